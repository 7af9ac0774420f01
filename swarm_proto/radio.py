"""Compact encoding for the 900 MHz radio.

Every encoded message starts with two bytes: the radio schema version and the message
type tag (1-based index in `MESSAGE_TYPES`). Then:

- `VehicleStatus` (the 5 Hz hot path): a fixed 40-byte little-endian layout of
  fixed-point integers (see `STATUS_LAYOUT` and docs/radio-encoding.md).
- every other message: a MessagePack array of its fields by position (nested structs
  are nested arrays), floats as fixed-point integers at the resolution their type
  declares with `units.Fixed`, enums as integers, times as integer milliseconds.

Evolution is append-only: a decoder fills missing trailing fields with their defaults
and ignores extra trailing fields, so old and new nodes interoperate.

Decoding never raises anything but `swarm_proto.DecodeError`, whatever the bytes.
"""

from __future__ import annotations

import decimal
import enum
import math
import struct
import types
import typing
from dataclasses import dataclass
from typing import Any, Union

import msgspec

from .enums import AlertFlag, FsmState, GpsFix, MissionState
from .errors import DecodeError, EncodeError
from .messages import MESSAGE_TYPES, VehicleStatus
from .units import Fixed, Saturate

RADIO_SCHEMA_VERSION = 1
TAG_OF: dict[type, int] = {cls: i + 1 for i, cls in enumerate(MESSAGE_TYPES)}
TYPE_OF: dict[int, type] = {tag: cls for cls, tag in TAG_OF.items()}

_DECODE_FAILURES = (
    msgspec.MsgspecError,
    ValueError,
    TypeError,
    IndexError,
    KeyError,
    OverflowError,
    AttributeError,
    RecursionError,
    struct.error,
)

# --------------------------------------------------------------------------- fixed point


@dataclass(frozen=True)
class _Bounds:
    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None

    def contains(self, x: float) -> bool:
        """False for NaN and for anything outside the bounds."""
        return (
            (self.ge is None or x >= self.ge)
            and (self.gt is None or x > self.gt)
            and (self.le is None or x <= self.le)
            and (self.lt is None or x < self.lt)
            and x == x
        )


def _bounds(meta_items: tuple[Any, ...]) -> _Bounds:
    ge = gt = le = lt = None
    for m in meta_items:
        if isinstance(m, msgspec.Meta):
            ge = m.ge if m.ge is not None else ge
            gt = m.gt if m.gt is not None else gt
            le = m.le if m.le is not None else le
            lt = m.lt if m.lt is not None else lt
    return _Bounds(ge, gt, le, lt)


def _digits(res: float) -> int:
    """Decimal places that represent multiples of `res` exactly (0.25 -> 2, 1e-7 -> 7)."""
    exponent = decimal.Decimal(repr(res)).as_tuple().exponent
    return max(0, -int(exponent))


class _Fixed:
    """Fixed-point codec of one bounded float: value = integer * res.

    A value inside the bounds always encodes to an integer whose value is inside the
    bounds too (rounding next to a strict bound, e.g. heading < 360, steps back one
    unit). A value outside the bounds, NaN or infinite is an EncodeError.
    """

    def __init__(self, res: float, bounds: _Bounds) -> None:
        self.res, self.bounds, self.digits = res, bounds, _digits(res)
        lo = bounds.ge if bounds.ge is not None else bounds.gt
        hi = bounds.le if bounds.le is not None else bounds.lt
        self.lo_q = None if lo is None else math.ceil(lo / res - 1e-9)
        self.hi_q = None if hi is None else math.floor(hi / res + 1e-9)
        if self.lo_q is not None and bounds.gt is not None and self.lo_q * res <= bounds.gt:
            self.lo_q += 1
        if self.hi_q is not None and bounds.lt is not None and self.hi_q * res >= bounds.lt:
            self.hi_q -= 1

    def enc(self, x: float) -> int:
        if not self.bounds.contains(x):
            raise EncodeError(f"value {x!r} outside {self.bounds}")
        q = round(x / self.res)
        if self.hi_q is not None and q > self.hi_q:
            q = self.hi_q
        if self.lo_q is not None and q < self.lo_q:
            q = self.lo_q
        return q

    def dec(self, q: Any) -> float:
        if type(q) is not int:
            raise TypeError(f"expected a fixed-point integer, got {type(q).__name__}")
        return round(q * self.res, self.digits)


# --------------------------------------------------------------------------- generic plan


class _Codec:
    def enc(self, v: Any) -> Any:
        raise NotImplementedError

    def dec(self, v: Any) -> Any:
        raise NotImplementedError


class _Plain(_Codec):
    def __init__(self, saturate: int | None = None) -> None:
        self.saturate = saturate

    def enc(self, v: Any) -> Any:
        if isinstance(v, enum.Enum):
            v = v.value
        if self.saturate is not None and v > self.saturate:
            v = self.saturate
        return v

    def dec(self, v: Any) -> Any:
        return v


class _FixedFloat(_Codec):
    def __init__(self, res: float, bounds: _Bounds) -> None:
        self.fixed = _Fixed(res, bounds)

    def enc(self, v: Any) -> Any:
        return self.fixed.enc(float(v))

    def dec(self, v: Any) -> Any:
        return self.fixed.dec(v)


class _Optional(_Codec):
    def __init__(self, inner: _Codec) -> None:
        self.inner = inner

    def enc(self, v: Any) -> Any:
        return None if v is None else self.inner.enc(v)

    def dec(self, v: Any) -> Any:
        return None if v is None else self.inner.dec(v)


class _Seq(_Codec):
    def __init__(self, inner: _Codec) -> None:
        self.inner = inner

    def enc(self, v: Any) -> Any:
        return [self.inner.enc(x) for x in v]

    def dec(self, v: Any) -> Any:
        if not isinstance(v, list):
            raise TypeError("expected an array")
        return [self.inner.dec(x) for x in v]


class _StructCodec(_Codec):
    def __init__(self, cls: type) -> None:
        self.cls = cls
        self.fields: list[tuple[str, _Codec, bool]] = []  # name, codec, required
        info = msgspec.inspect.type_info(cls)
        self.array_like = isinstance(info, msgspec.inspect.StructType) and info.array_like

    def enc(self, v: Any) -> Any:
        return [codec.enc(getattr(v, name)) for name, codec, _ in self.fields]

    def dec(self, v: Any) -> Any:
        if not isinstance(v, list):
            raise TypeError(f"expected an array for {self.cls.__name__}")
        out: dict[str, Any] = {}
        for i, (name, codec, required) in enumerate(self.fields):
            if i < len(v):
                out[name] = codec.dec(v[i])
            elif required:
                raise ValueError(f"{self.cls.__name__}.{name} missing")
        return list(out.values()) if self.array_like else out


_PLANS: dict[type, _StructCodec] = {}


def _codec_for(tp: Any) -> _Codec:
    origin = typing.get_origin(tp)
    if origin is typing.Annotated:
        base, *extras = typing.get_args(tp)
        fixed = next((e for e in extras if isinstance(e, Fixed)), None)
        sat = next((e for e in extras if isinstance(e, Saturate)), None)
        if base is float:
            if fixed is None:
                raise EncodeError(f"float field without a Fixed resolution: {tp}")
            return _FixedFloat(fixed.resolution, _bounds(tuple(extras)))
        if sat is not None:
            return _Plain(sat.maximum)
        return _codec_for(base)
    if origin in (Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) != 1:
            raise EncodeError(f"unsupported union {tp}")
        return _Optional(_codec_for(args[0]))
    if origin is tuple:
        targs = typing.get_args(tp)
        if len(targs) != 2 or targs[1] is not Ellipsis:
            raise EncodeError(f"only tuple[X, ...] is supported, got {tp}")
        return _Seq(_codec_for(targs[0]))
    if isinstance(tp, type) and issubclass(tp, msgspec.Struct):
        return _plan(tp)
    if tp is float:
        raise EncodeError("float field without a Fixed resolution")
    if tp in (int, bool, str, bytes) or (isinstance(tp, type) and issubclass(tp, enum.Enum)):
        return _Plain()
    raise EncodeError(f"unsupported field type {tp!r}")


def _plan(cls: type) -> _StructCodec:
    plan = _PLANS.get(cls)
    if plan is None:
        plan = _PLANS[cls] = _StructCodec(cls)  # registered first: recursive types
        hints = typing.get_type_hints(cls, include_extras=True)
        info = msgspec.inspect.type_info(cls)
        assert isinstance(info, msgspec.inspect.StructType)
        for f in info.fields:
            plan.fields.append((f.name, _codec_for(hints[f.name]), f.required))
    return plan


def plan(cls: type) -> None:
    """Build the radio field plan of `cls` now (`warm.warm_decoders`: a plan is
    registered before its fields are filled in, so it must not be built first on two
    threads at once)."""
    _plan(cls)


# --------------------------------------------------------------------------- status layout

#: version, tag, vehicle_id, time_ms mod 2^32, lat e7, lon e7, alt_msl/4, alt_rel/4,
#: vn, ve, vd (cm/s), heading (cdeg), airspeed (cm/s), battery % (255 unknown),
#: voltage (10 mV), gps (fix | sats << 3), ap_mode, flags, progress %, fleet, alerts
STATUS_LAYOUT = struct.Struct("<BBHIiihhhhhHHBHBBBBBH")
STATUS_BYTES = STATUS_LAYOUT.size
_STATUS_TAG = TAG_OF[VehicleStatus]
_MS_WRAP = 1 << 32


def _status_fixed(name: str) -> _Fixed:
    hint = typing.get_type_hints(VehicleStatus, include_extras=True)[name]
    extras = typing.get_args(hint)[1:]
    fixed = next(e for e in extras if isinstance(e, Fixed))
    return _Fixed(fixed.resolution, _bounds(tuple(extras)))


_LAT, _LON, _ALT, _REL, _VN, _VE, _VD, _HDG, _ASPD, _VOLT = (
    _status_fixed(n)
    for n in (
        "lat_deg",
        "lon_deg",
        "alt_msl_m",
        "alt_rel_m",
        "vel_north_m_s",
        "vel_east_m_s",
        "vel_down_m_s",
        "heading_deg",
        "airspeed_m_s",
        "battery_v",
    )
)
_TIME = _status_fixed("time_unix_s")


def _status_int_bounds(name: str) -> _Bounds:
    # nested Annotated aliases are flattened by typing: every Meta is in the extras
    hint = typing.get_type_hints(VehicleStatus, include_extras=True)[name]
    return _bounds(typing.get_args(hint)[1:])


# integer fields packed as they are: their declared bounds, checked when encoding so
# that we never put on air a status every receiver would reject
_STATUS_INTS = {
    n: _status_int_bounds(n)
    for n in ("vehicle_id", "battery_pct", "ap_mode", "mission_progress_pct", "fleet_id")
}


def _check_status_ints(s: VehicleStatus) -> None:
    for name, bounds in _STATUS_INTS.items():
        value = getattr(s, name)
        if not bounds.contains(value):
            raise EncodeError(f"VehicleStatus.{name} = {value!r} is out of its range")


def _closed(f: _Fixed) -> tuple[float, float]:
    """A fixed field's bounds as a closed range (the layout's fields have no strict
    lower bound; a strict upper bound is checked as `x < hi` by its caller)."""
    b = f.bounds
    assert b.gt is None and b.ge is not None
    hi = b.le if b.le is not None else b.lt
    assert hi is not None
    return float(b.ge), float(hi)


def _ints_range(name: str) -> tuple[int, int]:
    b = _STATUS_INTS[name]
    assert b.gt is None and b.lt is None and b.ge is not None and b.le is not None
    return int(b.ge), int(b.le)


# the status fields' limits as plain numbers, for the fast paths below; the fast paths
# only accept what the checked paths (`_encode_status_checked`, `_decode_status_checked`)
# accept, and hand anything else to them (for the exact error)
assert all(f.bounds.lt is None for f in (_TIME, _LAT, _LON, _ALT, _REL, _VN, _VE, _VD, _ASPD))
assert _VOLT.bounds.lt is None and _HDG.bounds.le is None and _HDG.bounds.lt is not None
_T_LO, _T_HI = _closed(_TIME)
_LAT_LO, _LAT_HI = _closed(_LAT)
_LON_LO, _LON_HI = _closed(_LON)
_ALT_LO, _ALT_HI = _closed(_ALT)
_REL_LO, _REL_HI = _closed(_REL)
_VN_LO, _VN_HI = _closed(_VN)
_VE_LO, _VE_HI = _closed(_VE)
_VD_LO, _VD_HI = _closed(_VD)
_HDG_LO, _HDG_LT = _closed(_HDG)  # heading < 360
_ASPD_LO, _ASPD_HI = _closed(_ASPD)
_VOLT_LO, _VOLT_HI = _closed(_VOLT)
_VID_LO, _VID_HI = _ints_range("vehicle_id")
_BAT_LO, _BAT_HI = _ints_range("battery_pct")
_MODE_LO, _MODE_HI = _ints_range("ap_mode")
_PROG_LO, _PROG_HI = _ints_range("mission_progress_pct")
_FLEET_LO, _FLEET_HI = _ints_range("fleet_id")
assert _TIME.hi_q is not None and _HDG.hi_q is not None
_T_RES, _T_HQ = _TIME.res, _TIME.hi_q
_LAT_RES, _LON_RES, _ALT_RES, _REL_RES = _LAT.res, _LON.res, _ALT.res, _REL.res
_VN_RES, _VE_RES, _VD_RES = _VN.res, _VE.res, _VD.res
_HDG_RES, _HDG_HQ, _ASPD_RES, _VOLT_RES = _HDG.res, _HDG.hi_q, _ASPD.res, _VOLT.res
_PACK = STATUS_LAYOUT.pack


def _encode_status(s: VehicleStatus) -> bytes:
    """The status layout, fast path: the same bytes as `_encode_status_checked` (the
    same quantization, rounding and clamping) for every status within its bounds;
    anything else (out of range, NaN, wrong type) goes through the checked path."""
    try:
        vid, t, lat, lon = s.vehicle_id, s.time_unix_s, s.lat_deg, s.lon_deg
        alt, rel, vn, ve, vd = (
            s.alt_msl_m,
            s.alt_rel_m,
            s.vel_north_m_s,
            s.vel_east_m_s,
            s.vel_down_m_s,
        )
        hdg, aspd, bat, volt = s.heading_deg, s.airspeed_m_s, s.battery_pct, s.battery_v
        mode, prog, fleet = s.ap_mode, s.mission_progress_pct, s.fleet_id
        if (
            _VID_LO <= vid <= _VID_HI
            and _T_LO <= t <= _T_HI
            and _LAT_LO <= lat <= _LAT_HI
            and _LON_LO <= lon <= _LON_HI
            and _ALT_LO <= alt <= _ALT_HI
            and _REL_LO <= rel <= _REL_HI
            and _VN_LO <= vn <= _VN_HI
            and _VE_LO <= ve <= _VE_HI
            and _VD_LO <= vd <= _VD_HI
            and _HDG_LO <= hdg < _HDG_LT
            and _ASPD_LO <= aspd <= _ASPD_HI
            and _BAT_LO <= bat <= _BAT_HI
            and _VOLT_LO <= volt <= _VOLT_HI
            and _MODE_LO <= mode <= _MODE_HI
            and _PROG_LO <= prog <= _PROG_HI
            and _FLEET_LO <= fleet <= _FLEET_HI
        ):
            q_t = round(t / _T_RES)
            q_h = round(hdg / _HDG_RES)
            return _PACK(
                RADIO_SCHEMA_VERSION,
                _STATUS_TAG,
                vid,
                (q_t if q_t <= _T_HQ else _T_HQ) % _MS_WRAP,
                round(lat / _LAT_RES),
                round(lon / _LON_RES),
                round(alt / _ALT_RES),
                round(rel / _REL_RES),
                round(vn / _VN_RES),
                round(ve / _VE_RES),
                round(vd / _VD_RES),
                q_h if q_h <= _HDG_HQ else _HDG_HQ,
                round(aspd / _ASPD_RES),
                255 if bat < 0 else bat,
                round(volt / _VOLT_RES),
                (int(s.gps_fix) & 0x7) | min(s.gps_sats, 31) << 3,
                mode,
                (1 if s.armed else 0)
                | (int(s.fsm_state) & 0x3) << 1
                | (int(s.mission_state) & 0xF) << 3,
                prog,
                fleet,
                int(s.alerts),
            )
    except (struct.error, TypeError, ValueError, OverflowError):
        pass
    return _encode_status_checked(s)


def _encode_status_checked(s: VehicleStatus) -> bytes:
    _check_status_ints(s)
    flags = (
        (1 if s.armed else 0) | (int(s.fsm_state) & 0x3) << 1 | (int(s.mission_state) & 0xF) << 3
    )
    gps = (int(s.gps_fix) & 0x7) | min(s.gps_sats, 31) << 3
    try:
        return STATUS_LAYOUT.pack(
            RADIO_SCHEMA_VERSION,
            _STATUS_TAG,
            s.vehicle_id,
            _TIME.enc(s.time_unix_s) % _MS_WRAP,
            _LAT.enc(s.lat_deg),
            _LON.enc(s.lon_deg),
            _ALT.enc(s.alt_msl_m),
            _REL.enc(s.alt_rel_m),
            _VN.enc(s.vel_north_m_s),
            _VE.enc(s.vel_east_m_s),
            _VD.enc(s.vel_down_m_s),
            _HDG.enc(s.heading_deg),
            _ASPD.enc(s.airspeed_m_s),
            255 if s.battery_pct < 0 else s.battery_pct,
            _VOLT.enc(s.battery_v),
            gps,
            s.ap_mode,
            flags,
            s.mission_progress_pct,
            s.fleet_id,
            int(s.alerts),
        )
    except (struct.error, TypeError) as exc:
        raise EncodeError(f"VehicleStatus out of range for the radio layout: {exc}") from exc


def unwrap_time_ms(ms_mod: int, now_unix_s: float) -> float:
    """The UNIX time (s) whose milliseconds mod 2^32 are `ms_mod`, nearest to `now`."""
    now_ms = int(now_unix_s * 1000.0)
    k = round((now_ms - ms_mod) / _MS_WRAP)
    t = ms_mod + k * _MS_WRAP
    if t < 0:
        t += _MS_WRAP
    return t / 1000.0


_UNPACK = STATUS_LAYOUT.unpack_from
# enum members by value (a value missing here is not a member: the checked path says so)
_GPS_FIX = {int(m): m for m in GpsFix}
_FSM = {int(m): m for m in FsmState}
_MISSION = {int(m): m for m in MissionState}
_ALERTS: dict[int, AlertFlag] = {}  # filled as values are seen (at most 2^16)
_LAT_D, _LON_D, _ALT_D, _REL_D = _LAT.digits, _LON.digits, _ALT.digits, _REL.digits
_VN_D, _VE_D, _VD_D, _HDG_D = _VN.digits, _VE.digits, _VD.digits, _HDG.digits
_ASPD_D, _VOLT_D = _ASPD.digits, _VOLT.digits


def _decode_status(data: bytes, now_unix_s: float) -> VehicleStatus:
    """The status layout, fast path: the same status as `_decode_status_checked` (which
    validates through msgspec.convert) for every payload whose values are all within
    the message's bounds, built directly; anything else goes through the checked path
    (for the exact error)."""
    if len(data) >= STATUS_BYTES:
        try:
            (
                _v,
                _t,
                vid,
                t_ms,
                lat,
                lon,
                alt,
                rel,
                vn,
                ve,
                vd,
                hdg,
                aspd,
                batt,
                volt,
                gps,
                mode,
                flags,
                prog,
                fleet,
                alerts,
            ) = _UNPACK(data)
            t = unwrap_time_ms(t_ms, now_unix_s)
            f_lat = round(lat * _LAT_RES, _LAT_D)
            f_lon = round(lon * _LON_RES, _LON_D)
            f_alt = round(alt * _ALT_RES, _ALT_D)
            f_rel = round(rel * _REL_RES, _REL_D)
            f_vn = round(vn * _VN_RES, _VN_D)
            f_ve = round(ve * _VE_RES, _VE_D)
            f_vd = round(vd * _VD_RES, _VD_D)
            f_hdg = round(hdg * _HDG_RES, _HDG_D)
            f_aspd = round(aspd * _ASPD_RES, _ASPD_D)
            f_volt = round(volt * _VOLT_RES, _VOLT_D)
            bat = -1 if batt == 255 else batt
            flag = _ALERTS.get(alerts)
            if flag is None:
                flag = _ALERTS[alerts] = AlertFlag(alerts)
            if (
                _VID_LO <= vid <= _VID_HI
                and _T_LO <= t <= _T_HI
                and _LAT_LO <= f_lat <= _LAT_HI
                and _LON_LO <= f_lon <= _LON_HI
                and _ALT_LO <= f_alt <= _ALT_HI
                and _REL_LO <= f_rel <= _REL_HI
                and _VN_LO <= f_vn <= _VN_HI
                and _VE_LO <= f_ve <= _VE_HI
                and _VD_LO <= f_vd <= _VD_HI
                and _HDG_LO <= f_hdg < _HDG_LT
                and _ASPD_LO <= f_aspd <= _ASPD_HI
                and _BAT_LO <= bat <= _BAT_HI
                and _VOLT_LO <= f_volt <= _VOLT_HI
                and _PROG_LO <= prog <= _PROG_HI
                and _FLEET_LO <= fleet <= _FLEET_HI
            ):
                return VehicleStatus(
                    vid,
                    t,
                    f_lat,
                    f_lon,
                    f_alt,
                    f_rel,
                    f_vn,
                    f_ve,
                    f_vd,
                    f_hdg,
                    f_aspd,
                    bat,
                    f_volt,
                    _GPS_FIX[gps & 0x7],
                    gps >> 3,
                    mode,
                    bool(flags & 1),
                    _FSM[(flags >> 1) & 0x3],
                    _MISSION[(flags >> 3) & 0xF],
                    prog,
                    fleet,
                    flag,
                )
        except _DECODE_FAILURES:
            pass
    return _decode_status_checked(data, now_unix_s)


def _decode_status_checked(data: bytes, now_unix_s: float) -> VehicleStatus:
    if len(data) < STATUS_BYTES:
        raise DecodeError(
            f"VehicleStatus needs {STATUS_BYTES} bytes, got {len(data)}", reason="truncated"
        )
    values: tuple[int, ...] = STATUS_LAYOUT.unpack_from(data)
    (
        _v,
        _t,
        vid,
        t_ms,
        lat,
        lon,
        alt,
        rel,
        vn,
        ve,
        vd,
        hdg,
        aspd,
        batt,
        volt,
        gps,
        mode,
        flags,
        prog,
        fleet,
        alerts,
    ) = values
    fields = {
        "vehicle_id": vid,
        "time_unix_s": unwrap_time_ms(t_ms, now_unix_s),
        "lat_deg": _LAT.dec(lat),
        "lon_deg": _LON.dec(lon),
        "alt_msl_m": _ALT.dec(alt),
        "alt_rel_m": _REL.dec(rel),
        "vel_north_m_s": _VN.dec(vn),
        "vel_east_m_s": _VE.dec(ve),
        "vel_down_m_s": _VD.dec(vd),
        "heading_deg": _HDG.dec(hdg),
        "airspeed_m_s": _ASPD.dec(aspd),
        "battery_pct": -1 if batt == 255 else batt,
        "battery_v": _VOLT.dec(volt),
        "gps_fix": GpsFix(gps & 0x7),
        "gps_sats": gps >> 3,
        "ap_mode": mode,
        "armed": bool(flags & 1),
        "fsm_state": FsmState((flags >> 1) & 0x3),
        "mission_state": MissionState((flags >> 3) & 0xF),
        "mission_progress_pct": prog,
        "fleet_id": fleet,
        "alerts": AlertFlag(alerts),
    }
    return msgspec.convert(fields, VehicleStatus)


# --------------------------------------------------------------------------- public API

_packer = msgspec.msgpack.Encoder()


def encode(msg: msgspec.Struct) -> bytes:
    """Encode a message for the radio. Raises EncodeError for unregistered types or
    values the radio cannot carry."""
    tag = TAG_OF.get(type(msg))
    if tag is None:
        raise EncodeError(f"{type(msg).__name__} has no radio type tag")
    if isinstance(msg, VehicleStatus):
        return _encode_status(msg)
    try:
        body = _plan(type(msg)).enc(msg)
        data = bytes((RADIO_SCHEMA_VERSION, tag)) + _packer.encode(body)
    except (TypeError, ValueError, OverflowError) as exc:
        raise EncodeError(f"{type(msg).__name__}: {exc}") from exc
    try:  # rare messages: prove the receiver can decode what we send
        msgspec.convert(_plan(type(msg)).dec(msgspec.msgpack.decode(data[2:])), type(msg))
    except _DECODE_FAILURES as exc:
        raise EncodeError(f"{type(msg).__name__} is not valid at radio resolution: {exc}") from exc
    return data


def peek_type(data: bytes) -> type:
    """The message type of an encoded radio message, without decoding it."""
    if len(data) < 2:
        raise DecodeError("radio message shorter than its 2-byte header", reason="truncated")
    if data[0] != RADIO_SCHEMA_VERSION:
        raise DecodeError(f"unsupported radio schema version {data[0]}", reason="version")
    cls = TYPE_OF.get(data[1])
    if cls is None:
        raise DecodeError(f"unknown radio message type tag {data[1]}", reason="unknown-type")
    return cls


def decode(data: bytes | bytearray | memoryview, *, now_unix_s: float) -> msgspec.Struct:
    """Decode one radio message. `now_unix_s` resolves the 32-bit millisecond time of a
    VehicleStatus (the nearest match to now; unambiguous within +-24 days)."""
    data = bytes(data)
    cls = peek_type(data)
    try:
        if cls is VehicleStatus:
            return _decode_status(data, now_unix_s)
        raw = msgspec.msgpack.decode(data[2:])
        return msgspec.convert(_plan(cls).dec(raw), cls)
    except DecodeError:
        raise
    except _DECODE_FAILURES as exc:
        raise DecodeError(f"invalid {cls.__name__} radio payload: {exc}") from exc


def quantized(msg: msgspec.Struct, *, now_unix_s: float | None = None) -> msgspec.Struct:
    """What a receiver decodes from `msg`: the message at radio resolution."""
    now = now_unix_s if now_unix_s is not None else getattr(msg, "time_unix_s", 0.0)
    return decode(encode(msg), now_unix_s=now)


_ON_AIR: dict[tuple[type, str], tuple[_Codec, Any]] = {}


def on_air(cls: type[msgspec.Struct], name: str, value: Any) -> Any:
    """Field `name` of a `cls` message holding `value`, as every receiver decodes it from
    the radio (floats on their fixed-point grid, bounds clamped as the encoder does,
    nested structs alike). Idempotent, and bit-identical to what `decode(encode(msg))`
    gives: a sender that computes with the value it publishes computes what its radio
    receivers compute (and its LAN receivers, when it publishes that value). An
    EncodeError for a value the field cannot carry."""
    known = _ON_AIR.get((cls, name))
    if known is None:
        codec = next((c for n, c, _r in _plan(cls).fields if n == name), None)
        if codec is None:
            raise EncodeError(f"{cls.__name__} has no field {name!r}")
        known = _ON_AIR[(cls, name)] = (
            codec,
            typing.get_type_hints(cls, include_extras=True)[name],
        )
    codec, hint = known
    try:
        return msgspec.convert(codec.dec(codec.enc(value)), hint)
    except (TypeError, ValueError, OverflowError, msgspec.MsgspecError) as exc:
        raise EncodeError(f"{cls.__name__}.{name}: {exc}") from exc
