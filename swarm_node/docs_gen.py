"""Regenerate the diagrams in docs/state-machine.md from their tables (`make docs`):
the swarm state machine (`core/state_machine.RULES`), the sortie
(`core/mission/sortie.TRANSITIONS`) and the mission manager's phases
(`core/mission/phases.TRANSITIONS`). Each diagram is the mermaid block after its
marker line."""

from __future__ import annotations

import sys
from pathlib import Path

from .core import state_machine
from .core.mission import phases, sortie

MARKERS = {
    "## Diagram (generated from the table: `python -m swarm_node.core.state_machine`)": (
        state_machine.mermaid
    ),
    "## Sortie diagram (generated from the table: `python -m swarm_node.core.mission.sortie`)": (
        sortie.mermaid
    ),
    "## Phase diagram (generated from the table: `python -m swarm_node.core.mission.phases`)": (
        phases.mermaid
    ),
}


def regenerate(text: str) -> str:
    lines = text.splitlines(keepends=True)
    out: list[str] = []
    i = 0
    while i < len(lines):
        out.append(lines[i])
        gen = MARKERS.get(lines[i].strip())
        i += 1
        if gen is None:
            continue
        while i < len(lines) and not lines[i].startswith("```mermaid"):
            out.append(lines[i])
            i += 1
        if i == len(lines):
            raise SystemExit(f"no mermaid block after {out[-1].strip()!r}")
        end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
        out += ["```mermaid\n", gen(), "```\n"]
        i = end + 1
    return "".join(out)


def main(argv: list[str]) -> None:
    path = Path(argv[0] if argv else "docs/state-machine.md")
    path.write_text(regenerate(path.read_text()))


if __name__ == "__main__":
    main(sys.argv[1:])
