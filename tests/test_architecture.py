"""Functional core, imperative shell: pure modules never import I/O or read the clock."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.conftest import REPO

FORBIDDEN = {"zenoh", "serial", "asyncio", "socket", "time", "threading", "sqlite3", "subprocess"}
FORBIDDEN_FROM = {"pymavlink.mavutil"}  # the MAVLink parser (pymavlink.dialects) is pure

PURE_PROTO = [
    "messages",
    "enums",
    "units",
    "errors",
    "lan",
    "radio",
    "topics",
    "keyspace_doc",
    "ardupilot",
]


def pure_files() -> list[Path]:
    files = [REPO / "swarm_proto" / f"{m}.py" for m in PURE_PROTO]
    for pkg in ("swarm_node", "radio_gateway", "swarm_sim", "gcs_cli"):
        core = REPO / pkg / "core"
        if core.is_dir():
            files += sorted(core.rglob("*.py"))
    return files


def imported(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{a.name}" for a in node.names)
    return names


@pytest.mark.parametrize("path", pure_files(), ids=lambda p: str(p.relative_to(REPO)))
def test_pure_modules_do_no_io(path: Path) -> None:
    bad = {
        n
        for n in imported(path)
        if n.split(".")[0] in FORBIDDEN or any(n.startswith(f) for f in FORBIDDEN_FROM)
    }
    assert not bad, f"{path.relative_to(REPO)} imports {sorted(bad)}: move I/O to runtime/"
