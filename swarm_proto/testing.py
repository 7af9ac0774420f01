"""Hypothesis strategies for every message, derived from the Structs' own constraints.

For tests (of this package and of anything that moves messages): `messages()` draws any
valid message, `message_of(cls)` one type. Requires hypothesis (a test dependency).
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import msgspec
import msgspec.inspect as mi
from hypothesis import assume
from hypothesis import strategies as st

from .enums import GeometryKind, SelectorKind
from .messages import MESSAGE_TYPES, Geometry, LatLon, Selector

_MAX_LIST = 6


def _floats(t: mi.FloatType) -> st.SearchStrategy[float]:
    lo = t.ge if t.ge is not None else t.gt
    hi = t.le if t.le is not None else t.lt
    return st.floats(
        min_value=lo,
        max_value=hi,
        exclude_min=t.gt is not None,
        exclude_max=t.lt is not None,
        allow_nan=False,
        allow_infinity=False,
    )


def _ints(t: mi.IntType) -> st.SearchStrategy[int]:
    lo = t.ge if t.ge is not None else (t.gt + 1 if t.gt is not None else -(2**31))
    hi = t.le if t.le is not None else (t.lt - 1 if t.lt is not None else 2**31)
    return st.integers(min_value=lo, max_value=hi)


def _strategy(t: Any) -> st.SearchStrategy[Any]:
    if isinstance(t, mi.Metadata):
        return _strategy(t.type)
    if isinstance(t, mi.IntType):
        return _ints(t)
    if isinstance(t, mi.FloatType):
        return _floats(t)
    if isinstance(t, mi.BoolType):
        return st.booleans()
    if isinstance(t, mi.BytesType):
        return st.binary(max_size=t.max_length if t.max_length is not None else 32)
    if isinstance(t, mi.StrType):
        return st.text(max_size=t.max_length if t.max_length is not None else 32)
    if isinstance(t, mi.EnumType):
        if issubclass(t.cls, int) and t.cls.__name__ == "AlertFlag":
            return st.integers(0, 0xFFFF).map(t.cls)
        return st.sampled_from(list(t.cls))
    if isinstance(t, mi.NoneType):
        return st.none()
    if isinstance(t, mi.UnionType):
        return st.one_of([_strategy(x) for x in t.types])
    if isinstance(t, mi.VarTupleType):
        return st.lists(_strategy(t.item_type), max_size=_MAX_LIST).map(tuple)
    if isinstance(t, mi.StructType):
        return message_of(t.cls)
    raise TypeError(f"no strategy for {t!r}")


@st.composite
def _ring(draw: st.DrawFn, lat0: float, lon0: float, radius_deg: float) -> tuple[LatLon, ...]:
    """A star-shaped (hence simple) ring around (lat0, lon0)."""
    n = draw(st.integers(3, 10))
    angles = sorted(
        draw(
            st.lists(
                st.floats(0, 2 * math.pi, exclude_max=True), min_size=n, max_size=n, unique=True
            )
        )
    )
    assume(all(b - a > 0.05 for a, b in itertools.pairwise(angles)))
    assume(2 * math.pi - angles[-1] + angles[0] > 0.05)
    rs = draw(st.lists(st.floats(0.5, 1.0), min_size=n, max_size=n))
    return tuple(
        LatLon(lat0 + radius_deg * r * math.sin(a), lon0 + radius_deg * r * math.cos(a))
        for a, r in zip(angles, rs, strict=True)
    )


@st.composite
def geometries(draw: st.DrawFn, kinds: tuple[GeometryKind, ...] = tuple(GeometryKind)) -> Geometry:
    kind = draw(st.sampled_from(kinds))
    lat0 = draw(st.floats(-70, 70))
    lon0 = draw(st.floats(-170, 170))
    pt = st.builds(LatLon, st.floats(-89, 89), st.floats(-179, 179))
    if kind == GeometryKind.POINT:
        return Geometry(kind, (LatLon(lat0, lon0),))
    if kind == GeometryKind.POINTS:
        return Geometry(kind, tuple(draw(st.lists(pt, min_size=1, max_size=_MAX_LIST))))
    if kind == GeometryKind.POLYLINE:
        return Geometry(kind, tuple(draw(st.lists(pt, min_size=2, max_size=_MAX_LIST))))
    if kind == GeometryKind.CIRCLE:
        return Geometry(kind, (LatLon(lat0, lon0),), radius_m=draw(st.floats(1, 50_000)))
    radius = draw(st.floats(0.001, 0.05))
    shell = draw(_ring(lat0, lon0, radius))
    holes: tuple[tuple[LatLon, ...], ...] = ()
    if draw(st.booleans()):
        # a small square hole at the centre (inside every star-shaped shell with r >= 0.5)
        h = radius * 0.1
        holes = (
            (
                LatLon(lat0 - h, lon0 - h),
                LatLon(lat0 - h, lon0 + h),
                LatLon(lat0 + h, lon0 + h),
                LatLon(lat0 + h, lon0 - h),
            ),
        )
    try:
        return Geometry(kind, shell, holes)
    except ValueError:
        assume(False)
        raise


@st.composite
def selectors(draw: st.DrawFn) -> Selector:
    kind = draw(st.sampled_from(list(SelectorKind)))
    if kind == SelectorKind.IDS:
        return Selector(
            kind,
            vehicle_ids=tuple(
                draw(st.lists(st.integers(1, 65534), min_size=1, max_size=_MAX_LIST))
            ),
        )
    if kind == SelectorKind.FLEET:
        return Selector(kind, fleet_id=draw(st.integers(1, 255)))
    if kind == SelectorKind.QUANTITY:
        return Selector(
            kind,
            fleet_id=draw(st.integers(0, 255)),
            quantity=draw(st.integers(1, 255)),
            payload_model=draw(st.text(max_size=16)),
        )
    return Selector(kind)


@st.composite
def _zones(draw: st.DrawFn) -> Any:
    from .messages import NoFlyZone

    floor = draw(st.floats(-1000.0, 7000.0))
    start = draw(st.floats(0.0, 3.9e9))
    return NoFlyZone(
        zone_id=draw(st.integers(1, 2**32 - 1)),
        geometry=draw(
            geometries((GeometryKind.POLYGON, GeometryKind.CIRCLE)).filter(lambda g: not g.holes)
        ),
        floor_alt_msl_m=floor,
        ceiling_alt_msl_m=draw(st.floats(floor + 1.0, 8000.0)),
        valid_from_unix_s=start,
        valid_until_unix_s=draw(st.none() | st.floats(start + 1.0, 4e9)),
        active=draw(st.booleans()),
        name=draw(st.text(max_size=48)),
        operating_area=draw(st.booleans()),
    )


_OVERRIDES: dict[type, Any] = {
    Geometry: lambda: geometries(),
    Selector: lambda: selectors(),
}


def message_of(cls: type) -> st.SearchStrategy[Any]:
    """Any valid instance of a Struct type (cross-field rules respected)."""
    if cls in _OVERRIDES:
        return _OVERRIDES[cls]()
    info = mi.type_info(cls)
    assert isinstance(info, mi.StructType)
    fields = {f.name: _strategy(f.type) for f in info.fields}
    if cls.__name__ == "NoFlyZone":
        return _zones()

    @st.composite
    def build(draw: st.DrawFn) -> Any:
        values = {name: draw(s) for name, s in fields.items()}
        try:
            msg = cls(**values)
            msgspec.convert(msgspec.to_builtins(msg), cls)  # constraints checked on decode only
        except (ValueError, TypeError, msgspec.ValidationError):
            assume(False)
            raise
        return msg

    return build()


def messages() -> st.SearchStrategy[Any]:
    """Any valid message of any registered type."""
    return st.one_of([message_of(cls) for cls in MESSAGE_TYPES])
