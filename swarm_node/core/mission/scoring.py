"""The paper's voting score (section 2.3.6), a pure object apart from the ballot.

    score = 1 - w_p * v_p - w_t * v_t - w_b * v_b        in [0, 1], 1 best

- payload v_p: the candidate's payload is the mission's model 0, the same subtype 0.5,
  the same type 0.75, anything else (or none) 1; a mission asking for no payload: 0
  for everyone.
- time v_t: t = distance to the mission's reference point / cruise speed;
  v_t = tanh(time_scale_per_s * t). The paper's atanh(0.01 t) is undefined past 100 s;
  tanh has the same slope at 0 and stays in [0, 1) (docs/paper-choices.md).
- battery v_b: linear, 100 % -> 0, 0 % -> 1 (unknown -> 1).

The weights come from the swarm database's module parameters (`module_params("voting")`:
weight_payload, weight_time, weight_battery, time_scale_per_s) and are normalized to
sum to 1 (the paper's 0.6, 0.2, 0.3 sum to 1.1). The reference point (MUM-T: the lead;
area/perimeter: the centroid; others: the start) is `reference_point`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from swarm_proto import Geometry, GeometryKind, LatLon, Mission, MissionType

from ..planning.geo import LocalFrame
from ..profile import PayloadClass, VehicleProfile

# match -> v_p (paper section 2.3.6)
PAYLOAD_MODEL = 0.0
PAYLOAD_SUBTYPE = 0.5
PAYLOAD_TYPE = 0.75
PAYLOAD_NONE = 1.0


class ScoreError(ValueError):
    """Bad score parameters or inputs (a clear message, never a NaN score)."""


@dataclass(frozen=True, slots=True)
class Candidate:
    """What scoring needs to know about one vehicle."""

    vehicle_id: int
    payload: PayloadClass  # PayloadClass() = no payload
    position: LatLon | None  # None: unknown (time term 1)
    cruise_speed_m_s: float
    battery_pct: float | None  # None: unknown (battery term 1)

    @classmethod
    def of(
        cls, profile: VehicleProfile, position: LatLon | None, battery_pct: float | None
    ) -> Candidate:
        """A vehicle's candidate from its database profile and its latest status."""
        return cls(
            profile.vehicle_id,
            profile.payload_class,
            position,
            profile.cruise_speed_m_s,
            battery_pct,
        )


@dataclass(frozen=True, slots=True)
class Terms:
    """The three acquired scores v (0 best .. 1 worst) and the total (1 best)."""

    payload: float
    time: float
    battery: float
    score: float


@dataclass(frozen=True, slots=True)
class PaperScore:
    """score = 1 - sum(w v), weights normalized to sum 1, time term bounded."""

    weight_payload: float = 0.6 / 1.1
    weight_time: float = 0.2 / 1.1
    weight_battery: float = 1.0 - 0.6 / 1.1 - 0.2 / 1.1  # = 0.3 / 1.1, as from_params
    time_scale_per_s: float = 0.01

    def __post_init__(self) -> None:
        ws = (self.weight_payload, self.weight_time, self.weight_battery)
        if not all(math.isfinite(w) and w >= 0.0 for w in ws):
            raise ScoreError(f"voting weights must be finite and >= 0, got {ws}")
        if abs(sum(ws) - 1.0) > 1e-9:
            raise ScoreError(f"voting weights must sum to 1 (use from_params), got {sum(ws)}")
        if not (math.isfinite(self.time_scale_per_s) and self.time_scale_per_s > 0.0):
            raise ScoreError(f"time_scale_per_s must be > 0, got {self.time_scale_per_s}")

    @classmethod
    def from_params(cls, params: Mapping[str, float]) -> PaperScore:
        """From the database's `module_params("voting")`; the weights are normalized.
        Missing names take the paper's values."""
        wp = float(params.get("weight_payload", 0.6))
        wt = float(params.get("weight_time", 0.2))
        wb = float(params.get("weight_battery", 0.3))
        scale = float(params.get("time_scale_per_s", 0.01))
        total = wp + wt + wb
        if not all(math.isfinite(w) and w >= 0.0 for w in (wp, wt, wb)) or total <= 0.0:
            raise ScoreError(
                f"voting weights must be finite, >= 0 and not all 0, got "
                f"payload={wp}, time={wt}, battery={wb}"
            )
        return cls(wp / total, wt / total, max(0.0, 1.0 - wp / total - wt / total), scale)

    # ------------------------------------------------------------------ the terms
    @staticmethod
    def payload_term(have: PayloadClass, want: PayloadClass) -> float:
        if not want.model and not want.subtype and not want.type:
            return PAYLOAD_MODEL  # the mission asks for no payload: everyone matches
        if have.model and have.model == want.model:
            return PAYLOAD_MODEL
        if have.subtype and have.subtype == want.subtype:
            return PAYLOAD_SUBTYPE
        if have.type and have.type == want.type:
            return PAYLOAD_TYPE
        return PAYLOAD_NONE

    def time_term(self, time_s: float | None) -> float:
        if time_s is None or not math.isfinite(time_s):
            return 1.0
        return math.tanh(self.time_scale_per_s * max(0.0, time_s))

    @staticmethod
    def battery_term(pct: float | None) -> float:
        if pct is None or not math.isfinite(pct):
            return 1.0
        return 1.0 - min(100.0, max(0.0, pct)) / 100.0

    @staticmethod
    def arrival_s(c: Candidate, reference: LatLon) -> float | None:
        """Distance to the reference point over cruise speed; None when unknown."""
        if c.position is None or not (c.cruise_speed_m_s > 0.0):
            return None
        frame = LocalFrame(reference.lat_deg, reference.lon_deg)
        x, y = frame.to_local(c.position.lat_deg, c.position.lon_deg)
        return math.hypot(x, y) / c.cruise_speed_m_s

    def terms(self, c: Candidate, want: PayloadClass, reference: LatLon) -> Terms:
        vp = self.payload_term(c.payload, want)
        vt = self.time_term(self.arrival_s(c, reference))
        vb = self.battery_term(c.battery_pct)
        s = 1.0 - self.weight_payload * vp - self.weight_time * vt - self.weight_battery * vb
        return Terms(vp, vt, vb, min(1.0, max(0.0, s)))

    def score(self, c: Candidate, want: PayloadClass, reference: LatLon) -> float:
        return self.terms(c, want, reference).score


def reference_point(
    mission_type: MissionType, geometry: Geometry, lead: LatLon | None = None
) -> LatLon:
    """Where the time term measures to (paper section 2.3.6): MUM-T the lead vehicle
    (`lead`; its geometry's first point if the lead's position is unknown), area and
    perimeter the polygon's centroid, every other mission its start."""
    if mission_type == MissionType.MUMT and lead is not None:
        return lead
    if mission_type in (MissionType.AREA, MissionType.PERIMETER):
        if geometry.kind == GeometryKind.POLYGON:
            frame = LocalFrame.for_geometry(geometry)
            c = frame.shape(geometry).centroid
            lat, lon = frame.to_geodetic(float(c.x), float(c.y))
            return LatLon(lat, lon)
        return geometry.points[0]  # a CIRCLE's centre is its centroid
    if not geometry.points:
        raise ScoreError(f"a {mission_type.name} mission's geometry has no point")
    return geometry.points[0]


def payload_wanted(model: str, classes: Mapping[str, PayloadClass]) -> PayloadClass:
    """The class of the payload model a mission asks for ("" = none), from the swarm
    database's `payload_classes()`. An unknown model is a clear error."""
    if not model:
        return PayloadClass()
    if model not in classes:
        raise ScoreError(f"unknown payload model {model!r} (not in the swarm database)")
    return classes[model]


def mission_terms(
    score: PaperScore,
    mission: Mission,
    me: Candidate,
    classes: Mapping[str, PayloadClass],
    lead: LatLon | None = None,
) -> Terms:
    """A vehicle's own score for a QUANTITY mission: the payload the mission's selector
    asks for, the reference point of its kind (`lead`: the MUM-T lead's position)."""
    want = payload_wanted(mission.selection.payload_model, classes)
    return score.terms(me, want, reference_point(mission.mission_type, mission.geometry, lead))
