"""Files in and out: GeoJSON, KML, QGroundControl .plan and MAVLink waypoint files for
missions and zones (round trips through each format; a plan as QGroundControl writes
it; bad files refused with one line, exit 2, nothing sent)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gcs_cli.app import run
from gcs_cli.geofiles import (
    GeoFileError,
    mission_geometry,
    read_features,
    save_mission,
    save_zones,
    zone_features,
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
        save_mission(path, m)
        g = mission_geometry(path, m.mission_type)
        if suffix in (".plan", ".waypoints") and m.mission_type == MissionType.AREA:
            # waypoint files have no holes; a .plan survey keeps the outline
            assert close(g, Geometry.polygon(FIELD)), (suffix, g)
        else:
            assert close(g, m.geometry), (suffix, g)
            assert [len(h) for h in g.holes] == [len(h) for h in m.geometry.holes]


@pytest.mark.parametrize("suffix", FORMATS)
def test_zones_round_trip(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"zones{suffix}"
    save_zones(path, ZONES)

    def key(g: Geometry) -> tuple:
        return (g.kind, g.points[0].lat_deg, g.points[0].lon_deg)

    got = sorted(zone_features(path), key=lambda f: key(f.geometry))
    assert len(got) == 3
    for want, f in zip(sorted(ZONES, key=lambda z: key(z.geometry)), got, strict=True):
        assert close(f.geometry, want.geometry), (suffix, f)
        assert (f.role == "inclusion") == want.operating_area


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


def test_mission_file_in_and_save_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "field.geojson"
    save_mission(src, AREA)
    for suffix in FORMATS:
        out = tmp_path / f"saved{suffix}"
        code = run(
            [
                "--connect",
                "tcp/127.0.0.1:9",
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
        assert code == 0, capsys.readouterr()
        assert close(
            Geometry.polygon(FIELD),
            mission_geometry(out, MissionType.AREA).__class__(
                GeometryKind.POLYGON, mission_geometry(out, MissionType.AREA).points
            ),
        )
    saved = json.loads((tmp_path / "saved.json").read_text())
    assert saved["params"]["altitude_rel_m"] == 45.0 and saved["mission_type"] == 1
