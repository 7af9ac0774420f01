"""The message contract of bandada: msgspec Structs, one per kind of data.

Every field carries its unit in its name or in its type's description (see `units`).
Messages are frozen. Range constraints are checked when decoding; cross-field rules
(`__post_init__`) are checked on construction and on decoding. Use `validate(msg)` to
check a message you produced before you send it.

Evolution rule (both encodings): append fields with defaults at the end; never change a
field's type or meaning; never reuse an enum value.
"""

from __future__ import annotations

import math
from typing import Annotated

import msgspec
from msgspec import Meta, Struct

from .enums import (
    AckReason,
    AckRef,
    AlertCode,
    AlertFlag,
    CommandKind,
    DetailCode,
    FsmState,
    GeometryKind,
    GpsFix,
    MissionState,
    MissionType,
    SelectorKind,
    Severity,
    TargetSource,
    VehicleType,
)
from .units import (
    AltitudeM,
    AngleDeg,
    DistanceM,
    DurationS,
    Fixed,
    FleetId,
    Fraction,
    HeadingDeg,
    HeightM,
    LatitudeDeg,
    LongitudeDeg,
    MissionId,
    Name,
    OptVehicleId,
    Percent,
    Saturate,
    Score,
    Seq,
    ShortText,
    SpeedMS,
    Uint8,
    Uint16,
    UnixTimeS,
    VehicleId,
    VelocityMS,
    VoltageV,
    ZoneId,
)

# --------------------------------------------------------------------------- geometry


class LatLon(Struct, frozen=True, array_like=True):
    """A horizontal position (WGS84). Encoded as a 2-element array [lat_deg, lon_deg]."""

    lat_deg: LatitudeDeg
    lon_deg: LongitudeDeg


class GeoPoint(Struct, frozen=True):
    """A 3-D position: WGS84 latitude/longitude and altitude above mean sea level."""

    lat_deg: LatitudeDeg
    lon_deg: LongitudeDeg
    alt_msl_m: AltitudeM


def _ring_problem(ring: tuple[LatLon, ...], what: str) -> str | None:
    if len(ring) < 3:
        return f"{what} needs at least 3 vertices, got {len(ring)}"
    if ring[0] == ring[-1]:
        return f"{what} must be an open ring (do not repeat the first vertex)"
    lons = [p.lon_deg for p in ring]
    if max(lons) - min(lons) > 180.0:
        return f"{what} spans more than 180 degrees of longitude (antimeridian is unsupported)"
    return None


def polygon_problem(
    shell: tuple[LatLon, ...], holes: tuple[tuple[LatLon, ...], ...] = ()
) -> str | None:
    """Why `shell` with `holes` is not a valid simple polygon, or None if it is.

    Topology is checked in (lon, lat) degrees with shapely: self-intersection, zero area,
    holes outside the shell or overlapping each other.
    """
    problem = _ring_problem(shell, "polygon shell")
    if problem:
        return problem
    for i, hole in enumerate(holes):
        problem = _ring_problem(hole, f"hole {i}")
        if problem:
            return problem
    from shapely.geometry import Polygon
    from shapely.validation import explain_validity

    poly = Polygon(
        [(p.lon_deg, p.lat_deg) for p in shell],
        [[(p.lon_deg, p.lat_deg) for p in h] for h in holes],
    )
    if not poly.is_valid:
        return f"polygon is not simple: {explain_validity(poly)}"
    if poly.area <= 0.0:
        return "polygon has zero area"
    return None


class Geometry(Struct, frozen=True):
    """Where a mission or a zone is. Which fields are used depends on `kind`:

    - POINT: `points[0]`; POINTS: one or more `points`; POLYLINE: two or more `points`.
    - POLYGON: `points` is the shell (>= 3 vertices, open ring), `holes` are inner rings.
    - CIRCLE: `points[0]` is the centre and `radius_m` the radius.

    Only a POLYGON has holes, only a CIRCLE a radius (> 0). A polygon must be simple:
    rings of >= 3 vertices, open (the first vertex not repeated), no self-intersection,
    non-zero area, holes inside the shell and not overlapping each other, spanning less
    than 180 degrees of longitude.
    """

    kind: GeometryKind
    points: tuple[LatLon, ...] = ()
    holes: tuple[tuple[LatLon, ...], ...] = ()
    radius_m: DistanceM | None = None

    def __post_init__(self) -> None:
        problem = self.problem()
        if problem:
            raise ValueError(f"invalid {self.kind.name} geometry: {problem}")

    def problem(self) -> str | None:
        k, n = self.kind, len(self.points)
        if k != GeometryKind.POLYGON and self.holes:
            return "only a POLYGON may have holes"
        if k != GeometryKind.CIRCLE and self.radius_m is not None:
            return "only a CIRCLE has a radius"
        if k == GeometryKind.POINT and n != 1:
            return f"needs exactly 1 point, got {n}"
        if k == GeometryKind.POINTS and n < 1:
            return "needs at least 1 point"
        if k == GeometryKind.POLYLINE and n < 2:
            return f"needs at least 2 points, got {n}"
        if k == GeometryKind.CIRCLE:
            if n != 1:
                return f"needs exactly 1 centre point, got {n}"
            if self.radius_m is None or self.radius_m <= 0.0:
                return "needs a positive radius_m"
        if k == GeometryKind.POLYGON:
            return polygon_problem(self.points, self.holes)
        return None

    @classmethod
    def point(cls, lat_deg: float, lon_deg: float) -> Geometry:
        return cls(GeometryKind.POINT, (LatLon(lat_deg, lon_deg),))

    @classmethod
    def polygon(
        cls,
        shell: list[tuple[float, float]],
        holes: list[list[tuple[float, float]]] | None = None,
    ) -> Geometry:
        """A polygon from (lat, lon) pairs."""
        return cls(
            GeometryKind.POLYGON,
            tuple(LatLon(a, b) for a, b in shell),
            tuple(tuple(LatLon(a, b) for a, b in h) for h in (holes or [])),
        )

    @classmethod
    def circle(cls, lat_deg: float, lon_deg: float, radius_m: float) -> Geometry:
        return cls(GeometryKind.CIRCLE, (LatLon(lat_deg, lon_deg),), radius_m=radius_m)


# --------------------------------------------------------------------------- telemetry


class VehicleStatus(Struct, frozen=True):
    """Fast telemetry of one vehicle (5 Hz). Radio: a fixed 40-byte layout."""

    vehicle_id: VehicleId
    time_unix_s: UnixTimeS  # GPS-derived UNIX time of the sample
    lat_deg: LatitudeDeg
    lon_deg: LongitudeDeg
    alt_msl_m: AltitudeM  # above mean sea level
    alt_rel_m: AltitudeM  # above home
    vel_north_m_s: VelocityMS = 0.0
    vel_east_m_s: VelocityMS = 0.0
    vel_down_m_s: VelocityMS = 0.0
    heading_deg: HeadingDeg = 0.0  # vehicle yaw, from true north
    airspeed_m_s: SpeedMS = 0.0
    battery_pct: Annotated[int, Meta(ge=-1, le=100, description="remaining %, -1 unknown")] = -1
    battery_v: VoltageV = 0.0
    gps_fix: GpsFix = GpsFix.NO_GPS
    gps_sats: Annotated[int, Meta(ge=0, le=255), Saturate(31)] = 0  # radio saturates at 31
    ap_mode: Uint8 = 0  # ArduPilot custom_mode number (meaning depends on VehicleType)
    armed: bool = False
    fsm_state: FsmState = FsmState.INACTIVE
    mission_state: MissionState = MissionState.IDLE
    mission_progress_pct: Percent = 0
    fleet_id: FleetId = 0
    alerts: Annotated[AlertFlag, Meta(description="active AlertFlag bits")] = AlertFlag.NONE
    # appended: a radio gateway republishes a radio peer's status predicted to
    # `time_unix_s` from the last one it heard (dead reckoning, send on error): the
    # position is then within `position_error_m` of the truth, and `predicted_s` is how
    # far it was carried forward (the autopilot data is `predicted_s` older than
    # `time_unix_s`). Both 0: the vehicle's own measurement. LAN only (the 40-byte radio
    # layout carries measured statuses).
    position_error_m: DistanceM = 0.0  # a radio gateway's prediction: the truth is within this
    predicted_s: DurationS = 0.0  # a radio gateway's prediction: carried forward this long

    def __post_init__(self) -> None:
        if not 0 <= int(self.alerts) <= 0xFFFF:
            raise ValueError("alerts must fit 16 bits")

    @property
    def groundspeed_m_s(self) -> float:
        """Horizontal speed over ground, m/s (derived from the NED velocity)."""
        return math.hypot(self.vel_north_m_s, self.vel_east_m_s)

    @property
    def course_deg(self) -> float:
        """Course over ground, degrees from true north (derived from the NED velocity)."""
        return math.degrees(math.atan2(self.vel_east_m_s, self.vel_north_m_s)) % 360.0


class VehicleInfo(Struct, frozen=True):
    """Identity and slower state of a node (1 Hz): the paper's VehicleInfo."""

    vehicle_id: VehicleId
    vehicle_type: VehicleType
    model: Name  # system model name, e.g. "Albatross 250 VTOL"
    user_id: Name  # the operator's id of this airframe
    mav_sysid: Annotated[int, Meta(ge=0, le=255, description="MAVLink system id, 0 = none")] = 0
    payload_model: Name = ""  # "" = no payload
    payload_subtype: Name = ""
    payload_type: Name = ""
    cruise_speed_m_s: SpeedMS = 0.0
    home: GeoPoint | None = None  # autopilot home
    base: GeoPoint | None = None  # swarm base (set by the operator), where it returns
    fleet_id: FleetId = 0
    mission_id: MissionId = 0  # current mission, 0 = none
    fsm_state: FsmState = FsmState.INACTIVE
    errors: tuple[AlertCode, ...] = ()  # active error conditions
    # appended: the mission's roster hash (swarm_node roster.py; 0 = none) and
    # how far along its planned path this vehicle is
    members_hash: Annotated[int, Meta(ge=0, le=0xFFFF, description="roster hash, 0 = none")] = 0
    mission_progress_m: DistanceM = 0.0  # metres of this vehicle's share flown
    mission_path_m: DistanceM = 0.0  # length of this vehicle's share
    # appended: the ground station's flight display (`gcs vehicle ID`, the
    # paper's PFD) and the autopilot the node is paired with, as its HEARTBEAT says
    roll_deg: AngleDeg = 0.0
    pitch_deg: AngleDeg = 0.0
    sensors_present: Annotated[int, Meta(ge=0, le=2**32 - 1, description="SYS_STATUS bits")] = 0
    sensors_health: Annotated[int, Meta(ge=0, le=2**32 - 1, description="SYS_STATUS bits")] = 0
    mav_type: Uint8 = 0  # the autopilot's HEARTBEAT type (MAV_TYPE), 0 = not heard
    # appended (PREMISSION): the earliest time this vehicle can be at its
    # share's entry point (swarm_node mission/fleet_sync.py; 0 = not flying a PREMISSION)
    entry_unix_s: UnixTimeS = 0.0
    # appended: the battery now; what a member published on entering PLAN for
    # a mission is what every node plans its share with (swarm_node roster.py)
    battery_pct: Annotated[int, Meta(ge=-1, le=100, description="remaining %, -1 unknown")] = -1
    # appended: the battery the autopilot itself says it has (its BATT_CAPACITY, read
    # at link-up): what every node plans this vehicle's endurance with, not its own
    # database's figure for the model (0 = not known: the database's)
    battery_capacity_mah: Annotated[
        int, Meta(ge=0, le=1_000_000, description="the autopilot's battery, mAh, 0 unknown")
    ] = 0


# --------------------------------------------------------------------------- control


class Selector(Struct, frozen=True):
    """Which vehicles a command or mission addresses (paper section 3.5.2)."""

    kind: SelectorKind = SelectorKind.ALL
    vehicle_ids: tuple[VehicleId, ...] = ()  # IDS
    fleet_id: FleetId = 0  # FLEET; for QUANTITY the fleet to choose from (0 = any)
    quantity: Uint8 = 0  # QUANTITY: how many vehicles voting selects
    payload_model: Name = ""  # QUANTITY: required payload model ("" = none)

    def __post_init__(self) -> None:
        if self.kind == SelectorKind.IDS and not self.vehicle_ids:
            raise ValueError("an IDS selector needs at least one vehicle id")
        if self.kind != SelectorKind.IDS and self.vehicle_ids:
            raise ValueError("vehicle_ids are only used by an IDS selector")
        if self.kind == SelectorKind.FLEET and self.fleet_id == 0:
            raise ValueError("a FLEET selector needs a fleet_id > 0")
        if self.kind == SelectorKind.QUANTITY and self.quantity == 0:
            raise ValueError("a QUANTITY selector needs quantity > 0")

    def addresses(self, vehicle_id: int, fleet_id: int) -> bool:
        """Whether this vehicle is addressed (QUANTITY: whether it is a candidate)."""
        if self.kind == SelectorKind.ALL:
            return True
        if self.kind == SelectorKind.IDS:
            return vehicle_id in self.vehicle_ids
        if self.kind == SelectorKind.FLEET:
            return fleet_id == self.fleet_id
        return self.fleet_id == 0 or fleet_id == self.fleet_id

    @classmethod
    def ids(cls, *vehicle_ids: int) -> Selector:
        return cls(SelectorKind.IDS, vehicle_ids=tuple(vehicle_ids))

    @classmethod
    def fleet(cls, fleet_id: int) -> Selector:
        return cls(SelectorKind.FLEET, fleet_id=fleet_id)


class CommandArgs(Struct, frozen=True):
    """Arguments of a command; which are used depends on CommandKind."""

    point: GeoPoint | None = None
    value: Annotated[float, Meta(ge=-1.0e6, le=1.0e6), Fixed(0.001)] | None = (
        None  # unit per CommandKind (see CommandKind below)
    )
    text: ShortText = ""
    fleet_id: FleetId = 0
    mission_id: MissionId = 0
    other_mission_id: MissionId = 0


class Command(Struct, frozen=True):
    """An operator (or peer) command. Every addressed node answers with an Ack."""

    issuer_id: VehicleId
    seq: Seq  # per issuer, increasing; (issuer_id, seq) identifies the command
    kind: CommandKind
    target: Selector = Selector()
    args: CommandArgs = CommandArgs()
    time_unix_s: UnixTimeS = 0.0


class ReasonDetail(Struct, frozen=True):
    """The facts behind a refusal or an alert, as numbers: a 64-character text cannot
    hold them, and the ground station words them in full (gcs_cli/core/reasons.py).
    `code` says which fields are used; the others stay 0."""

    code: DetailCode = DetailCode.NONE
    vehicle_id: OptVehicleId = 0  # whom it is about (0: every vehicle, or none)
    needed_s: DurationS = 0.0  # ENDURANCE: its share and the way home, at cruise
    available_s: DurationS = 0.0  # ENDURANCE: what its battery allows at cruise
    distance_m: DistanceM = 0.0  # COLLISION: the closest approach predicted
    in_s: DurationS = 0.0  # COLLISION: in how long
    altitude_m: HeightM = 0.0  # COLLISION: the altitude above home it goes to (0: it stops)


class Ack(Struct, frozen=True):
    """A node's answer to a command, mission, zone or fleet assignment."""

    vehicle_id: VehicleId  # who answers
    issuer_id: VehicleId  # who sent what is answered
    ref: AckRef
    ref_id: Seq  # command seq, mission id, zone id or fleet id
    accepted: bool
    reason: AckReason = AckReason.OK
    text: ShortText = ""
    # appended: the reason's numbers (None: the code and the text say it all)
    detail: ReasonDetail | None = None


class Alert(Struct, frozen=True):
    """A condition raised by a vehicle's monitoring or swarm logic (paper 2.3.2).

    Sent when a condition is raised or its severity rises, and with code
    CONDITION_CLEARED when it clears; the active conditions are also in every
    VehicleStatus (`alerts` bits), so a receiver that missed an Alert still sees them."""

    vehicle_id: VehicleId  # who raises it
    time_unix_s: UnixTimeS
    severity: Severity
    code: AlertCode
    text: ShortText = ""  # for the operator, e.g. "battery 9%" or "in zone 3"
    # appended: the alert's numbers (None: the code and the text say it all)
    detail: ReasonDetail | None = None


# --------------------------------------------------------------------------- missions


class MissionParams(Struct, frozen=True):
    """Planning parameters. Unused ones keep their defaults; None = the vehicle's own."""

    altitude_rel_m: HeightM = 100.0  # flight altitude above home
    speed_m_s: SpeedMS | None = None  # None: each vehicle's cruise speed
    side_overlap: Annotated[float, Meta(ge=0.0, le=0.95), Fixed(1e-4)] = (
        0.7  # fraction of the camera footprint adjacent lanes share (0.7 = 70 %)
    )
    radius_m: DistanceM | None = None  # target / perimeter / circle radius
    altitude_step_m: HeightM = 0.0  # vertical separation between vehicles
    loops: Uint16 = 0  # perimeter / target orbits, 0 = until told otherwise
    duration_s: DurationS | None = None  # how long to hold (target, objective)
    heading_deg: HeadingDeg | None = None  # approach / landing heading
    lead_vehicle_id: OptVehicleId = 0  # MUM-T lead
    separation_s: DurationS = 0.0  # autoland time separation between vehicles


class Mission(Struct, frozen=True):
    """A mission for the swarm (paper section 2.3.5)."""

    mission_id: MissionId
    issuer_id: VehicleId
    mission_type: MissionType
    geometry: Geometry
    params: MissionParams = MissionParams()
    selection: Selector = Selector()
    name: Name = ""
    time_unix_s: UnixTimeS = 0.0

    def __post_init__(self) -> None:
        if self.mission_id == 0:
            raise ValueError("mission_id 0 is reserved for 'no mission'")


class VoteScore(Struct, frozen=True, array_like=True):
    """One candidate's score in a Vote. Encoded as a 2-element array [vehicle_id, score]."""

    vehicle_id: VehicleId
    score: Score  # paper's score: 1 best .. 0 worst


class Vote(Struct, frozen=True):
    """A voter's scores of the candidates for a QUANTITY mission (paper Figure 18): its
    own, and every other member's as it received them (relayed), so that all voters end
    with the same table; re-sent until the vote commits (docs/voting.md)."""

    mission_id: MissionId
    voter_id: VehicleId
    scores: tuple[VoteScore, ...]
    round: Uint8 = 0
    # appended: the roster hash of the electorate the voter votes in
    # (swarm_node.core.mission.voting; 0 = none); votes with another hash are not counted
    members_hash: Annotated[int, Meta(ge=0, le=0xFFFF, description="roster hash, 0 = none")] = 0
    committed: bool = False  # the voter has decided (it stops re-sending once all have)


class FleetAssignment(Struct, frozen=True):
    """The vehicles that fly a mission together as one fleet."""

    fleet_id: Annotated[int, Meta(ge=1, le=255)]
    mission_id: MissionId
    vehicle_ids: tuple[VehicleId, ...]
    issuer_id: VehicleId
    time_unix_s: UnixTimeS = 0.0


class NoFlyZone(Struct, frozen=True):
    """Airspace vehicles must never enter, or with operating_area must never leave.

    A no-fly zone is avoided by routes and coverage plans between its floor and
    ceiling. An operating area (the operator's "restrict the operational region", paper
    section 3.5.1; an ArduPilot inclusion fence) is 2-D: its floor and ceiling are not
    used; with several, the vehicles must stay inside all of them."""

    zone_id: ZoneId
    geometry: Geometry  # POLYGON (without holes) or CIRCLE
    floor_alt_msl_m: AltitudeM = -1000.0
    ceiling_alt_msl_m: AltitudeM = 8000.0
    valid_from_unix_s: UnixTimeS = 0.0
    valid_until_unix_s: UnixTimeS | None = None  # None: until removed
    active: bool = True
    name: Name = ""
    operating_area: bool = False  # True: keep in (an operating area), not keep out
    # appended: who declared it; each vehicle acknowledges the zone to it
    # (Ack ref ZONE, ref_id the zone id); 0 = nobody to answer (e.g. an older sender)
    issuer_id: OptVehicleId = 0
    # appended: when the operator declared it, the ground station's clock;
    # the newest declaration of a zone id wins everywhere, so a withdrawal (active=False)
    # stays withdrawn when a node that missed it rejoins (0: unknown, the receiver's time)
    time_unix_s: UnixTimeS = 0.0

    def __post_init__(self) -> None:
        if self.geometry.kind not in (GeometryKind.POLYGON, GeometryKind.CIRCLE):
            raise ValueError("a no-fly zone is a POLYGON or a CIRCLE")
        if self.geometry.holes:
            raise ValueError("a no-fly zone polygon has no holes (declare two zones)")
        if not self.floor_alt_msl_m < self.ceiling_alt_msl_m:
            raise ValueError("zone floor must be below its ceiling")
        if (
            self.valid_until_unix_s is not None
            and self.valid_until_unix_s <= self.valid_from_unix_s
        ):
            raise ValueError("zone validity ends before it starts")

    def in_force(self, now_unix_s: float) -> bool:
        if not self.active or now_unix_s < self.valid_from_unix_s:
            return False
        return self.valid_until_unix_s is None or now_unix_s < self.valid_until_unix_s


class TargetReport(Struct, frozen=True):
    """A target detected by a payload or marked by the operator."""

    target_id: Seq
    source_id: VehicleId
    source: TargetSource
    time_unix_s: UnixTimeS
    position: GeoPoint
    target_class: Name = ""  # autodetection class, e.g. "person", "vehicle"
    confidence: Fraction = 1.0
    vel_north_m_s: VelocityMS = 0.0
    vel_east_m_s: VelocityMS = 0.0


class PeerEntry(Struct, frozen=True):
    """One live peer in a node's SwarmView."""

    node_id: VehicleId
    vehicle_type: VehicleType = VehicleType.OTHER
    fleet_id: FleetId = 0
    fsm_state: FsmState = FsmState.INACTIVE
    heard_age_s: DurationS = 0.0  # since the last telemetry or liveliness news
    # appended: its telemetry comes from two sources (two Zenoh sessions, or two
    # MAVLink system ids) or it reports an identity conflict itself: kept out of voting
    # and planning (docs/security.md)
    untrusted: bool = False


class DroppedInput(Struct, frozen=True):
    """What a node dropped before any logic saw it: on one topic, for one reason
    (swarm_proto.intake), since it started."""

    key_expr: Name  # the topic's key expression under the swarm, e.g. "vehicle/*/status"
    reason: Name  # too_large, malformed, invalid, key_mismatch, bad_key, identity
    count: Count


class SwarmView(Struct, frozen=True):
    """A node's view of the swarm (answer to a query on vehicle/<id>/peers; LAN only)."""

    vehicle_id: VehicleId
    time_unix_s: UnixTimeS
    peers: tuple[PeerEntry, ...] = ()
    # appended: what it dropped, and its own identity conflict ("" = none)
    dropped: tuple[DroppedInput, ...] = ()
    identity_conflict: ShortText = ""


class DeclaredMission(Struct, frozen=True):
    """A mission the node heard and accepted, and whether it is still in force for it."""

    mission: Mission
    in_force: bool = True  # False: completed, cancelled or left by this node
    changed_unix_s: UnixTimeS = 0.0  # when in_force last changed


class DeclaredState(Struct, frozen=True):
    """What the operator declared, as one node holds it (answer to a query on
    vehicle/<id>/declared; LAN only): every zone and operating area (withdrawn
    ones too, each with the stamp that orders it), the SET_BASE, SET_FLEET and
    CANCEL_MISSION commands in force (newest last) and fleet assignments, from which any
    vehicle's base and fleet follow, the missions it holds, and this node's own base,
    fleet and mission. Nodes exchange it when they meet; the newest stamp wins."""

    vehicle_id: VehicleId
    time_unix_s: UnixTimeS
    zones: tuple[NoFlyZone, ...] = ()
    commands: tuple[Command, ...] = ()
    assignments: tuple[FleetAssignment, ...] = ()
    missions: tuple[DeclaredMission, ...] = ()
    base: GeoPoint | None = None  # this node's base now
    fleet_id: FleetId = 0  # this node's fleet now
    mission_id: MissionId = 0  # the mission this node flies now (0: none)


# --------------------------------------------------------------------------- radio

RatePerS = Annotated[float, Meta(ge=0.0, le=10_000.0, description="events per second"), Fixed(0.01)]
OffsetMs = Annotated[
    float, Meta(ge=-1.0e6, le=1.0e6, description="time offset, milliseconds"), Fixed(0.01)
]
Count = Annotated[int, Meta(ge=0, le=2**32 - 1, description="count since start (uint32)")]


class PeerRadioStats(Struct, frozen=True):
    """What one radio gateway hears of one peer over the last statistics period."""

    node_id: VehicleId
    packets_per_s: RatePerS = 0.0
    loss: Fraction = 0.0  # 1 - frames heard / frames its slots should have carried
    slot_utilization: Fraction = 0.0  # its frame's bytes / the slot's capacity
    time_offset_ms: OffsetMs = 0.0  # arrival minus expected arrival (median)
    last_heard_s: DurationS = 0.0  # seconds since its last frame
    time_stratum: Annotated[int, Meta(ge=0, le=3)] = 3  # 0 GPS .. 3 free-running


class RadioStats(Struct, frozen=True):
    """A radio gateway's statistics, on the LAN about once a second (never on air).

    The TDM table it follows, its own slot, what it dropped and why, one entry per peer.
    Counts are totals since the gateway started."""

    node_id: VehicleId
    time_unix_s: UnixTimeS
    phase: Name = ""  # listening, joining, member
    members: tuple[VehicleId, ...] = ()
    table_version: Uint16 = 0  # the 16-bit slot-table hash carried in frames
    rate_divisor: Uint8 = 1  # 1: every cycle (5 Hz); k: every k-th cycle, past the limit
    slot_s: DurationS = 0.0
    slot_budget_bytes: Uint16 = 0
    slot_utilization: Fraction = 0.0  # our record bytes / budget
    time_offset_ms: OffsetMs = 0.0  # our correction to the time source
    time_stratum: Annotated[int, Meta(ge=0, le=3)] = 3
    tx_frames: Count = 0
    rx_frames: Count = 0
    dropped_corrupt: Count = 0  # COBS, CRC, length or version
    dropped_forged: Count = 0  # tag mismatch
    dropped_replayed: Count = 0  # old or repeated cycle counter
    dropped_malformed: Count = 0  # authentic but unparseable
    dropped_duplicates: Count = 0  # already heard on the LAN or the air
    retransmissions: Count = 0
    failed_deliveries: Count = 0  # acked messages given up on
    peers: tuple[PeerRadioStats, ...] = ()


# --------------------------------------------------------------------------- add / swap


class LineageHome(Struct, frozen=True, array_like=True):
    """A member of a fleet's first plan and the home that plan posed it at."""

    vehicle_id: VehicleId
    home: GeoPoint | None = None
    # the battery the first plan gave it (what it published on entering PLAN), -1 unknown
    battery_pct: Annotated[int, Meta(ge=-1, le=100, description="remaining %, -1 unknown")] = -1


class LineageBattery(Struct, frozen=True, array_like=True):
    """A survivor's battery left by the model when the fleet replanned (what the replan
    gave it no more work than)."""

    vehicle_id: VehicleId
    battery_pct: Annotated[float, Meta(ge=0.0, le=100.0, description="remaining %"), Fixed(0.01)]


class LineageProgress(Struct, frozen=True, array_like=True):
    """A member's progress along its share when the fleet replanned."""

    vehicle_id: VehicleId
    progress_m: DistanceM


class LineageStep(Struct, frozen=True, array_like=True):
    """One replan of a fleet: the members it was made for and the progress it started
    from (every old member's metres along its share)."""

    members: tuple[VehicleId, ...]
    progress: tuple[LineageProgress, ...] = ()
    battery: tuple[LineageBattery, ...] = ()  # the survivors' modelled battery (area replans)


class PlanLineage(Struct, frozen=True):
    """How a fleet's plan came to be (add and swap, docs/voting.md): the mission as the
    fleet flies it, the first plan's members with their homes, and every replan since.
    Every fleet member plans from the same inputs, so a vehicle joining the fleet
    replays this and holds the fleet's plan too; a fleet emptied by a swap publishes
    it, with the progress its members left at, for the fleet its mission is handed to."""

    mission: Mission
    sender_id: VehicleId
    first: tuple[LineageHome, ...]
    replans: tuple[LineageStep, ...] = ()
    members_hash: Annotated[int, Meta(ge=0, le=0xFFFF, description="of the last step")] = 0
    handed_to: MissionId = 0  # the emptied fleet's mission goes to this mission's fleet

    @property
    def mission_id(self) -> int:
        return self.mission.mission_id


# --------------------------------------------------------------------------- MAVLink passthrough

SessionId = Annotated[
    int, Meta(ge=1, le=2**32 - 1, description="MAVLink passthrough session id (uint32)")
]


class MavlinkSession(Struct, frozen=True):
    """A ground station's MAVLink passthrough session with one vehicle's autopilot
    (`gcs mavlink`, docs/ground-station.md): announced when it opens, again every second
    while its client is there, and once with `closing` when it ends; the node ends a
    session it has not heard of for 5 s. The frames travel raw (MAVLink bytes) on the
    session's `up` and `down` keys. LAN only."""

    vehicle_id: VehicleId  # whose autopilot the client talks to
    session_id: SessionId  # chosen at random by the ground station
    issuer_id: VehicleId  # the ground station
    read_only: bool = False  # telemetry and downloads only: commanding frames refused
    closing: bool = False


MavlinkFrames = Annotated[
    bytes, Meta(max_length=280, description="MAVLink frames, as the autopilot or client wrote them")
]


class MavlinkSummary(Struct, frozen=True):
    """A vehicle's HIGH_LATENCY2 (one MAVLink frame) for ground stations behind the 900
    MHz radio (`gcs mavlink --radio`), every 5 s while a radio session asks for it: the
    budgeted passthrough of the radio (docs/radio.md, "MAVLink passthrough on the air")."""

    vehicle_id: VehicleId
    frame: MavlinkFrames


class MavlinkCommand(Struct, frozen=True):
    """A radio session's command to a vehicle's autopilot: one COMMAND_LONG, COMMAND_INT
    or SET_MODE frame, ruled on by the vehicle's node as the operator's; empty: the
    session is still there (every 20 s)."""

    issuer_id: VehicleId  # the ground station
    target_id: VehicleId  # the vehicle
    frame: MavlinkFrames = b""


class MavlinkAnswer(Struct, frozen=True):
    """The vehicle's answer to a radio session's command (COMMAND_ACK, STATUSTEXT)."""

    vehicle_id: VehicleId
    issuer_id: VehicleId
    frame: MavlinkFrames


#: the most legs a VehicleIntent carries (a receiver ignores one with more, counted)
MAX_INTENT_LEGS = 3


class IntentPoint(Struct, frozen=True, array_like=True):
    """A point of a vehicle's path ahead: WGS84 position (int32 1e-7 deg on the radio) and
    altitude above mean sea level (int16, 0.25 m)."""

    lat_deg: LatitudeDeg
    lon_deg: LongitudeDeg
    alt_msl_m: AltitudeM


class VehicleIntent(Struct, frozen=True):
    """Where a vehicle flies next (its mission's next legs), for the peers' collision
    avoidance: published when the legs change and every 2 s while it flies them; no
    legs: it follows no known path (a receiver falls back to straight-line prediction).
    `speed_m_s` is the speed it flies them at; `turn_radius_m` its smallest turn at that
    speed (0: it turns on the spot, a multirotor); `hold_at_end`: it stops at the last
    point (a multirotor's hold or landing), else it goes on."""

    vehicle_id: VehicleId
    time_unix_s: UnixTimeS  # the sender's clock (its autopilot's GPS time)
    speed_m_s: SpeedMS = 0.0
    turn_radius_m: HeightM = 0.0
    hold_at_end: bool = False
    legs: Annotated[tuple[IntentPoint, ...], Meta(max_length=MAX_INTENT_LEGS)] = ()


#: Every message type, in radio type-tag order (index + 1 is the tag). Append only.
MESSAGE_TYPES: tuple[type[Struct], ...] = (
    VehicleStatus,
    VehicleInfo,
    Command,
    Ack,
    Alert,
    Mission,
    Vote,
    FleetAssignment,
    NoFlyZone,
    TargetReport,
    RadioStats,
    PlanLineage,
    MavlinkSummary,
    MavlinkCommand,
    MavlinkAnswer,
    VehicleIntent,
)


def validate(msg: Struct) -> None:
    """Check every constraint of a message we produced (msgspec only checks on decode).

    Raises `swarm_proto.EncodeError` naming the field. Cheap enough for 5 Hz telemetry.
    """
    from .errors import EncodeError

    try:
        msgspec.convert(msgspec.to_builtins(msg), type(msg))
    except (msgspec.ValidationError, ValueError, TypeError) as exc:
        raise EncodeError(f"{type(msg).__name__}: {exc}") from exc
