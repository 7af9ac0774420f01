"""The mission manager's phases (mission/phases.py): a checked table, every phase
reachable, the documented diagram generated from it."""

from __future__ import annotations

import pytest

from swarm_node.core.mission.phases import TRANSITIONS, IllegalMove, Phase, Step, go, mermaid
from tests.conftest import REPO


def test_every_phase_is_reachable_from_idle_and_back() -> None:
    seen, todo = {Phase.IDLE}, [Phase.IDLE]
    while todo:
        p = todo.pop()
        for (a, _), b in TRANSITIONS.items():
            if a == p and b not in seen:
                seen.add(b)
                todo.append(b)
    assert seen == set(Phase)
    assert all(go(p, Step.STOP) == Phase.IDLE for p in Phase)


def test_every_step_is_used() -> None:
    assert {step for _, step in TRANSITIONS} == set(Step)


def test_an_illegal_move_raises() -> None:
    with pytest.raises(IllegalMove):
        go(Phase.IDLE, Step.TOOK_OFF)
    assert go(go(go(Phase.IDLE, Step.PLANNED), Step.TOOK_OFF), Step.CLIMBED) == Phase.STARTING


def test_the_documented_diagram_is_the_table() -> None:
    assert mermaid() in (REPO / "docs" / "state-machine.md").read_text(), "run make docs"
