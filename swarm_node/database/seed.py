"""Seed data: what a new swarm database holds, as an export document.

The paper's platform (section 3, experiments 1 and 2): the Albatross 250 VTOL, wingspan
2.5 m, cruise 26 m/s and stall 15.5 m/s at 12.5 kg, ceiling 4800 m, wind 10.8-13.8 m/s
in fixed-wing mode, with a two-axis (roll and pitch) gyrostabilized 1.5 Mpx camera; six
of them, as in the simulated experiment. Beside it a generic quadcopter, rover and boat
and a ground station, several of each, for the demo and the tests.

Values the paper does not give are ArduPilot defaults or stated assumptions, each
commented where it is set and listed in docs/database.md. Node ids: vehicles 1..13,
the ground station 900.
"""

from __future__ import annotations

from typing import Any

ALBATROSS = "Albatross 250 VTOL"
QUADCOPTER = "Generic Quadcopter"
ROVER = "Generic Rover"
BOAT = "Generic Boat"
GROUND_STATION = "Ground Station"
SEED_MODELS = (ALBATROSS, QUADCOPTER, ROVER, BOAT, GROUND_STATION)

GCS_NODE_ID = 900

# (node id, user id, system layout, payload user id or None)
_FLEET: tuple[tuple[int, str, str, str | None], ...] = (
    *((i, f"ALB-{i:02d}", "Albatross 250 VTOL + EO 1.5 Mpx", f"CAM-{i:02d}") for i in range(1, 7)),
    (7, "QUAD-01", "Quadcopter + EO 1080p", "EO1080-01"),
    (8, "QUAD-02", "Quadcopter + EO 1080p", "EO1080-02"),
    (9, "QUAD-03", "Quadcopter + thermal", "TH640-01"),
    (10, "ROVER-01", "Rover + SDR", "SDR-01"),
    (11, "ROVER-02", "Rover + SDR", "SDR-02"),
    (12, "BOAT-01", "Boat + acoustic array", "MIC-01"),
    (13, "BOAT-02", "Boat + acoustic array", "MIC-02"),
    (GCS_NODE_ID, "GCS-01", "Ground station", None),
)

# payload user id -> payload layout (payload ids follow this order, from 1)
_PAYLOADS: tuple[tuple[str, str], ...] = (
    *((f"CAM-{i:02d}", "EO 1.5 Mpx 2-axis") for i in range(1, 7)),
    ("EO1080-01", "EO 1080p 2-axis"),
    ("EO1080-02", "EO 1080p 2-axis"),
    ("TH640-01", "Thermal 640 3-axis"),
    ("SDR-01", "SDR receiver"),
    ("SDR-02", "SDR receiver"),
    ("MIC-01", "Acoustic array"),
    ("MIC-02", "Acoustic array"),
)


def _model_params() -> list[dict[str, Any]]:
    return [
        {
            "model": ALBATROSS,
            "cruise_speed_m_s": 26.0,  # paper: cruise 26 m/s @ 12.5 kg
            "min_speed_m_s": 15.5,  # paper: stall 15.5 m/s @ 12.5 kg
            "max_speed_m_s": 32.0,  # assumption (~1.25 x cruise); ArduPlane AIRSPEED_MAX
            "max_bank_deg": 45.0,  # ArduPlane ROLL_LIMIT_DEG default
            "climb_rate_m_s": 5.0,  # ArduPlane TECS_CLMB_MAX default
            "sink_rate_m_s": 5.0,  # ArduPlane TECS_SINK_MAX default
            "loiter_radius_m": 60.0,  # ArduPlane WP_LOITER_RAD default (turn radius: 69 m)
            "has_parachute": True,  # assumption: the paper's PARACHUTE mission state
            "max_altitude_m": 4800.0,  # paper: maximum flight altitude
            "wingspan_m": 2.5,  # paper: 2500 mm
            "mass_kg": 12.5,  # paper: the speeds' reference mass (MTOW 15 kg, empty 7 kg)
            "battery_low_pct": 30,
            "battery_critical_pct": 15,
            "max_tilt_deg": 60.0,  # abnormal attitude: beyond the 45 deg bank limit + margin
            "max_wind_m_s": 10.8,  # paper: fixed-wing wind resistance 10.8-13.8 m/s (low end)
            # 12S 22 Ah; 12 A in level cruise, 70 A on the lift motors (the simulator's
            # Albatross; assumptions, the paper gives no battery figures)
            "battery_capacity_mah": 22000.0,
            "cruise_current_a": 12.0,
            "hover_current_a": 70.0,
        },
        {
            "model": QUADCOPTER,
            "cruise_speed_m_s": 10.0,  # ArduCopter WPNAV_SPEED default 1000 cm/s
            "min_speed_m_s": 0.0,
            "max_speed_m_s": 15.0,  # assumption
            "max_bank_deg": 30.0,  # ArduCopter ANGLE_MAX default 3000 cdeg
            "climb_rate_m_s": 2.5,  # ArduCopter WPNAV_SPEED_UP default 250 cm/s
            "sink_rate_m_s": 1.5,  # ArduCopter WPNAV_SPEED_DN default 150 cm/s
            "loiter_radius_m": 0.0,  # hovers on the spot
            "has_parachute": False,
            "max_altitude_m": 4000.0,  # assumption (the simulator's default ceiling)
            "wingspan_m": 0.65,  # frame diagonal with propellers, assumption
            "mass_kg": 1.5,  # assumption (the simulator's quad)
            "battery_low_pct": 30,
            "battery_critical_pct": 15,
            "max_tilt_deg": 45.0,
            "max_wind_m_s": 10.0,  # assumption
            # 3S 3300 mAh as in SITL; 30 A at hover, 36 A flying at 10 m/s (assumptions,
            # the simulator's quad); ArduCopter WPNAV_ACCEL default 250 cm/s/s
            "battery_capacity_mah": 3300.0,
            "cruise_current_a": 36.0,
            "hover_current_a": 30.0,
            "accel_m_s2": 2.5,
        },
        {
            "model": ROVER,
            "cruise_speed_m_s": 2.0,  # ArduRover WP_SPEED default 2 m/s
            "min_speed_m_s": 0.0,
            "max_speed_m_s": 5.0,  # assumption
            "max_bank_deg": 0.0,  # turns on the spot / steering: no bank
            "loiter_radius_m": 0.0,  # holds position
            "has_parachute": False,
            "wingspan_m": 0.5,  # width, assumption
            "mass_kg": 5.0,  # assumption
            "battery_low_pct": 25,
            "battery_critical_pct": 10,
            "max_tilt_deg": 35.0,  # roll-over risk beyond, assumption
            "battery_capacity_mah": 10000.0,  # assumptions (the simulator's rover)
            "cruise_current_a": 5.3,
            "accel_m_s2": 1.0,
        },
        {
            "model": BOAT,
            "cruise_speed_m_s": 3.0,  # assumption (the simulator's boat)
            "min_speed_m_s": 0.0,
            "max_speed_m_s": 6.0,  # assumption (the simulator's boat)
            "max_bank_deg": 0.0,
            "loiter_radius_m": 0.0,  # holds position
            "has_parachute": False,
            "wingspan_m": 0.6,  # beam, assumption
            "mass_kg": 15.0,  # assumption (the simulator's boat)
            "battery_low_pct": 25,
            "battery_critical_pct": 10,
            "max_tilt_deg": 30.0,  # capsize risk beyond, assumption
            "battery_capacity_mah": 20000.0,  # assumptions (the simulator's boat)
            "cruise_current_a": 8.3,
            "accel_m_s2": 0.5,
        },
        {
            "model": GROUND_STATION,
            "cruise_speed_m_s": 0.0,
            "max_speed_m_s": 0.0,
            "max_bank_deg": 0.0,
            "battery_low_pct": 20,
            "battery_critical_pct": 10,
            "max_tilt_deg": 180.0,
        },
    ]


def _systems() -> dict[str, list[dict[str, Any]]]:
    payload_ids = {uid: i for i, (uid, _) in enumerate(_PAYLOADS, start=1)}
    systems, params = [], []
    for node_id, user_id, layout, payload in _FLEET:
        systems.append(
            {
                "id": node_id,
                "user_id": user_id,
                "layout": layout,
                "payload": payload_ids[payload] if payload else None,
            }
        )
        if node_id != GCS_NODE_ID:
            # MAVLink system id = node id for the SITL fleet (SYSID_THISMAV).
            params.append({"system": node_id, "name": "mav_sysid", "value": str(node_id)})
        # Locally administered MAC addresses (placeholders, set the real ones).
        params.append(
            {
                "system": node_id,
                "name": "mac_address",
                "value": f"02:00:00:00:{node_id >> 8:02x}:{node_id & 0xFF:02x}",
            }
        )
    for node_id, _user_id, layout, _ in _FLEET:
        if layout.startswith("Albatross"):
            params.append(
                {
                    "system": node_id,
                    "name": "udev_rule",
                    "value": (
                        'SUBSYSTEM=="tty", ATTRS{idVendor}=="0403", ATTRS{idProduct}=="6015", '
                        'SYMLINK+="xtend"'
                    ),
                }
            )
    return {
        "types": [
            {"name": "UAV", "description": "unmanned aerial vehicle"},
            {"name": "UGV", "description": "unmanned ground vehicle"},
            {"name": "USV", "description": "unmanned surface vehicle"},
            {"name": "GCS", "description": "ground control station"},
        ],
        "subtypes": [
            {"name": "fixed-wing", "type": "UAV", "vehicle_type": "PLANE"},
            {
                "name": "VTOL",
                "type": "UAV",
                "vehicle_type": "VTOL",
                "description": "QuadPlane: vertical take-off, fixed-wing cruise",
            },
            {"name": "multirotor", "type": "UAV", "vehicle_type": "COPTER"},
            {"name": "helicopter", "type": "UAV", "vehicle_type": "COPTER"},
            {"name": "rover", "type": "UGV", "vehicle_type": "ROVER"},
            {"name": "boat", "type": "USV", "vehicle_type": "BOAT"},
            {"name": "ground control station", "type": "GCS", "vehicle_type": "GCS"},
        ],
        "models": [
            {
                "name": ALBATROSS,
                "subtype": "VTOL",
                "description": "the paper's platform: carbon fibre, 2.5 m span, 12S, MTOW 15 kg",
            },
            {"name": QUADCOPTER, "subtype": "multirotor", "description": "ArduCopter quad X"},
            {"name": ROVER, "subtype": "rover", "description": "ArduRover skid-steer"},
            {"name": BOAT, "subtype": "boat", "description": "ArduRover boat frame"},
            {
                "name": GROUND_STATION,
                "subtype": "ground control station",
                "description": "operator laptop running gcs",
            },
        ],
        "model-params": _model_params(),
        "layouts": [
            {
                "name": "Albatross 250 VTOL + EO 1.5 Mpx",
                "model": ALBATROSS,
                "payload_layout": "EO 1.5 Mpx 2-axis",
                "computer": "Jetson Orin Nano",
            },
            {
                "name": "Quadcopter + EO 1080p",
                "model": QUADCOPTER,
                "payload_layout": "EO 1080p 2-axis",
                "computer": "Raspberry Pi 4",
            },
            {
                "name": "Quadcopter + thermal",
                "model": QUADCOPTER,
                "payload_layout": "Thermal 640 3-axis",
                "computer": "Raspberry Pi 4",
            },
            {
                "name": "Rover + SDR",
                "model": ROVER,
                "payload_layout": "SDR receiver",
                "computer": "Raspberry Pi 4",
            },
            {
                "name": "Boat + acoustic array",
                "model": BOAT,
                "payload_layout": "Acoustic array",
                "computer": "Raspberry Pi 4",
            },
            {
                "name": "Ground station",
                "model": GROUND_STATION,
                "payload_layout": None,
                "computer": "Ground station laptop",
            },
        ],
        "systems": systems,
        "params": params,
    }


def _swarm() -> dict[str, list[dict[str, Any]]]:
    def mp(mission: str, name: str, value: float, unit: str, desc: str = "") -> dict[str, Any]:
        return {"mission": mission, "name": name, "value": value, "unit": unit, "description": desc}

    def modp(module: str, name: str, value: float, unit: str, desc: str = "") -> dict[str, Any]:
        return {"module": module, "name": name, "value": value, "unit": unit, "description": desc}

    return {
        "missions": [
            {
                "name": "area",
                "mission_type": "AREA",
                "description": "cover a polygon with camera lanes",
            },
            {
                "name": "target",
                "mission_type": "TARGET",
                "description": "orbit or hover around a point",
            },
            {
                "name": "perimeter",
                "mission_type": "PERIMETER",
                "description": "patrol a closed boundary",
            },
            {"name": "route", "mission_type": "ROUTE", "description": "follow a polyline"},
            {"name": "objective", "mission_type": "OBJECTIVE", "description": "visit points"},
            {
                "name": "autoland",
                "mission_type": "AUTOLAND",
                "description": "land one after another",
            },
            {"name": "MUM-T", "mission_type": "MUMT", "description": "accompany a manned lead"},
        ],
        "mission-params": [
            mp("area", "altitude_rel_m", 100.0, "m"),
            mp("area", "side_overlap", 0.7, "", "fraction of the camera footprint"),
            mp("target", "altitude_rel_m", 100.0, "m"),
            mp("target", "radius_m", 150.0, "m"),
            mp("target", "altitude_step_m", 10.0, "m", "vertical separation between vehicles"),
            mp("perimeter", "altitude_rel_m", 100.0, "m"),
            mp("perimeter", "altitude_step_m", 10.0, "m"),
            mp("route", "altitude_rel_m", 100.0, "m"),
            mp("objective", "altitude_rel_m", 100.0, "m"),
            mp("objective", "duration_s", 60.0, "s", "hold at each point"),
            mp("autoland", "separation_s", 30.0, "s", "time between landings"),
            mp("MUM-T", "altitude_step_m", 20.0, "m"),
        ],
        "modules": [
            {
                "name": "collision avoidance (fixed-wing)",
                "subtype": "fixed-wing",
                "description": "TTC extrapolation, upward-only altitude manoeuvre (also VTOL)",
            },
            {
                "name": "collision avoidance (multirotor)",
                "subtype": "multirotor",
                "description": "TTC extrapolation, altitude manoeuvre",
            },
            {
                "name": "voting",
                "subtype": None,
                "description": "QUANTITY missions: score = 1 - sum(w v) (paper section 2.3.6)",
            },
            {
                "name": "target re-tasking",
                "subtype": None,
                "description": "a TargetReport -> a target mission for count.<class> vehicles, voted",
            },
        ],
        "module-params": [
            # paper section 3: risk 10-40 m, danger 5-10 m, near-collision < 5 m
            modp("collision avoidance (fixed-wing)", "risk_distance_m", 40.0, "m"),
            modp("collision avoidance (fixed-wing)", "danger_distance_m", 10.0, "m"),
            modp("collision avoidance (fixed-wing)", "near_collision_m", 5.0, "m"),
            modp("collision avoidance (fixed-wing)", "ttc_threshold_s", 20.0, "s", "assumption"),
            modp("collision avoidance (fixed-wing)", "climb_step_m", 15.0, "m", "assumption"),
            modp("collision avoidance (fixed-wing)", "hysteresis_s", 5.0, "s", "assumption"),
            modp("collision avoidance (multirotor)", "risk_distance_m", 40.0, "m"),
            modp("collision avoidance (multirotor)", "danger_distance_m", 10.0, "m"),
            modp("collision avoidance (multirotor)", "near_collision_m", 5.0, "m"),
            modp("collision avoidance (multirotor)", "ttc_threshold_s", 10.0, "s", "assumption"),
            modp("collision avoidance (multirotor)", "climb_step_m", 5.0, "m", "assumption"),
            modp("collision avoidance (multirotor)", "hysteresis_s", 3.0, "s", "assumption"),
            # paper section 2.3.6 (they sum to 1.1: see docs/paper-choices.md)
            modp("voting", "weight_payload", 0.6, ""),
            modp("voting", "weight_time", 0.2, ""),
            modp("voting", "weight_battery", 0.3, ""),
            modp("voting", "time_scale_per_s", 0.01, "1/s", "time score = atanh(t x scale)"),
            # the paper's experiment: a target detected during a survey, 2 vehicles sent
            # (assumptions: which classes, how sure, how long; docs/voting.md)
            modp("target re-tasking", "count", 0.0, "", "vehicles per target, any class"),
            modp("target re-tasking", "count.person", 2.0, "", "vehicles per person"),
            modp("target re-tasking", "count.vehicle", 2.0, "", "vehicles per vehicle"),
            modp("target re-tasking", "min_confidence", 0.8, "", "reports below are ignored"),
            modp("target re-tasking", "duration_s", 120.0, "s", "hold on the target"),
            modp("target re-tasking", "dedup_radius_m", 100.0, "m", "one target within"),
            modp("target re-tasking", "hold_s", 0.5, "s", "reports gathered before tasking"),
            modp("target re-tasking", "keep_s", 900.0, "s", "a tasked target is remembered"),
            modp("target re-tasking", "payload_of_source", 1.0, "", "1: the reporter's payload"),
        ],
    }


def _payload() -> dict[str, list[dict[str, Any]]]:
    payloads = [
        {"id": i, "user_id": uid, "layout": layout}
        for i, (uid, layout) in enumerate(_PAYLOADS, start=1)
    ]
    params = []
    for i, (_uid, layout) in enumerate(_PAYLOADS, start=1):
        if layout == "SDR receiver":
            params += [
                {"payload": i, "name": "interface", "value": "usb"},
                {"payload": i, "name": "protocol", "value": "SoapySDR"},
            ]
        elif layout == "Acoustic array":
            params += [
                {"payload": i, "name": "interface", "value": "usb"},
                {"payload": i, "name": "protocol", "value": "UAC2"},
            ]
        else:
            params += [
                {"payload": i, "name": "interface", "value": "ethernet"},
                {"payload": i, "name": "protocol", "value": "RTSP"},
            ]
    return {
        "types": [
            {"name": "optical", "description": "imaging"},
            {"name": "radio frequency"},
            {"name": "sound"},
        ],
        "subtypes": [
            {"name": "visible camera", "type": "optical"},
            {"name": "thermal camera", "type": "optical"},
            {"name": "SDR", "type": "radio frequency", "description": "software-defined radio"},
            {"name": "microphone array", "type": "sound"},
        ],
        "models": [
            {
                "name": "EO 1.5 Mpx 2-axis gimbal",
                "subtype": "visible camera",
                "description": "the paper's two-axis gyrostabilized 1.5 Mpx camera",
            },
            {"name": "EO 1080p 2-axis gimbal", "subtype": "visible camera"},
            {"name": "Thermal 640 3-axis gimbal", "subtype": "thermal camera"},
            {"name": "SDR receiver", "subtype": "SDR"},
            {"name": "Acoustic array", "subtype": "microphone array"},
        ],
        "gimbal-axes": [
            {
                "name": "roll +-45",
                "axis": "roll",
                "motor": "gimbal brushless",
                "pid": "gimbal roll",
                "min_angle_deg": -45.0,
                "max_angle_deg": 45.0,
                "max_rate_deg_s": 180.0,
            },
            {
                "name": "tilt -90..+30",
                "axis": "tilt",
                "motor": "gimbal brushless",
                "pid": "gimbal tilt",
                "min_angle_deg": -90.0,
                "max_angle_deg": 30.0,
                "max_rate_deg_s": 120.0,
            },
            {
                "name": "pan 360",
                "axis": "pan",
                "motor": "gimbal brushless",
                "pid": "gimbal pan",
                "min_angle_deg": -180.0,
                "max_angle_deg": 180.0,
                "max_rate_deg_s": 180.0,
            },
        ],
        "gimbals": [
            # the paper's camera: gyrostabilized in roll and pitch (tilt)
            {
                "name": "2-axis roll/tilt",
                "baud_rate": 115200,
                "period_ms": 20.0,
                "pan_axis": None,
                "tilt_axis": "tilt -90..+30",
                "roll_axis": "roll +-45",
            },
            {
                "name": "3-axis",
                "baud_rate": 115200,
                "period_ms": 20.0,
                "pan_axis": "pan 360",
                "tilt_axis": "tilt -90..+30",
                "roll_axis": "roll +-45",
            },
        ],
        "sensors": [
            {"name": "EO 1.5 Mpx", "kind": "camera"},
            {"name": "EO 1080p", "kind": "camera"},
            {"name": "Thermal 640x512", "kind": "thermal"},
            {"name": "SDR 70 MHz-6 GHz", "kind": "sdr"},
            {"name": "8-microphone array", "kind": "microphone"},
        ],
        "sensor-params": [
            # 1.5 Mpx = 1440 x 1080 (4:3). The lens is assumed (the paper gives the
            # resolution only): the simulator's 62 x 48 deg.
            {
                "sensor": "EO 1.5 Mpx",
                "hfov_deg": 62.0,
                "vfov_deg": 48.0,
                "width_px": 1440,
                "height_px": 1080,
                "frame_rate_hz": 30.0,
            },
            {
                # the simulator's quadcopter camera
                "sensor": "EO 1080p",
                "hfov_deg": 78.0,
                "vfov_deg": 62.0,
                "width_px": 1920,
                "height_px": 1080,
                "frame_rate_hz": 30.0,
            },
            {
                "sensor": "Thermal 640x512",
                "hfov_deg": 32.0,
                "vfov_deg": 25.8,
                "width_px": 640,
                "height_px": 512,
                "frame_rate_hz": 30.0,
            },
            {"sensor": "SDR 70 MHz-6 GHz", "range_m": 5000.0},
        ],
        "layouts": [
            {
                "name": "EO 1.5 Mpx 2-axis",
                "model": "EO 1.5 Mpx 2-axis gimbal",
                "gimbal": "2-axis roll/tilt",
                "sensor": "EO 1.5 Mpx",
            },
            {
                "name": "EO 1080p 2-axis",
                "model": "EO 1080p 2-axis gimbal",
                "gimbal": "2-axis roll/tilt",
                "sensor": "EO 1080p",
            },
            {
                "name": "Thermal 640 3-axis",
                "model": "Thermal 640 3-axis gimbal",
                "gimbal": "3-axis",
                "sensor": "Thermal 640x512",
            },
            {
                "name": "SDR receiver",
                "model": "SDR receiver",
                "gimbal": None,
                "sensor": "SDR 70 MHz-6 GHz",
            },
            {
                "name": "Acoustic array",
                "model": "Acoustic array",
                "gimbal": None,
                "sensor": "8-microphone array",
            },
        ],
        "payloads": payloads,
        "params": params,
        "detection-classes": [
            {"name": "person"},
            {"name": "vehicle"},
            {"name": "boat"},
            {"name": "aircraft"},
            {"name": "animal"},
            {"name": "fire"},
        ],
        "motors": [
            {"name": "gimbal brushless", "kind": "brushless"},
            {"name": "gimbal servo", "kind": "servo"},
        ],
    }


def _common() -> dict[str, list[dict[str, Any]]]:
    comms = []
    for node_id, user_id, _, _ in _FLEET:
        comms.append(
            {
                "name": f"XTend {user_id}",
                "kind": "xtend900",
                "address": "/dev/xtend",
                "system": node_id,
                "description": "900 MHz mesh radio (XTend 1 W)",
            }
        )
        if user_id.startswith("ALB"):
            comms.append(
                {
                    "name": f"Microhard {user_id}",
                    "kind": "microhard",
                    "address": f"192.168.168.{10 + node_id}",
                    "system": node_id,
                    "description": "payload radio modem",
                }
            )
    return {
        "computers": [
            {
                "name": "Raspberry Pi 4",
                "board": "Raspberry Pi 4 Model B",
                "cpu": "Cortex-A72 4 x 1.5 GHz",
                "ram_mb": 4096,
                "os": "Raspberry Pi OS 12",
            },
            {
                "name": "Jetson Orin Nano",
                "board": "NVIDIA Jetson Orin Nano 8GB",
                "cpu": "Cortex-A78AE 6 x 1.5 GHz",
                "ram_mb": 8192,
                "os": "Ubuntu 22.04 (JetPack 6)",
            },
            {
                "name": "Ground station laptop",
                "board": "Lenovo Legion 5 16IRX8",
                "cpu": "Intel Core i7-13700HX",
                "ram_mb": 32768,
                "os": "Ubuntu 24.04",
            },
        ],
        "comms": comms,
        "corrections": [],
        "pids": [
            # placeholders to tune per gimbal
            {
                "name": "gimbal roll",
                "p": 0.8,
                "i": 0.05,
                "d": 0.02,
                "max_integral": 10.0,
                "anti_windup": True,
            },
            {
                "name": "gimbal tilt",
                "p": 0.8,
                "i": 0.05,
                "d": 0.02,
                "max_integral": 10.0,
                "anti_windup": True,
            },
            {
                "name": "gimbal pan",
                "p": 0.6,
                "i": 0.03,
                "d": 0.01,
                "max_integral": 10.0,
                "anti_windup": True,
            },
        ],
    }


def document() -> dict[str, Any]:
    """The seed data as an export document (a fresh copy each call)."""
    return {
        "format": "bandada-swarm-db",
        "schema_version": 4,
        "groups": {
            "systems": _systems(),
            "swarm": _swarm(),
            "payload": _payload(),
            "common": _common(),
        },
    }
