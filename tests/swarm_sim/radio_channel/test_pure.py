"""The channel model and the fleet harness are pure (no I/O, no clock), like every core."""

from __future__ import annotations

import pytest

from tests.conftest import REPO
from tests.test_architecture import FORBIDDEN, imported


@pytest.mark.parametrize("name", ["model", "harness"])
def test_emulator_cores_do_no_io(name: str) -> None:
    path = REPO / "swarm_sim" / "radio_channel" / f"{name}.py"
    bad = {n for n in imported(path) if n.split(".")[0] in FORBIDDEN}
    assert not bad, f"{path.name} imports {sorted(bad)}"
