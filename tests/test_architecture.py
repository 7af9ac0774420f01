"""The architecture, checked from the source.

Functional core, imperative shell: pure modules never import I/O or read the clock,
nor the shells (runtime/) or the database. Fails closed: every swarm_proto module is
pure unless it is named a shell here, and relative imports are resolved and checked
like absolute ones.

Structure (below): no import circle in the packages (module-level and function-local
imports count, `if TYPE_CHECKING:` imports do not); no module uses another module's
private names; a state machine is fed only by the module that owns it."""

from __future__ import annotations

import ast
import functools
import itertools
import sys
import textwrap
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
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


def imported(path: Path, text: str | None = None) -> set[str]:
    """Every module (and module.name) `path` imports (its `text`, if given), relative
    imports resolved."""
    names: set[str] = set()
    package = module_of(path)[:-1]
    source = path.read_text() if text is None else text
    for node in ast.walk(ast.parse(source, str(path))):
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


def test_the_rules_catch_a_core_importing_a_shell() -> None:
    core = REPO / "swarm_node" / "core" / "probe.py"  # never written: its text is given
    text = "from ..runtime import node\nfrom ..database import SwarmDatabase\n"
    assert violations(core, text) == {
        "swarm_node.runtime",
        "swarm_node.runtime.node",
        "swarm_node.database",
        "swarm_node.database.SwarmDatabase",
    }


def violations(path: Path, text: str | None = None) -> set[str]:
    return {
        n
        for n in imported(path, text)
        if n.split(".")[0] in FORBIDDEN
        or any(n == f or n.startswith(f + ".") for f in FORBIDDEN_FROM)
    }


@pytest.mark.parametrize("path", pure_files(), ids=lambda p: str(p.relative_to(REPO)))
def test_pure_modules_do_no_io(path: Path) -> None:
    bad = violations(path)
    assert not bad, f"{path.relative_to(REPO)} imports {sorted(bad)}: move I/O to runtime/"


# =========================================================================== structure
# Three rules over every module of the five packages, read from the source (AST) so that
# nothing is imported to check it. Each fails closed: a new module is checked without
# being named here, and the only exceptions are the named lists below.

PACKAGES = ("swarm_proto", "swarm_node", "radio_gateway", "gcs_cli", "swarm_sim")


@dataclass(frozen=True)
class Module:
    name: str  # dotted: swarm_sim.core.autopilot (a package: its __init__'s name)
    path: Path
    is_package: bool
    tree: ast.Module

    @property
    def package(self) -> str:
        """The package relative imports start from."""
        return self.name if self.is_package else self.name.rpartition(".")[0]


def modules_under(root: Path, packages: tuple[str, ...] = PACKAGES) -> dict[str, Module]:
    out: dict[str, Module] = {}
    for pkg in packages:
        for path in sorted((root / pkg).rglob("*.py")):
            parts = list(path.relative_to(root).with_suffix("").parts)
            is_package = parts[-1] == "__init__"
            name = ".".join(parts[:-1] if is_package else parts)
            out[name] = Module(name, path, is_package, ast.parse(path.read_text(), str(path)))
    return out


#: the tests that read the whole repository's trees run on one worker, which parses them once
ON_THE_REPO = pytest.mark.xdist_group("architecture")


@functools.cache
def repo_modules() -> dict[str, Module]:
    return modules_under(REPO)


def file_of(m: Module, root: Path = REPO) -> str:
    return m.path.relative_to(root).as_posix()


# --------------------------------------------------------------------- (a) import circles


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def runtime_imports(tree: ast.AST) -> list[ast.Import | ast.ImportFrom]:
    """Every import statement that runs: at module level, in classes and in functions
    (a function-local import is a dependency all the same: it only moves the circle to
    call time), but not under `if TYPE_CHECKING:` (annotations only; its `else:` runs)."""
    found: list[ast.Import | ast.ImportFrom] = []

    def visit(node: ast.AST) -> None:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            found.append(node)
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            children: list[ast.stmt] | Iterator[ast.AST] = node.orelse
        else:
            children = ast.iter_child_nodes(node)
        for child in children:
            visit(child)

    visit(tree)
    return found


def _known(name: str, modules: dict[str, Module]) -> str | None:
    """The package module `name` is, or is in (a.b.C -> a.b); None outside the packages."""
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def imported_modules(m: Module, modules: dict[str, Module]) -> dict[str, int]:
    """The package modules `m` imports -> the line of the first such import. `from p
    import x` is a dependency on the module p.x if there is one, else on p; importing
    p.q does not count as importing p's __init__ (every package would be in a circle
    with the modules its __init__ re-exports)."""
    deps: dict[str, int] = {}
    for node in runtime_imports(m.tree):
        targets: list[str | None] = []
        if isinstance(node, ast.Import):
            targets = [_known(a.name, modules) for a in node.names]
        else:
            base = _absolute(node, m)
            for a in node.names:
                full = f"{base}.{a.name}" if base else a.name
                targets.append(full if full in modules else _known(base, modules))
        for t in targets:
            if t is not None and t != m.name:
                deps.setdefault(t, node.lineno)
    return deps


def _absolute(node: ast.ImportFrom, m: Module) -> str:
    if not node.level:
        return node.module or ""
    parts = m.package.split(".")
    base = parts[: len(parts) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def import_circles(modules: dict[str, Module]) -> list[list[str]]:
    """Each set of modules that import each other, directly or round a longer circle (a
    strongly connected component of more than one module), smallest first."""
    graph = {name: imported_modules(m, modules) for name, m in modules.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def strong(v: str) -> None:  # Tarjan
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                components.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            strong(v)
    return sorted(components, key=len)


def circle_through(component: list[str], modules: dict[str, Module]) -> list[str]:
    """A shortest way round from the component's first module back to it."""
    graph = {name: imported_modules(modules[name], modules) for name in component}
    start, inside = component[0], set(component)
    came: dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(graph[v]):
                if w == start:
                    path = [v]
                    while path[-1] != start:
                        path.append(came[path[-1]])
                    return [*reversed(path), start]
                if w in inside and w not in came:
                    came[w] = v
                    nxt.append(w)
        frontier = nxt
    return component  # unreachable for a strongly connected component


def describe_circle(component: list[str], modules: dict[str, Module], root: Path = REPO) -> str:
    """The component's files, and one circle through it, import by import."""
    steps = [
        f"{file_of(modules[a], root)}:{imported_modules(modules[a], modules)[b]} imports {b}"
        for a, b in itertools.pairwise(circle_through(component, modules))
    ]
    files = ", ".join(file_of(modules[n], root) for n in component)
    return f"import circle of {len(component)} files: {files}\n    " + "\n    ".join(steps)


@ON_THE_REPO
def test_no_import_circle_in_the_packages() -> None:
    modules = repo_modules()
    circles = import_circles(modules)
    assert not circles, "\n".join(describe_circle(c, modules) for c in circles)


# ------------------------------------------------------------- (b) reach-ins into privates

#: namedtuple's public API and the standard library's names that start with one
#: underscore and are public
PUBLIC_UNDERSCORE = frozenset(
    {"_replace", "_asdict", "_fields", "_make", "_field_defaults", "_exit"}
)


#: a library's internals set on purpose (file, name): the fast MAVLink decoder builds
#: pymavlink's message objects as pymavlink's own parser does, with the fields its
#: pack() and get_header() read, which have no public setter
LIBRARY_INTERNALS = frozenset(
    {
        ("swarm_node/core/autopilot/mavcodec.py", "_header"),
        ("swarm_node/core/autopilot/mavcodec.py", "_msgbuf"),
        ("swarm_node/core/autopilot/mavcodec.py", "_payload"),
        ("swarm_node/core/autopilot/mavcodec.py", "_signed"),
    }
)


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def own_privates(tree: ast.AST) -> set[str]:
    """The private names a module defines: its functions, classes, methods and
    variables (at any level, class fields too) and the attributes it assigns on `self`
    or `cls`. Assigning another object's attribute does not make it the module's."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif (
            isinstance(node, ast.Attribute)
            and isinstance(node.ctx, (ast.Store, ast.Del))
            and isinstance(node.value, ast.Name)
            and node.value.id in ("self", "cls")
        ):
            names.add(node.attr)
    return {n for n in names if _private(n)}


def _module_aliases(m: Module, modules: dict[str, Module]) -> dict[str, str]:
    """Local names bound to package modules by `import a.b as x` / `from a import b`."""
    aliases: dict[str, str] = {}
    for node in runtime_imports(m.tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.asname and a.name in modules:
                    aliases[a.asname] = a.name
        else:
            base = _absolute(node, m)
            for a in node.names:
                full = f"{base}.{a.name}" if base else a.name
                if full in modules:
                    aliases[a.asname or a.name] = full
    return aliases


@dataclass(frozen=True, order=True)
class ReachIn:
    file: str
    line: int
    name: str
    code: str

    def __str__(self) -> str:
        return f"{self.file}:{self.line}: {self.code}"


def reach_ins(m: Module, modules: dict[str, Module], root: Path = REPO) -> list[ReachIn]:
    """Where module `m` uses another module's private names: `x._name` (x not `self` or
    `cls`; `_name` not defined in this module, or x a package module that does not
    define it), getattr/setattr/hasattr/delattr(x, "_name"), and `from y import _name`
    (a private module `_y` may be imported by the modules of its own package)."""
    here = file_of(m, root)
    own = own_privates(m.tree)
    aliases = _module_aliases(m, modules)
    found: list[ReachIn] = []

    def check(node: ast.AST, value: ast.expr, name: str) -> None:
        if not _private(name) or name in PUBLIC_UNDERSCORE:
            return
        if isinstance(value, ast.Name) and value.id in ("self", "cls"):
            return
        names_a_module = isinstance(value, ast.Name) and value.id in aliases
        if name in own and not names_a_module:
            return  # this module's own private name (on another instance of its class)
        found.append(ReachIn(here, getattr(node, "lineno", 0), name, ast.unparse(node)))

    for node in ast.walk(m.tree):
        if isinstance(node, ast.Attribute):
            check(node, node.value, node.attr)
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name)
            and node.func.id in ("getattr", "setattr", "hasattr", "delattr")
            and len(node.args) >= 2
            and isinstance(node.args[1], ast.Constant)
            and isinstance(node.args[1].value, str)
        ):
            check(node, node.args[0], node.args[1].value)
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(node, m)
            for a in node.names:
                if not _private(a.name):
                    continue
                full = f"{base}.{a.name}" if base else a.name
                if full in modules and (m.name + ".").startswith(base + "."):
                    continue  # a package-private module, imported within its package
                found.append(ReachIn(here, node.lineno, a.name, f"from {base} import {a.name}"))
        elif isinstance(node, ast.Import):
            for a in node.names:
                private = [p for p in a.name.split(".") if _private(p)]
                parent = a.name.rpartition(".")[0]
                if private and not (m.name + ".").startswith(parent + "."):
                    found.append(ReachIn(here, node.lineno, private[0], f"import {a.name}"))
    return sorted(found)


def all_reach_ins(modules: dict[str, Module], root: Path = REPO) -> list[ReachIn]:
    return [r for m in modules.values() for r in reach_ins(m, modules, root)]


@ON_THE_REPO
def test_no_module_reaches_into_another_modules_private_names() -> None:
    found = all_reach_ins(repo_modules())
    allowed = LIBRARY_INTERNALS
    new = [r for r in found if (r.file, r.name) not in allowed]
    assert not new, (
        "private names used outside their module (make them public API, or move "
        "the code to their owner):\n  " + "\n  ".join(map(str, new))
    )
    stale = allowed - {(r.file, r.name) for r in found}
    assert not stale, f"allow-listed but no longer done, remove from the list: {sorted(stale)}"


def test_only_the_node_core_is_allow_listed() -> None:
    for file, _name in LIBRARY_INTERNALS:
        assert file.startswith("swarm_node/core/"), file


# --------------------------------------------------- (c) state machines posted to by owners

#: the state machines: class -> (the module defining it, the methods that feed it). The
#: owner is the one module that creates it; only the owner feeds it.
STATE_MACHINES = {
    "StateMachine": ("swarm_node.core.state_machine", ("post",)),
    "Sortie": ("swarm_node.core.mission.sortie", ("go",)),
}


def _called_name(f: ast.expr) -> str | None:
    if isinstance(f, ast.Name):
        return f.id
    if isinstance(f, ast.Attribute):
        return f.attr
    return None


def _created(tree: ast.AST, classes: Iterable[str]) -> set[str]:
    """Which of `classes` the module creates (calls, or names as a default_factory), in
    one walk of its tree."""
    wanted = set(classes)
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            names = [_called_name(node.func)]
            names += [_called_name(kw.value) for kw in node.keywords if kw.arg == "default_factory"]
            found.update(n for n in names if n in wanted)
    return found


def owners(modules: dict[str, Module]) -> dict[str, str]:
    """Each state machine's owner: the one module (other than its own) that creates it."""
    out: dict[str, str] = {}
    created = {n: _created(m.tree, STATE_MACHINES) for n, m in modules.items()}
    for cls, (home, methods) in STATE_MACHINES.items():
        defined = [
            n for n in ast.walk(modules[home].tree) if isinstance(n, ast.ClassDef) and n.name == cls
        ]
        assert defined, f"{home} defines no {cls}: update STATE_MACHINES"
        have = {f.name for f in defined[0].body if isinstance(f, ast.FunctionDef)}
        assert set(methods) <= have, f"{cls} has no {set(methods) - have}: update STATE_MACHINES"
        creators = sorted(n for n in modules if n != home and cls in created[n])
        assert len(creators) == 1, f"{cls} must have one owner, created in {creators}"
        out[cls] = creators[0]
    return out


def foreign_posts(
    modules: dict[str, Module], root: Path = REPO, owner: dict[str, str] | None = None
) -> list[ReachIn]:
    """Calls of a state machine's input methods (`x.post(...)`) outside its owner."""
    found = []
    by_method = {meth: cls for cls, (_h, methods) in STATE_MACHINES.items() for meth in methods}
    if owner is None:
        owner = owners(modules)
    for name, m in modules.items():
        for node in ast.walk(m.tree):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and node.func.attr in by_method
            ):
                cls = by_method[node.func.attr]
                if name in (owner[cls], STATE_MACHINES[cls][0]):
                    continue
                label = f"{cls}.{node.func.attr}"
                found.append(ReachIn(file_of(m, root), node.lineno, label, ast.unparse(node.func)))
    return sorted(found)


@ON_THE_REPO
def test_a_state_machine_is_fed_by_its_owner_only() -> None:
    owner = owners(repo_modules())
    found = foreign_posts(repo_modules(), owner=owner)
    assert not found, (
        f"state machines fed outside their owner ({owner}): the owner posts, others "
        "send it outputs:\n  " + "\n  ".join(map(str, found))
    )


# ----------------------------------------------------------- the rules catch what they say


def _tree(root: Path, files: dict[str, str]) -> dict[str, Module]:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text))
    return modules_under(root, ("pkg",))


def test_the_circle_rule_reads_imports_as_documented(tmp_path: Path) -> None:
    modules = _tree(
        tmp_path,
        {
            "pkg/__init__.py": "from .a import A\n",
            "pkg/a.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .b import B\nA = 1\n",
            "pkg/b.py": "def f():\n    from . import c\n",
            "pkg/c.py": "import pkg.b as b\n",
            "pkg/sub/__init__.py": "",
            "pkg/sub/d.py": "from .. import a\nfrom ..e import E\n",
            "pkg/e.py": "from pkg.sub import d\nE = 1\n",
        },
    )
    assert imported_modules(modules["pkg.a"], modules) == {}  # TYPE_CHECKING only
    assert imported_modules(modules["pkg.b"], modules) == {"pkg.c": 2}  # in a function
    assert imported_modules(modules["pkg.sub.d"], modules) == {"pkg.a": 1, "pkg.e": 2}
    circles = import_circles(modules)
    assert circles == [["pkg.b", "pkg.c"], ["pkg.e", "pkg.sub.d"]]
    assert describe_circle(circles[0], modules, tmp_path) == (
        "import circle of 2 files: pkg/b.py, pkg/c.py\n"
        "    pkg/b.py:2 imports pkg.c\n"
        "    pkg/c.py:1 imports pkg.b"
    )


def test_the_private_rule_catches_reach_ins_and_spares_owners(tmp_path: Path) -> None:
    modules = _tree(
        tmp_path,
        {
            "pkg/__init__.py": "",
            "pkg/_util.py": "X = 1\n",
            "pkg/owner.py": """\
                from collections import namedtuple
                from . import _util
                P = namedtuple("P", "a")
                _TABLE = {}
                class Owner:
                    def __init__(self):
                        self._n = 0
                    def __eq__(self, other):
                        return self._n == other._n and P(1)._replace(a=2) and _util.X
                """,
            "pkg/user.py": """\
                from . import owner
                from .owner import _TABLE
                def f(o, x):
                    x._other = 1
                    return o._n, owner._TABLE, getattr(o, "_n"), o.__class__, x._other
                """,
            "pkg/sub/__init__.py": "",
            "pkg/sub/far.py": "from .. import _util\n",
        },
    )
    found = {(r.file, r.name, r.code) for r in all_reach_ins(modules, tmp_path)}
    assert found == {
        ("pkg/user.py", "_TABLE", "from pkg.owner import _TABLE"),
        ("pkg/user.py", "_n", "o._n"),
        ("pkg/user.py", "_TABLE", "owner._TABLE"),
        ("pkg/user.py", "_n", "getattr(o, '_n')"),
        ("pkg/user.py", "_other", "x._other"),
    }


def test_the_post_rule_finds_the_owner_and_the_others(tmp_path: Path, monkeypatch) -> None:
    modules = _tree(
        tmp_path,
        {
            "pkg/__init__.py": "",
            "pkg/fsm.py": "class Machine:\n    def post(self, e):\n        pass\n",
            "pkg/owner.py": "from .fsm import Machine\nclass O:\n    def __init__(self):\n        self.m = Machine()\n        self.m.post(1)\n",
            "pkg/other.py": "def f(o):\n    o.m.post(2)\n",
        },
    )
    monkeypatch.setattr(
        sys.modules[__name__], "STATE_MACHINES", {"Machine": ("pkg.fsm", ("post",))}
    )
    assert owners(modules) == {"Machine": "pkg.owner"}
    assert [(r.file, r.line, r.name) for r in foreign_posts(modules, tmp_path)] == [
        ("pkg/other.py", 2, "Machine.post")
    ]
