"""Shared test fixtures: paths, free loopback ports, Zenoh sessions on 127.0.0.1."""

from __future__ import annotations

import importlib
import itertools
import os
import pkgutil
import socket
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings
from hypothesis.database import DirectoryBasedExampleDatabase

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("BANDADA_SHARED", REPO.parent / "shared"))

# Property tests in `make test` run the same examples on every run of a commit
# (derandomized: seeded by each test's own code; no example database), so a verdict
# never depends on what an earlier run happened to find. No per-example deadline: the
# machines are shared. `make fuzz` (--hypothesis-profile=fuzz) explores instead: random
# examples, FUZZ_FACTOR times as many, and a database that replays what it found; a
# failure it finds comes back to its test as an @example.
DEFAULT_EXAMPLES = 50
FUZZ_FACTOR = 20
settings.register_profile(
    "default",
    derandomize=True,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
    print_blob=True,
    max_examples=DEFAULT_EXAMPLES,
)
settings.register_profile(
    "fuzz",
    parent=settings.get_profile("default"),
    derandomize=False,
    database=DirectoryBasedExampleDatabase(REPO / ".hypothesis" / "examples"),
    max_examples=DEFAULT_EXAMPLES * FUZZ_FACTOR,
)
settings.load_profile("default")


def _cached_command() -> None:
    """typer's CliRunner builds the whole click command tree of an app at every invoke
    (`gcs` has some thirty commands in eleven groups: 50 ms of reading signatures and type
    hints each time, a fifth of the suite's CLI tests' CPU). The apps are built once at
    import and never changed after, so the tests build each app's tree once."""
    import typer.testing

    build = typer.testing._get_command
    built: dict[int, tuple[object, object]] = {}  # id -> (the app, kept alive; its tree)

    def cached(app: object) -> object:
        got = built.get(id(app))
        if got is None or got[0] is not app:
            got = built[id(app)] = (app, build(app))  # type: ignore[arg-type]
        return got[1]

    typer.testing._get_command = cached  # type: ignore[assignment]


_cached_command()


def examples(n: int) -> int:
    """A property test's own example count: `n` under the default profile, scaled as the
    loaded profile scales DEFAULT_EXAMPLES (FUZZ_FACTOR times `n` in `make fuzz`)."""
    return max(1, n * settings.default.max_examples // DEFAULT_EXAMPLES)


# The longest modules of `make test` (real processes, whole flights in fast time), started
# first so that the workers finish together instead of one waiting on a long tail.
LONGEST_FIRST = (
    "swarm_sim/test_demo_story.py",
    "gcs_cli/test_map_browser.py",
    "swarm_node/test_voting_processes.py",
    "swarm_sim/test_demo_radio.py",
    "swarm_node/test_node_processes.py",
    "swarm_node/autopilot/test_behaviour_replay.py",
    "swarm_sim/test_fast_fleet.py",
    "swarm_sim/test_autoland_mumt.py",
    "swarm_sim/test_faults_smoke.py",
    "test_netns.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    def rank(item: pytest.Item) -> int:
        path = item.nodeid.split("::")[0].removeprefix("tests/")
        return LONGEST_FIRST.index(path) if path in LONGEST_FIRST else len(LONGEST_FIRST)

    items.sort(key=rank)  # stable: the others keep their order


PACKAGES = ("swarm_proto", "swarm_node", "radio_gateway", "gcs_cli", "swarm_sim", "bench")


def pytest_collection_finish(session: pytest.Session) -> None:
    """Before any property test runs, import every module of the project. Hypothesis
    draws now and then from the constants of the project's modules imported so far
    (sys.modules), so without this a test's examples depended on which tests ran before
    it in its process (xdist's schedule varies from run to run) and on whether it ran
    alone: the same commit could pass and fail, and a failure did not reproduce."""
    if not any(item.get_closest_marker("hypothesis") for item in session.items):
        return
    for package in PACKAGES:
        module = importlib.import_module(package)
        for info in pkgutil.walk_packages(module.__path__, f"{package}."):
            if not info.name.endswith(".__main__"):
                importlib.import_module(info.name)


def free_tcp_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.skip(f"../shared not found at {SHARED}")
    return SHARED


@pytest.fixture(scope="session")
def fleet_profiles() -> dict:
    """Every seed system's profile by vehicle id: what a node resolves from the swarm
    database, for fleets of simulated vehicles (`FastFleet.build(ids, fleet_profiles)`)."""
    from swarm_node.database import seed_fleet

    return {p.vehicle_id: p for p in seed_fleet()}


@pytest.fixture
def swarm_db(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A seeded swarm database file, named by BANDADA_DB for this test and its children
    (never the user's own database)."""
    from swarm_node.database import SwarmDatabase

    path = tmp_path / "swarm.db"
    SwarmDatabase.open(path).close()
    monkeypatch.setenv("BANDADA_DB", str(path))
    return path


_LOST_LISTS = itertools.count()


@pytest.fixture(autouse=True)
def _gcs_lost_list(
    tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each test's ground station keeps its lost list (gcs_cli/lost_store.py) in a file
    of its own, for it and its children: never the user's, never another test's (made
    only by a test that stores one: no directory per test)."""
    name = f"gcs-lost-{next(_LOST_LISTS)}-{os.getpid()}.db"
    monkeypatch.setenv("BANDADA_GCS_STATE", str(tmp_path_factory.getbasetemp() / name))


@pytest.fixture
def zenoh_router() -> Iterator[str]:
    """A router-mode Zenoh session on a free 127.0.0.1 port; yields its endpoint."""
    from swarm_proto.session import ZenohSettings, open_session

    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    session = open_session(ZenohSettings(mode="router", listen=(endpoint,)))
    try:
        yield endpoint
    finally:
        session.close()
