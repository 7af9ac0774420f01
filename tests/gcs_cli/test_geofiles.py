"""Files in and out: GeoJSON, KML, QGroundControl .plan and MAVLink waypoint files for
missions and zones: round trips through each format keep altitude, overlap, holes, ids
and names where the format has room (a hypothesis property over every format), and say
what it has no room for; files as other tools write them (tests/gcs_cli/data: a
QGroundControl survey plan with fences and a rally point, a Google Earth KML polygon
with a hole in a Folder, a geojson.io polygon and bare Point); bad files refused with
one line, exit 2, nothing sent."""

from __future__ import annotations

import json
import math
import string
from pathlib import Path

import msgspec
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from gcs_cli.app import run
from gcs_cli.geofiles import (
    GeoFileError,
    mission_from_file,
    mission_geometry,
    read_features,
    save_mission,
    save_zones,
    zone_features,
    zones_from_file,
)
from swarm_proto import (
    Geometry,
    GeometryKind,
    LatLon,
    Mission,
    MissionParams,
    MissionType,
    NoFlyZone,
)
from tests.conftest import examples

FIELD = [(37.410, -5.990), (37.410, -5.980), (37.418, -5.980), (37.418, -5.990)]
HOLE = [(37.412, -5.987), (37.412, -5.985), (37.414, -5.985)]
AREA = Mission(
    12,
    900,
    MissionType.AREA,
    Geometry.polygon(FIELD, [HOLE]),
    MissionParams(altitude_rel_m=60.0, side_overlap=0.6),
    name="field",
)
ROUTE = Mission(
    13,
    900,
    MissionType.ROUTE,
    Geometry(
        GeometryKind.POLYLINE, (LatLon(37.41, -5.99), LatLon(37.42, -5.98), LatLon(37.43, -5.99))
    ),
)
ZONES = [
    NoFlyZone(3, Geometry.circle(37.414, -5.986, 35.0), 0.0, 300.0, name="tower"),
    NoFlyZone(4, Geometry.polygon(HOLE), 0.0, 500.0),
    NoFlyZone(8, Geometry.polygon(FIELD), operating_area=True, name="field area"),
]
FORMATS = (".geojson", ".kml", ".plan", ".waypoints", ".json")
DATA = Path(__file__).parent / "data"


def close(a: Geometry, b: Geometry) -> bool:
    pa = [(p.lat_deg, p.lon_deg) for p in a.points]
    pb = [(p.lat_deg, p.lon_deg) for p in b.points]
    return (
        a.kind == b.kind
        and len(pa) == len(pb)
        and all(
            abs(x - u) < 1e-7 and abs(y - v) < 1e-7 for (x, y), (u, v) in zip(pa, pb, strict=True)
        )
        and (a.radius_m or 0) == pytest.approx(b.radius_m or 0)
    )


@pytest.mark.parametrize("suffix", FORMATS)
def test_a_mission_round_trips(tmp_path: Path, suffix: str) -> None:
    for m in (AREA, ROUTE):
        path = tmp_path / f"m{m.mission_id}{suffix}"
        lost = save_mission(path, m)
        fm = mission_from_file(path, m.mission_type)
        g = fm.geometry
        assert close(g, m.geometry), (suffix, g)
        assert fm.params["altitude_rel_m"] == m.params.altitude_rel_m, (suffix, fm.params)
        if suffix in (".waypoints",):
            assert not g.holes and fm.name is None and fm.mission_id is None
            if m.geometry.holes:  # said at export, not dropped silently
                assert "1 hole(s)" in lost and "the name 'field'" in lost, lost
                assert "side overlap 0.6" in lost and f"mission id {m.mission_id}" in lost, lost
            continue
        assert [len(h) for h in g.holes] == [len(h) for h in m.geometry.holes], suffix
        assert fm.params["side_overlap"] == m.params.side_overlap, (suffix, fm.params)
        assert (fm.name, fm.mission_id) == (m.name, m.mission_id), suffix
        if suffix == ".plan" and m.geometry.holes:  # QGroundControl would survey the hole
            assert lost == ["1 hole(s) for QGroundControl (kept for gcs in the file)"], lost
        else:
            assert lost == [], (suffix, lost)


@pytest.mark.parametrize("suffix", FORMATS)
def test_zones_round_trip(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"zones{suffix}"
    lost = save_zones(path, ZONES)

    def key(g: Geometry) -> tuple:
        return (g.kind, g.points[0].lat_deg, g.points[0].lon_deg)

    got = sorted(zones_from_file(path).zones, key=lambda z: key(z.geometry))
    assert len(got) == 3
    for want, z in zip(sorted(ZONES, key=lambda z: key(z.geometry)), got, strict=True):
        assert close(z.geometry, want.geometry), (suffix, z)
        assert z.operating_area == want.operating_area
        if suffix in (".waypoints",):
            assert z.zone_id is None
            continue
        assert (z.zone_id, z.name) == (want.zone_id, want.name), (suffix, z)
        assert (z.floor_alt_msl_m, z.ceiling_alt_msl_m) == (
            want.floor_alt_msl_m,
            want.ceiling_alt_msl_m,
        ), suffix
    if suffix == ".waypoints":
        assert lost[0] == "zone ids 3, 4, 8" and "names 'tower', 'field area'" in lost, lost
        assert "floor and ceiling of 3, 4" in lost, lost
    elif suffix == ".plan":  # QGroundControl's fences are 2-D
        assert len(lost) == 1 and "floor and ceiling of 3, 4" in lost[0], lost
    else:
        assert lost == [], lost


def test_a_plan_as_qgroundcontrol_writes_it(tmp_path: Path) -> None:
    """A survey, waypoints, an inclusion fence polygon, an exclusion circle, rally
    points and the planned home, in QGroundControl's own layout."""
    plan = {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "QGroundControl",
        "mission": {
            "version": 2,
            "firmwareType": 3,
            "vehicleType": 2,
            "cruiseSpeed": 15,
            "hoverSpeed": 5,
            "plannedHomePosition": [37.409, -5.991, 12.5],
            "items": [
                {
                    "type": "SimpleItem",
                    "command": 22,
                    "frame": 3,
                    "autoContinue": True,
                    "doJumpId": 1,
                    "params": [0, 0, 0, None, 37.4095, -5.9905, 30],
                },
                {
                    "type": "ComplexItem",
                    "complexItemType": "survey",
                    "version": 5,
                    "polygon": [list(p) for p in FIELD],
                    "angle": 90,
                    "TransectStyleComplexItem": {"Items": [], "CameraCalc": {}},
                },
                {
                    "type": "SimpleItem",
                    "command": 16,
                    "frame": 3,
                    "autoContinue": True,
                    "doJumpId": 8,
                    "params": [0, 0, 0, None, 37.42, -5.98, 40],
                },
                {
                    "type": "SimpleItem",
                    "command": 20,
                    "frame": 2,
                    "autoContinue": True,
                    "doJumpId": 9,
                    "params": [0, 0, 0, 0, 0, 0, 0],
                },
            ],
        },
        "geoFence": {
            "version": 2,
            "polygons": [
                {
                    "inclusion": True,
                    "version": 1,
                    "polygon": [[37.40, -6.00], [37.40, -5.97], [37.43, -5.97], [37.43, -6.00]],
                }
            ],
            "circles": [
                {
                    "inclusion": False,
                    "version": 1,
                    "circle": {"center": [37.414, -5.986], "radius": 35},
                }
            ],
        },
        "rallyPoints": {"version": 2, "points": [[37.409, -5.991, 40.0]]},
    }
    path = tmp_path / "qgc.plan"
    path.write_text(json.dumps(plan))
    roles = [f.role for f in read_features(path)]
    assert roles == ["home", "area", "route", "inclusion", "exclusion", "rally"]
    assert close(mission_geometry(path, MissionType.AREA), Geometry.polygon(FIELD))
    assert mission_geometry(path, MissionType.ROUTE).kind == GeometryKind.POLYLINE
    zones = zone_features(path)
    assert [z.role for z in zones] == ["inclusion", "exclusion"]
    assert zones[1].geometry.radius_m == 35.0


def test_a_kml_from_an_earth_viewer(tmp_path: Path) -> None:
    path = tmp_path / "field.kml"
    path.write_text("""<?xml version="1.0" encoding="UTF-8"?>
<kml xmlns="http://www.opengis.net/kml/2.2"><Document><name>site</name><Folder><name>f</name>
<Placemark><name>North field</name><Polygon><outerBoundaryIs><LinearRing><coordinates>
-5.990,37.410,0 -5.980,37.410,0 -5.980,37.418,0 -5.990,37.418,0 -5.990,37.410,0
</coordinates></LinearRing></outerBoundaryIs></Polygon></Placemark>
<Placemark><name>road</name><LineString><coordinates>-5.99,37.41 -5.98,37.42</coordinates>
</LineString></Placemark></Folder></Document></kml>""")
    assert close(mission_geometry(path, MissionType.AREA, "North field"), Geometry.polygon(FIELD))
    assert mission_geometry(path, MissionType.ROUTE, "2").kind == GeometryKind.POLYLINE
    with pytest.raises(GeoFileError, match="no feature named 'South'"):
        mission_geometry(path, MissionType.AREA, "South")


BAD_FILES = {
    "empty.geojson": "",
    "garbage.geojson": "{not json",
    "nan.geojson": '{"type": "Polygon", "coordinates": [[[NaN, 0], [1, 1], [1, 0], [NaN, 0]]]}',
    "far.geojson": '{"type": "Point", "coordinates": [0, 95]}',
    "crossed.geojson": json.dumps(
        {
            "type": "Polygon",
            "coordinates": [
                [[-5.99, 37.41], [-5.98, 37.42], [-5.98, 37.41], [-5.99, 37.42], [-5.99, 37.41]]
            ],
        }
    ),
    "broken.kml": "<kml><Document><Placemark>",
    "notplan.plan": '{"fileType": "Something"}',
    "nan.plan": json.dumps(
        {
            "fileType": "Plan",
            "mission": {
                "items": [
                    {
                        "type": "ComplexItem",
                        "complexItemType": "survey",
                        "polygon": [[37.41, -5.99], [37.41, -5.98], ["x", -5.98]],
                    }
                ]
            },
        }
    ),
    "bad.waypoints": "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\tabc\t-5.9\t10\t1\n",
    # the right fileType, the wrong structure ("'str' object has no attribute 'get'")
    "str-mission.plan": '{"fileType": "Plan", "mission": "survey"}',
    "str-items.plan": '{"fileType": "Plan", "mission": {"items": ["a", "b"]}}',
    "str-fence.plan": '{"fileType": "Plan", "geoFence": {"polygons": [{"polygon": "x"}]}}',
    "short-rally.plan": '{"fileType": "Plan", "rallyPoints": {"points": [[37.4]]}}',
    "list-props.geojson": json.dumps(
        {"type": "Feature", "properties": [1], "geometry": {"type": "Point", "coordinates": [0, 1]}}
    ),
    "field.shp": "whatever",
}


def test_bad_files_are_one_line_exit_2_nothing_sent(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for name, text in BAD_FILES.items():
        path = tmp_path / name
        path.write_text(text)
        for args in (
            ["mission", "area", "--file", str(path), "--all", "--dry-run"],
            ["zone", "import", str(path)],
        ):
            # an unreachable router: had anything been sent, it would say so (exit 1)
            code = run(["--connect", "tcp/127.0.0.1:9", *args])
            err = capsys.readouterr().err
            assert code == 2, (name, args, err)
            assert len(err.strip().splitlines()) == 1 and str(path) in err, (name, err)


def test_mission_file_in_and_save_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], zenoh_router: str, swarm_db: Path
) -> None:
    """A mission read from a file and saved in every format: the file's altitude is
    overridden by --alt (given), everything else kept; the dry run asks the swarm (here
    nobody: the fleet's checks are not run) and sends nothing."""
    src = tmp_path / "field.geojson"
    save_mission(src, AREA)
    for suffix in FORMATS:
        out = tmp_path / f"saved{suffix}"
        code = run(
            [
                "--connect",
                zenoh_router,
                "mission",
                "area",
                "--file",
                str(src),
                "--all",
                "--alt",
                "45",
                "--dry-run",
                "--save",
                str(out),
            ]
        )
        text = capsys.readouterr().out
        assert code == 0, text
        assert "from field.geojson: altitude 60 m, " in text and "side overlap 0.6" in text, text
        assert "no vehicle it addresses is alive" in text, text
        fm = mission_from_file(out, MissionType.AREA)
        assert close(Geometry.polygon(FIELD), Geometry(GeometryKind.POLYGON, fm.geometry.points))
        assert fm.params["altitude_rel_m"] == 45.0, (suffix, fm.params)
        if suffix == ".waypoints":
            assert "warning: saved.waypoints cannot carry: 1 hole(s); mission id" in text, text
        else:
            assert fm.params["side_overlap"] == 0.6 and fm.name == "field", (suffix, fm)
    saved = json.loads((tmp_path / "saved.json").read_text())
    assert saved["params"]["altitude_rel_m"] == 45.0 and saved["mission_type"] == 1
    assert saved["geometry"]["holes"] and saved["name"] == "field"


# --------------------------------------------------------------------------- as written by others


def test_a_qgroundcontrol_survey_plan() -> None:
    """QGroundControl's own survey at 50 m flew at the database's 100 m: its altitude
    and side overlap are read; the fences are zones, the rest listed with why."""
    plan = DATA / "qgc-survey.plan"
    fm = mission_from_file(plan, MissionType.AREA)
    assert fm.params == {"altitude_rel_m": 50.0, "side_overlap": 0.6}
    assert fm.geometry.kind == GeometryKind.POLYGON and len(fm.geometry.points) == 4
    zf = zones_from_file(plan)
    assert [(z.operating_area, z.geometry.kind) for z in zf.zones] == [
        (True, GeometryKind.POLYGON),
        (False, GeometryKind.POLYGON),
        (False, GeometryKind.CIRCLE),
    ]
    assert zf.zones[2].geometry.radius_m == 20.0 and all(z.zone_id is None for z in zf.zones)
    skipped = {s.what: s.why for s in zf.skipped}
    assert "a rally point" in skipped["rally 'rally 1' (point)"]
    assert "a survey area is a mission" in skipped["area 'survey 2' (polygon)"]
    assert "planned home" in skipped["home 'home' (point)"]
    assert zf.rally == [(37.4108, -5.9895, 30.0)] and zf.home == (37.4112, -5.9889, 10.0)


def test_a_google_earth_polygon_with_a_hole_in_a_folder() -> None:
    kml = DATA / "google-earth.kml"
    fm = mission_from_file(kml, MissionType.AREA)
    assert fm.name == "Olive grove" and len(fm.geometry.holes) == 1 and fm.params == {}
    zf = zones_from_file(kml)
    assert len(zf.zones) == 1 and not zf.zones[0].geometry.holes
    assert zf.zones[0].name == "Olive grove"
    (skip,) = zf.skipped
    assert skip.what == "hole 1 of no-fly zone 'Olive grove'" and "all of it" in skip.why


def test_an_operating_areas_hole_becomes_a_no_fly_zone(tmp_path: Path) -> None:
    area = NoFlyZone(8, Geometry.polygon(FIELD), operating_area=True, name="field area")
    path = tmp_path / "area.geojson"
    save_zones(path, [area])
    data = json.loads(path.read_text())
    data["features"][0]["geometry"]["coordinates"].append([[lo, la] for la, lo in [*HOLE, HOLE[0]]])
    path.write_text(json.dumps(data))
    zf = zones_from_file(path)
    assert [(z.operating_area, z.zone_id, z.name) for z in zf.zones] == [
        (True, 8, "field area"),
        (False, None, "field area hole 1"),
    ]
    assert close(zf.zones[1].geometry, Geometry.polygon(HOLE)) and zf.skipped == []


def test_a_geojson_io_polygon_and_a_bare_point() -> None:
    path = DATA / "geojson-io.geojson"
    assert mission_geometry(path, MissionType.AREA).kind == GeometryKind.POLYGON
    assert mission_geometry(path, MissionType.TARGET).kind == GeometryKind.POINT
    zf = zones_from_file(path)
    assert len(zf.zones) == 1
    (skip,) = zf.skipped
    assert skip.what == "point 'feature 2' (point)" and "a circle needs a radius" in skip.why


def test_kml_altitude_modes(tmp_path: Path) -> None:
    """relativeToGround is the height above home; absolute is noted, not used."""

    def placemark(mode: str, z: float) -> str:
        ring = " ".join(f"{lo},{la},{z}" for la, lo in [*FIELD, FIELD[0]])
        return (
            '<kml xmlns="http://www.opengis.net/kml/2.2"><Document><Placemark><name>f</name>'
            f"<Polygon><altitudeMode>{mode}</altitudeMode><outerBoundaryIs><LinearRing>"
            f"<coordinates>{ring}</coordinates></LinearRing></outerBoundaryIs></Polygon>"
            "</Placemark></Document></kml>"
        )

    path = tmp_path / "f.kml"
    path.write_text(placemark("relativeToGround", 42.5))
    assert mission_from_file(path, MissionType.AREA).params == {"altitude_rel_m": 42.5}
    path.write_text(placemark("absolute", 420.0))
    fm = mission_from_file(path, MissionType.AREA)
    assert fm.params == {} and "above sea level" in fm.notes[0]


# --------------------------------------------------------------------------- property

NAMES = st.text(string.ascii_letters + string.digits + " -_.&<", max_size=20).map(str.strip)
LAT, LON = st.floats(20.0, 60.0), st.floats(-20.0, 30.0)


@st.composite
def shapes(draw: st.DrawFn, kind: GeometryKind, holes: bool = False) -> Geometry:
    lat0, lon0 = draw(LAT), draw(LON)
    if kind in (GeometryKind.POINT, GeometryKind.CIRCLE):
        r = draw(st.floats(1.0, 5000.0)) if kind == GeometryKind.CIRCLE else None
        return Geometry(kind, (LatLon(lat0, lon0),), radius_m=r)
    if kind in (GeometryKind.POINTS, GeometryKind.POLYLINE):
        n = draw(st.integers(2 if kind == GeometryKind.POLYLINE else 1, 6))
        offs = draw(  # distinct points (a route has no zero-length leg)
            st.lists(
                st.tuples(st.floats(-0.01, 0.01), st.floats(-0.01, 0.01)),
                min_size=n,
                max_size=n,
                unique_by=lambda ab: (round(ab[0], 6), round(ab[1], 6)),
            )
        )
        return Geometry(kind, tuple(LatLon(lat0 + a, lon0 + b) for a, b in offs))
    n = draw(st.integers(3, 9))
    size = draw(st.floats(0.001, 0.02))
    rs = draw(st.lists(st.floats(0.6, 1.0), min_size=n, max_size=n))
    shell = tuple(
        LatLon(
            lat0 + size * r * math.sin(2 * math.pi * k / n),
            lon0 + size * r * math.cos(2 * math.pi * k / n),
        )
        for k, r in enumerate(rs)
    )
    hole = ()
    if holes and draw(st.booleans()):
        h = size * 0.2
        hole = ((LatLon(lat0 - h, lon0 - h), LatLon(lat0 - h, lon0 + h), LatLon(lat0 + h, lon0)),)
    return Geometry(kind, shell, hole)


KINDS = {
    MissionType.AREA: (GeometryKind.POLYGON,),
    MissionType.PERIMETER: (GeometryKind.POLYGON, GeometryKind.CIRCLE),
    MissionType.TARGET: (GeometryKind.POINT, GeometryKind.CIRCLE),
    MissionType.ROUTE: (GeometryKind.POLYLINE,),
    MissionType.OBJECTIVE: (GeometryKind.POINTS, GeometryKind.POINT),
}


@st.composite
def missions(draw: st.DrawFn) -> Mission:
    mtype = draw(st.sampled_from(sorted(KINDS)))
    kind = draw(st.sampled_from(KINDS[mtype]))
    params = MissionParams(
        altitude_rel_m=draw(st.floats(1.0, 4000.0)),
        speed_m_s=draw(st.none() | st.floats(1.0, 40.0)),
        side_overlap=draw(st.floats(0.05, 0.95)),
        radius_m=draw(st.none() | st.floats(5.0, 900.0)),
        duration_s=draw(st.none() | st.floats(1.0, 3600.0)),
        loops=draw(st.integers(0, 20)),
    )
    return Mission(
        draw(st.integers(1, 2**32 - 1)),
        900,
        mtype,
        draw(shapes(kind, holes=mtype == MissionType.AREA)),
        params,
        name=draw(NAMES),
    )


@st.composite
def zone_lists(draw: st.DrawFn) -> list[NoFlyZone]:
    ids = draw(st.lists(st.integers(1, 2**32 - 1), min_size=1, max_size=4, unique=True))
    out = []
    for zid in ids:
        floor = draw(st.floats(-1000.0, 4000.0))
        out.append(
            NoFlyZone(
                zid,
                draw(shapes(draw(st.sampled_from((GeometryKind.POLYGON, GeometryKind.CIRCLE))))),
                floor,
                draw(st.floats(floor + 1.0, 8000.0)),
                name=draw(NAMES),
                operating_area=draw(st.booleans()),
            )
        )
    return out


def same_shape(a: Geometry, b: Geometry, tol: float) -> bool:
    def pts(ring: tuple[LatLon, ...]) -> list[tuple[float, float]]:
        return [(p.lat_deg, p.lon_deg) for p in ring]

    rings_a, rings_b = [a.points, *a.holes], [b.points, *b.holes]
    return (
        a.kind == b.kind
        and len(rings_a) == len(rings_b)
        and all(
            len(ra) == len(rb)
            and all(
                math.isclose(x, u, abs_tol=tol) and math.isclose(y, v, abs_tol=tol)
                for (x, y), (u, v) in zip(pts(ra), pts(rb), strict=True)
            )
            for ra, rb in zip(rings_a, rings_b, strict=True)
        )
        and a.radius_m == b.radius_m
    )


@settings(
    max_examples=examples(20),
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(m=missions(), zones=zone_lists())
# a survey's overlap as QGroundControl's percentage: 0.4773198971981235 * 100 / 100 is
# 0.47731989719812357
@example(
    m=Mission(
        1,
        900,
        MissionType.AREA,
        Geometry.polygon([(20.0, 0.015625), (20.0135, -0.0078), (19.9865, -0.0078)]),
        MissionParams(altitude_rel_m=1.0, side_overlap=0.4773198971981235),
    ),
    zones=[NoFlyZone(1, Geometry.circle(20.0, 0.0, 50.0))],
)
def test_every_format_round_trips_what_it_carries(
    tmp_path: Path, m: Mission, zones: list[NoFlyZone]
) -> None:
    """Export, import, compare: every format gives back the geometry, and the altitude;
    all but a waypoint file the holes, ids, names, heights and every parameter; a
    waypoint file names at export what it loses. Importing what was imported and
    exporting it again writes the same file."""
    for suffix in FORMATS:
        path = tmp_path / f"m{suffix}"
        lost = save_mission(path, m)
        fm = mission_from_file(path, m.mission_type)
        tol = 5e-9 if suffix == ".waypoints" else 0.0
        g = fm.geometry
        if suffix == ".waypoints":
            # one waypoint: a point (an objective's single point the same)
            one = m.geometry.kind == GeometryKind.POINTS and len(m.geometry.points) == 1
            kind = GeometryKind.POINT if one else m.geometry.kind
            flat = Geometry(kind, m.geometry.points, (), m.geometry.radius_m)
            assert same_shape(g, flat, tol), (suffix, g, m.geometry)
            assert fm.params["altitude_rel_m"] == m.params.altitude_rel_m
            assert (m.geometry.holes != ()) == any("hole" in x for x in lost), lost
            assert f"mission id {m.mission_id}" in lost
            assert (m.name != "") == any(x.startswith("the name") for x in lost), lost
        else:
            assert same_shape(g, m.geometry, tol), (suffix, g, m.geometry)
            back = msgspec.convert(
                {**msgspec.to_builtins(MissionParams()), **fm.params}, MissionParams
            )
            assert back == m.params, (suffix, fm.params, m.params)
            assert (fm.name, fm.mission_id) == (m.name, m.mission_id), suffix
            again = Mission(fm.mission_id or 1, 900, m.mission_type, g, back, name=fm.name or "")
            second = tmp_path / f"again{suffix}"
            save_mission(second, again)
            assert second.read_text() == path.read_text().replace(
                f'"time_unix_s": {m.time_unix_s}', f'"time_unix_s": {again.time_unix_s}'
            ), suffix
        zpath = tmp_path / f"z{suffix}"
        lost = save_zones(zpath, zones)
        got = zones_from_file(zpath).zones
        assert len(got) == len(zones), suffix
        order = (
            sorted(zones, key=lambda z: z.geometry.kind != GeometryKind.POLYGON)
            if suffix == ".plan"
            else zones
        )
        for want, z in zip(order, got, strict=True):
            assert same_shape(z.geometry, want.geometry, tol), (suffix, z, want)
            assert z.operating_area == want.operating_area
            if suffix == ".waypoints":
                continue
            assert (z.zone_id, z.name, z.floor_alt_msl_m, z.ceiling_alt_msl_m) == (
                want.zone_id,
                want.name,
                want.floor_alt_msl_m,
                want.ceiling_alt_msl_m,
            ), suffix
        if suffix == ".waypoints":
            assert lost and lost[0].startswith("zone ids "), lost
