"""Functional core, imperative shell: pure modules never import I/O or read the clock,
nor the shells (runtime/) or the database. Fails closed: every swarm_proto module is
pure unless it is named a shell here, and relative imports are resolved and checked
like absolute ones."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.conftest import REPO

FORBIDDEN = {
    "zenoh",
    "serial",
    "asyncio",
    "socket",
    "time",
    "threading",
    "sqlite3",
    "subprocess",
    "signal",
    "datetime",
    "multiprocessing",
    "concurrent",
    "os",
    "selectors",
}
FORBIDDEN_FROM = {
    "pymavlink.mavutil",  # the MAVLink parser (pymavlink.dialects) is pure
    # the shells and the database: a core is fed by them, never calls them
    "swarm_node.runtime",
    "swarm_node.database",
    "swarm_node.cli",
    "radio_gateway.runtime",
    "swarm_sim.runtime",
    "gcs_cli.runtime",
    "swarm_proto.session",
    "swarm_proto.clock",
    "swarm_proto.shutdown",
}

#: swarm_proto modules that do I/O (everything else in swarm_proto must be pure)
SHELL_PROTO = {"__init__", "clock", "session", "shutdown"}


def pure_files() -> list[Path]:
    files = [f for f in sorted((REPO / "swarm_proto").glob("*.py")) if f.stem not in SHELL_PROTO]
    for pkg in ("swarm_node", "radio_gateway", "swarm_sim", "gcs_cli"):
        core = REPO / pkg / "core"
        if core.is_dir():
            files += sorted(core.rglob("*.py"))
    return files


def module_of(path: Path) -> list[str]:
    return list(path.relative_to(REPO).with_suffix("").parts)


def imported(path: Path) -> set[str]:
    """Every module (and module.name) `path` imports, relative imports resolved."""
    names: set[str] = set()
    package = module_of(path)[:-1]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - (node.level - 1)]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            names.add(module)
            names.update(f"{module}.{a.name}" for a in node.names)
    return names


def test_relative_imports_are_resolved() -> None:
    here = REPO / "swarm_node" / "core" / "routes.py"
    assert "swarm_node.core.outputs" in imported(here)  # from . import outputs
    assert "swarm_node.core.mission.coordinator.MissionCoordinator" in imported(here)
    shell = REPO / "swarm_node" / "runtime" / "node.py"
    assert "swarm_node.core.node.NodeCore" in imported(shell)


def test_the_rules_catch_a_core_importing_a_shell(tmp_path: Path) -> None:
    core = REPO / "swarm_node" / "core" / "_probe_.py"
    try:
        core.write_text("from ..runtime import node\nfrom ..database import SwarmDatabase\n")
        assert violations(core) == {
            "swarm_node.runtime",
            "swarm_node.runtime.node",
            "swarm_node.database",
            "swarm_node.database.SwarmDatabase",
        }
    finally:
        core.unlink()


def violations(path: Path) -> set[str]:
    return {
        n
        for n in imported(path)
        if n.split(".")[0] in FORBIDDEN
        or any(n == f or n.startswith(f + ".") for f in FORBIDDEN_FROM)
    }


@pytest.mark.parametrize("path", pure_files(), ids=lambda p: str(p.relative_to(REPO)))
def test_pure_modules_do_no_io(path: Path) -> None:
    bad = violations(path)
    assert not bad, f"{path.relative_to(REPO)} imports {sorted(bad)}: move I/O to runtime/"
