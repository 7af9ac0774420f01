"""Constrained scalar types shared by every message.

Every float in a message is bounded, which rejects NaN and infinities at decode time
(msgspec checks `Meta` constraints when decoding, not when constructing; use
`swarm_proto.validate` where a message is produced). The `Fixed` marker gives the
resolution used by the compact radio encoding (fixed-point integers); it is ignored by
msgspec and read by `swarm_proto.radio`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from msgspec import Meta


@dataclass(frozen=True)
class Fixed:
    """Radio fixed-point resolution of a float field: value = integer * resolution."""

    resolution: float


@dataclass(frozen=True)
class Saturate:
    """Radio encoding clamps an integer field to `maximum` (e.g. satellite count)."""

    maximum: int


VehicleId = Annotated[
    int, Meta(ge=1, le=65534, description="swarm node id (uint16; 0 = none, 65535 = broadcast)")
]
OptVehicleId = Annotated[int, Meta(ge=0, le=65534, description="swarm node id, 0 = none")]
MissionId = Annotated[int, Meta(ge=0, le=2**32 - 1, description="mission id (uint32), 0 = none")]
ZoneId = Annotated[int, Meta(ge=1, le=2**32 - 1, description="no-fly zone id (uint32)")]
FleetId = Annotated[int, Meta(ge=0, le=255, description="fleet id (uint8), 0 = no fleet")]
Seq = Annotated[int, Meta(ge=0, le=2**32 - 1, description="sequence number (uint32)")]
Uint8 = Annotated[int, Meta(ge=0, le=255)]
Uint16 = Annotated[int, Meta(ge=0, le=65535)]
Percent = Annotated[int, Meta(ge=0, le=100, description="percent, 0..100")]

LatitudeDeg = Annotated[
    float, Meta(ge=-90.0, le=90.0, description="WGS84 latitude, degrees"), Fixed(1e-7)
]
LongitudeDeg = Annotated[
    float, Meta(ge=-180.0, le=180.0, description="WGS84 longitude, degrees"), Fixed(1e-7)
]
# Altitudes: -1000..8000 m fits the radio's int16 at 0.25 m resolution.
AltitudeM = Annotated[
    float, Meta(ge=-1000.0, le=8000.0, description="altitude, metres"), Fixed(0.25)
]
HeightM = Annotated[float, Meta(ge=0.0, le=8000.0, description="height, metres"), Fixed(0.25)]
DistanceM = Annotated[float, Meta(ge=0.0, le=1.0e6, description="distance, metres"), Fixed(0.01)]
SpeedMS = Annotated[float, Meta(ge=0.0, le=300.0, description="speed, m/s"), Fixed(0.01)]
VelocityMS = Annotated[
    float, Meta(ge=-300.0, le=300.0, description="velocity component, m/s"), Fixed(0.01)
]
HeadingDeg = Annotated[
    float, Meta(ge=0.0, lt=360.0, description="heading, degrees from true north"), Fixed(0.01)
]
AngleDeg = Annotated[float, Meta(ge=-360.0, le=360.0, description="angle, degrees"), Fixed(0.01)]
VoltageV = Annotated[float, Meta(ge=0.0, le=655.0, description="voltage, volts"), Fixed(0.01)]
UnixTimeS = Annotated[
    float,
    Meta(ge=0.0, le=4.0e9, description="UNIX time (GPS-derived where available), seconds"),
    Fixed(0.001),
]
DurationS = Annotated[float, Meta(ge=0.0, le=1.0e7, description="duration, seconds"), Fixed(0.01)]
Fraction = Annotated[float, Meta(ge=0.0, le=1.0, description="fraction, 0..1"), Fixed(1e-4)]
Score = Annotated[
    float,
    Meta(ge=0.0, le=1.0, description="voting score, 0 worst .. 1 best (score = 1 - sum w*v)"),
    Fixed(1e-4),
]

ShortText = Annotated[str, Meta(max_length=64)]
Name = Annotated[str, Meta(max_length=48)]
