"""`make sitl-check` (swarm_sim/sitl_check.py): its command line and its results file.
The full run against swarm-sim vehicles (`--sim`) is a soak test; against real SITL it
is `make sitl-check` (docs/sitl.md)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from swarm_sim import sitl_check


def test_without_sitl_binaries_it_says_what_to_set(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.delenv("ARDUPILOT_SITL_BIN", raising=False)
    assert sitl_check.main(["--out", str(tmp_path / "sitl.json")]) == 2
    assert "ARDUPILOT_SITL_BIN" in capsys.readouterr().out
    assert not (tmp_path / "sitl.json").exists()


def test_the_defaults_are_found_beside_the_build(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import argparse

    monkeypatch.delenv("ARDUPILOT_HOME", raising=False)
    args = argparse.Namespace(bin=str(tmp_path / "ardupilot/build/sitl/bin"))
    h = sitl_check.Harness.__new__(sitl_check.Harness)
    h.args = args
    assert h.defaults_dir() == tmp_path / "ardupilot/Tools/autotest/default_params"
    monkeypatch.setenv("ARDUPILOT_HOME", str(tmp_path / "ap"))
    assert h.defaults_dir() == tmp_path / "ap/Tools/autotest/default_params"


@pytest.mark.soak
def test_the_check_against_swarm_sim_vehicles(tmp_path: Path) -> None:
    """The whole check against the simulator (`make sitl-check SITL_ARGS=--sim`): every
    row runs for both vehicles and the results file has the figures."""
    out = tmp_path / "sitl.json"
    sitl_check.main(["--sim", "--first-instance", "37", "--out", str(out)])
    got = json.loads(out.read_text())
    assert got["target"] == "swarm-sim"
    for kind in ("copter", "quadplane"):
        v = got["vehicles"][kind]
        assert set(v["checks"]) == set(sitl_check.CHECKS)
        assert all(c["detail"] != "not run" for c in v["checks"].values()), v
        for check in ("status", "survey", "rtl/land", "link loss"):
            assert v["checks"][check]["pass"], (kind, check, v["checks"][check])
        assert v["min_zone_clearance_m"] > 0.0
