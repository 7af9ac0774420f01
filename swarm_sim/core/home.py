"""Where the vehicle boots (`Home`, SITL's --home) and the home position it keeps
(`HomeState`: set by the EKF origin, by arming, by DO_SET_HOME), with the messages that
report them."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .fields import deg_e7, i32
from .geo import LocalFrame
from .mission import FRAME_ABSOLUTE, GLOBAL_FRAMES, MAX_ALT_M, MissionItem


@dataclass(frozen=True)
class Home:
    """Boot position: latitude, longitude (deg), altitude above sea level (m), heading."""

    lat_deg: float
    lon_deg: float
    alt_m: float
    heading_deg: float = 0.0

    @classmethod
    def parse(cls, text: str) -> Home:
        """From SITL's --home text, LAT,LON,ALT,HDG (ALT and HDG optional)."""
        parts = [p.strip() for p in text.split(",")]
        if not 2 <= len(parts) <= 4:
            raise ValueError(f"home must be LAT,LON[,ALT[,HDG]], got {text!r}")
        vals = [float(p) for p in parts] + [0.0] * (4 - len(parts))
        home = cls(vals[0], vals[1], vals[2], vals[3])
        home.check()
        return home

    def check(self) -> None:
        if not (-90 <= self.lat_deg <= 90 and -180 <= self.lon_deg <= 180):
            raise ValueError(f"home out of range: {self}")
        if not all(
            math.isfinite(v) for v in (self.lat_deg, self.lon_deg, self.alt_m, self.heading_deg)
        ):
            raise ValueError(f"home not finite: {self}")


# The reference SITL home of the recordings
SITL_HOME = Home(37.4112, -5.9889, 10.0, 90.0)


class HomeState:
    """The home position (north/east of the boot position, altitude above sea level) in
    the local frame around the boot position, whose altitude is the EKF origin's."""

    def __init__(self, frame: LocalFrame, origin_alt: float, boot_time: float) -> None:
        self.frame = frame
        self.origin_alt = origin_alt
        self.boot_time = boot_time
        self.is_set = False
        self.ne = (0.0, 0.0)
        self.alt = origin_alt

    def set(self, n: float, e: float, alt: float) -> None:
        self.is_set = True
        self.ne = (n, e)
        self.alt = alt

    @property
    def latlon_alt(self) -> tuple[float, float, float]:
        lat, lon = self.frame.to_latlon(*self.ne)
        return lat, lon, self.alt

    def alt_from_frame(self, frame: int, z: float) -> float | None:
        """An altitude above sea level from a command's frame; None for a frame without
        an altitude or a value out of range."""
        if not math.isfinite(z) or abs(z) > MAX_ALT_M:
            return None
        if frame in FRAME_ABSOLUTE:
            return z
        if frame in GLOBAL_FRAMES:
            return self.alt + z
        return None

    def item_alt(self, item: MissionItem) -> float:
        """A mission item's altitude above sea level."""
        if item.frame in FRAME_ABSOLUTE:
            return item.z
        return self.alt + item.z

    def item(self) -> MissionItem:
        """Mission item 0: home, as ArduPilot stores it."""
        lat, lon, alt = self.latlon_alt
        return MissionItem(
            seq=0, frame=0, command=16, x=round(lat * 1e7), y=round(lon * 1e7), z=alt
        )

    def position_message(self, now: float) -> Any:
        """HOME_POSITION."""
        lat, lon, alt = self.latlon_alt
        hn, he = self.ne
        nan = float("nan")
        return mavlink.MAVLink_home_position_message(
            deg_e7(lat),
            deg_e7(lon),
            i32(alt * 1000),
            hn,
            he,
            -(alt - self.origin_alt),
            [nan, nan, nan, nan],
            0.0,
            0.0,
            0.0,
            int((now - self.boot_time) * 1e6),
        )

    def origin_message(self, now: float) -> Any:
        """GPS_GLOBAL_ORIGIN: the EKF origin (the boot position)."""
        return mavlink.MAVLink_gps_global_origin_message(
            deg_e7(self.frame.lat0),
            deg_e7(self.frame.lon0),
            i32(self.origin_alt * 1000),
            int((now - self.boot_time) * 1e6),
        )
