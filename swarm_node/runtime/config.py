"""Node configuration: a TOML file (msgspec), overridable from the command line.

# /etc/bandada/node.toml
swarm = "default"
node_id = 3                       # the swarm database's system id
autopilot = "/dev/bandada-autopilot,921600"   # or udpin:0.0.0.0:14550, tcp:127.0.0.1:5760
db = "/var/lib/bandada/swarm.db"  # where the node resolves its identity and parameters
status_hz = 5.0
info_hz = 1.0
plan_timeout_s = 60.0
avoidance = true                  # collision avoidance and pad sequencing (docs/avoidance.md)

[zenoh]                           # swarm_proto.session.ZenohSettings
mode = "peer"
connect = ["tcp/192.168.1.10:7447"]
lease_ms = 2000
# config_file = "/etc/bandada/zenoh.json5"   # a Zenoh JSON5 config (e.g. from
#                                 # `swarm-node certs make`); the keys above override it

[profile]                         # optional: parameters without a database
model = "Generic Quad"
vehicle_type = 3                  # swarm_proto.VehicleType
cruise_speed_m_s = 12.0
"""

from __future__ import annotations

from pathlib import Path

import msgspec

from swarm_proto.session import ZenohSettings, zenoh_config
from swarm_proto.topics import check_swarm_name

from ..core.profile import VehicleProfile


class ProfileOverride(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """VehicleProfile fields given in the config file (used when there is no database)."""

    model: str = "unknown"
    user_id: str = ""
    vehicle_type: int = 0
    cruise_speed_m_s: float = 0.0
    min_speed_m_s: float = 0.0
    max_speed_m_s: float = 0.0
    max_bank_deg: float = 45.0
    battery_low_pct: int = 30
    battery_critical_pct: int = 15
    has_parachute: bool = False
    max_tilt_deg: float = 60.0  # abnormal attitude beyond this roll or pitch


class NodeConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    node_id: int = 0
    swarm: str = "default"
    autopilot: str = ""  # "" = no autopilot (a node that only watches the swarm)
    db: str | None = None
    status_hz: float = 5.0
    info_hz: float = 1.0
    plan_timeout_s: float = 60.0
    stale_after_s: float = 2.0
    # Autopilot silence that counts as a lost link. Telemetry is requested at 10 Hz, so
    # 0.6 s is six missed position messages; with the 5 Hz state machine it keeps link
    # loss -> STATE_EMERGENCY under 1 s. Fast-time simulations on a loaded machine raise it.
    link_timeout_s: float = 0.6
    avoidance: bool = True  # collision avoidance, take-off/landing sequencing (safety/)
    intent: bool = True  # publish the next legs, predict peers along theirs (avoidance)
    zenoh: ZenohSettings = ZenohSettings()
    profile: ProfileOverride | None = None

    def __post_init__(self) -> None:
        if not 1 <= self.node_id <= 65534:
            raise ValueError(f"node_id must be 1..65534, got {self.node_id}")
        check_swarm_name(self.swarm)
        if not 0.1 <= self.status_hz <= 50 or not 0.05 <= self.info_hz <= 10:
            raise ValueError("status_hz must be 0.1..50 and info_hz 0.05..10")
        if not 0.2 <= self.link_timeout_s <= 30:
            raise ValueError("link_timeout_s must be 0.2..30")
        if not 1.0 <= self.plan_timeout_s <= 3600.0:  # also false for NaN
            raise ValueError("plan_timeout_s must be 1..3600")


def load_config(path: str | Path | None, **overrides: object) -> NodeConfig:
    """Read a TOML config (if given) and apply non-None overrides; clear errors."""
    data: dict[str, object] = {}
    if path is not None:
        try:
            data = msgspec.toml.decode(Path(path).read_bytes())
        except (OSError, msgspec.DecodeError) as exc:
            raise ValueError(f"cannot read config {path}: {exc}") from exc
    zenoh = dict(data.pop("zenoh", {}) or {})  # type: ignore[call-overload]
    file = zenoh.get("config_file")
    if isinstance(file, str) and path is not None and not Path(file).is_absolute():
        zenoh["config_file"] = str(Path(path).parent / file)  # relative to the TOML file
    for key in ("mode", "listen", "connect", "lease_ms", "config_file"):
        value = overrides.pop(f"zenoh_{key}", None)
        if value not in (None, (), []):
            zenoh[key] = value
    data.update({k: v for k, v in overrides.items() if v is not None})
    data["zenoh"] = zenoh
    try:
        cfg = msgspec.convert(data, NodeConfig)
    except (msgspec.ValidationError, ValueError) as exc:
        raise ValueError(f"invalid node configuration: {exc}") from exc
    if cfg.zenoh.config_file:
        zenoh_config(cfg.zenoh)  # a missing or broken Zenoh file: a clear error now
    return cfg


def profile_from_config(cfg: NodeConfig) -> VehicleProfile:
    from swarm_proto import VehicleType

    p = cfg.profile or ProfileOverride()
    return VehicleProfile(
        vehicle_id=cfg.node_id,
        user_id=p.user_id or f"node-{cfg.node_id}",
        model=p.model,
        vehicle_type=VehicleType(p.vehicle_type),
        cruise_speed_m_s=p.cruise_speed_m_s,
        min_speed_m_s=p.min_speed_m_s,
        max_speed_m_s=p.max_speed_m_s,
        max_bank_deg=p.max_bank_deg,
        battery_low_pct=p.battery_low_pct,
        battery_critical_pct=p.battery_critical_pct,
        has_parachute=p.has_parachute,
        max_tilt_deg=p.max_tilt_deg,
    )
