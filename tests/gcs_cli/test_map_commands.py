"""The map's requests are checked as `gcs` checks them: the same one-line errors as the
command line for the same mistakes (NaN, a self-intersecting polygon, a position off
the Earth, an unknown kind or id), and the same confirmation naming the vehicles."""

from __future__ import annotations

import base64
import json
from pathlib import Path

import pytest

from gcs_cli.app import run
from gcs_cli.map.commands import PageError, prepare, question
from swarm_proto import CommandKind, GeometryKind, MissionType, SelectorKind

NOWHERE = "tcp/127.0.0.1:1"  # every mistake is refused before a session is opened
KNOWN = {1, 2, 7}
BOWTIE = [[37.41, -5.99], [37.42, -5.98], [37.41, -5.98], [37.42, -5.99]]


def cli_error(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    code = run(["--connect", NOWHERE, *argv])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err, err
    return err


def page_error(req: dict) -> str:
    with pytest.raises(PageError) as exc:
        prepare(req, gcs_id=900, known=KNOWN)
    text = str(exc.value)
    assert "\n" not in text and text
    return text


@pytest.mark.parametrize(
    ("req", "argv"),
    [
        (
            {"type": "command", "kind": "takeoff", "value": "nan", "select": {"ids": [1]}},
            ("cmd", "takeoff", "--id", "1", "--value", "nan"),
        ),
        (
            {"type": "command", "kind": "set-base", "point": [91.0, 0.0]},
            ("cmd", "set-base", "--point", "91.0,0.0"),
        ),
        (
            {"type": "command", "kind": "goto", "point": ["nan", 0.0], "select": {"all": True}},
            ("cmd", "goto", "--all", "--point", "nan,0.0"),
        ),
        (
            {"type": "command", "kind": "warp-drive", "select": {"all": True}},
            ("cmd", "warp-drive", "--all"),
        ),
        ({"type": "command", "kind": "rtl"}, ("cmd", "rtl")),  # no selection
        (
            {"type": "command", "kind": "emergency-land", "select": {"all": True}},
            ("cmd", "emergency-land", "--all"),
        ),
        (
            {"type": "zone", "polygon": BOWTIE},
            ("zone", "add", "3", "--polygon", " ".join(f"{a},{b}" for a, b in BOWTIE)),
        ),
        (
            {"type": "zone", "circle": [37.4, -5.9, -5]},
            ("zone", "add", "3", "--circle", "37.4,-5.9,-5"),
        ),
        (
            {"type": "zone", "circle": [37.4, -5.9, 50], "floor": "300", "ceiling": "100"},
            ("zone", "add", "3", "--circle", "37.4,-5.9,50", "--floor", "300", "--ceiling", "100"),
        ),
        (
            {"type": "mission", "mission_type": "area", "polygon": BOWTIE, "select": {"ids": [1]}},
            (
                "mission",
                "area",
                "--id",
                "1",
                "--polygon",
                " ".join(f"{a},{b}" for a, b in BOWTIE),
            ),
        ),
        (
            {"type": "mission", "mission_type": "sightseeing", "point": [37.4, -5.9]},
            ("mission", "sightseeing", "--point", "37.4,-5.9", "--all"),
        ),
        (
            {
                "type": "mission",
                "mission_type": "target",
                "point": [37.4, -5.9],
                "alt": "inf",
                "select": {"all": True},
            },
            ("mission", "target", "--point", "37.4,-5.9", "--all", "--alt", "inf"),
        ),
    ],
    ids=lambda x: x.get("kind", x.get("type")) if isinstance(x, dict) else None,
)
def test_the_same_one_line_error_as_the_command_line(
    req: dict, argv: tuple[str, ...], capsys: pytest.CaptureFixture[str], swarm_db: Path
) -> None:
    mine = page_error(req)
    theirs = cli_error(capsys, *argv)
    assert theirs.endswith(mine), (mine, theirs)  # "gcs cmd: " + the same words


def test_an_unknown_id_or_a_bad_selection_is_refused() -> None:
    assert "no vehicle 99" in page_error(
        {"type": "command", "kind": "rtl", "select": {"ids": [1, 99]}}
    )
    assert "--id" in page_error({"type": "command", "kind": "rtl", "select": {"ids": [0]}})
    assert "--id" in page_error({"type": "command", "kind": "rtl", "select": {"ids": ["x"]}})
    assert "exclude each other" in page_error(
        {"type": "command", "kind": "rtl", "select": {"ids": [1], "all": True}}
    )
    assert "unknown request" in page_error({"type": "launch"})
    # what stops the swarm logic names its vehicles and is confirmed, as on the command line
    assert "say which vehicles" in page_error({"type": "command", "kind": "shutdown"})
    p = prepare(
        {"type": "command", "kind": "shutdown", "select": {"ids": [1]}}, gcs_id=900, known=KNOWN
    )
    assert p.moving
    with pytest.raises(PageError):
        prepare(["not", "an", "object"], gcs_id=900, known=KNOWN)


def test_requests_become_the_messages_the_command_line_sends(swarm_db: Path) -> None:
    p = prepare(
        {"type": "command", "kind": "rtl", "select": {"ids": [2, 1]}}, gcs_id=900, known=KNOWN
    )
    assert p.command is not None and p.command.kind == CommandKind.RTL and p.moving
    assert p.selector.vehicle_ids == (1, 2)
    assert question(p, {1: 0, 2: 0, 7: 0}) == "rtl to vehicles 1, 2?"
    p = prepare({"type": "command", "kind": "rtl", "select": {"fleet": 2}}, gcs_id=900, known=KNOWN)
    assert question(p, {1: 2, 2: 1, 7: 2}) == "rtl to fleet 2 (1, 7)?"
    p = prepare(
        {"type": "zone", "circle": [37.4, -5.9, 50.5], "name": "tower"},
        gcs_id=900,
        known=KNOWN,
        zone_ids={3, 4},
    )
    assert p.zone is not None and p.zone.zone_id == 5 and p.zone.geometry.radius_m == 50.5
    assert p.fixed == {"zone_id": 5} and p.zone.issuer_id == 900
    assert question(p, {1: 0, 2: 0}) == "zone 5 to every vehicle alive (1, 2)?"
    p = prepare(
        {
            "type": "mission",
            "mission_type": "route",
            "line": [[37.41, -5.99], [37.42, -5.98]],
            "count": "2",
            "alt": "60",
        },
        gcs_id=900,
        known=KNOWN,
    )
    assert p.mission is not None and p.mission.selection.kind == SelectorKind.QUANTITY
    assert p.mission.selection.quantity == 2 and p.mission.params.altitude_rel_m == 60.0
    assert p.fixed == {"mission_id": p.mission.mission_id}
    again = prepare(
        {
            "type": "mission",
            "mission_type": "route",
            "line": [[37.41, -5.99], [37.42, -5.98]],
            "count": "2",
            **p.fixed,
        },
        gcs_id=900,
        known=KNOWN,
    )
    assert again.mission is not None and again.mission.mission_id == p.mission.mission_id


def test_a_mission_from_a_file_the_page_read(swarm_db: Path) -> None:
    ring = [[-5.99, 37.41], [-5.98, 37.41], [-5.98, 37.42], [-5.99, 37.42], [-5.99, 37.41]]
    doc = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "properties": {"name": "field"},
                "geometry": {"type": "Polygon", "coordinates": [ring]},
            }
        ],
    }
    data = base64.b64encode(json.dumps(doc).encode()).decode()
    p = prepare(
        {
            "type": "mission",
            "mission_type": "area",
            "file": {"name": "field.geojson", "data": data},
            "select": {"all": True},
        },
        gcs_id=900,
        known=KNOWN,
    )
    assert p.mission is not None and p.mission.mission_type == MissionType.AREA
    assert p.mission.geometry.kind == GeometryKind.POLYGON and len(p.mission.geometry.points) == 4
    bad = {"type": "mission", "mission_type": "area", "select": {"all": True}}
    assert "not base64" in page_error({**bad, "file": {"name": "f.kml", "data": "@@@"}})
    assert "unknown format .exe" in page_error({**bad, "file": {"name": "f.exe", "data": ""}})
    junk = base64.b64encode(b"{not json").decode()
    err = page_error({**bad, "file": {"name": "f.geojson", "data": junk}})
    assert err.startswith("Invalid value for --file: f.geojson:") and "/tmp" not in err
