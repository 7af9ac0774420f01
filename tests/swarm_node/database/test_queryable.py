"""The database served over a real Zenoh session on 127.0.0.1 and queried by another:
info, profiles, tables with filters, the export; errors come back as error replies;
wildcards reach every node; plain zenoh-python + msgspec can read the replies."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from typing import TypeVar

import msgspec
import pytest
import zenoh

from swarm_node.core.profile import VehicleProfile
from swarm_node.database import ALBATROSS, SwarmDatabase
from swarm_node.database.queryable import (
    DatabaseQueryable,
    DbInfo,
    DbQueryError,
    fetch,
    fetch_export,
    fetch_info,
    fetch_profile,
    fetch_profiles,
    fetch_table,
    query,
    selector,
)
from swarm_node.database.schema import LATEST_VERSION
from swarm_proto.session import ZenohSettings, open_session
from swarm_proto.topics import DATABASE

pytestmark = pytest.mark.network

T = TypeVar("T")
SWARM = "dbtest"


def eventually(fn: Callable[[], T], timeout_s: float = 20.0) -> T:
    """Retry until the queryable's declaration has reached the querier."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            return fn()
        except DbQueryError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)


@pytest.fixture
def sessions(zenoh_router: str) -> Iterator[tuple[zenoh.Session, zenoh.Session]]:
    server = open_session(ZenohSettings(connect=(zenoh_router,)))
    client = open_session(ZenohSettings(connect=(zenoh_router,)))
    try:
        yield server, client
    finally:
        client.close()
        server.close()


@pytest.fixture
def served(
    sessions: tuple[zenoh.Session, zenoh.Session],
) -> Iterator[tuple[DatabaseQueryable, zenoh.Session]]:
    server, client = sessions
    db = SwarmDatabase.memory()
    q = DatabaseQueryable(server, db, node_id=3, swarm=SWARM)
    try:
        eventually(lambda: fetch_info(client, SWARM, 3, timeout_s=2.0))
        yield q, client
    finally:
        q.close()
        db.close()


def test_info_profile_profiles_and_export(served: tuple[DatabaseQueryable, zenoh.Session]) -> None:
    q, client = served
    info = fetch_info(client, SWARM, 3)
    assert info == DbInfo(
        3, LATEST_VERSION, {k.replace(".", "/"): v for k, v in q.db.counts().items()}
    )
    me = fetch_profile(client, SWARM, 3)
    assert me == q.db.vehicle_profile(3)
    assert me.model == ALBATROSS and me.camera is not None
    profiles = msgspec.convert(fetch(client, SWARM, 3, "profiles"), list[VehicleProfile])
    assert profiles == q.db.profiles()
    assert fetch_export(client, SWARM, 3) == q.db.export()
    assert q.served["profile"] >= 1


def test_tables_with_filters(served: tuple[DatabaseQueryable, zenoh.Session]) -> None:
    _, client = served
    models = fetch_table(client, SWARM, 3, "systems", "models")
    assert models[0]["name"] == ALBATROSS
    one = fetch_table(client, SWARM, 3, "systems", "systems", user_id="QUAD-02")
    assert one == [{"id": 8, "user_id": "QUAD-02", "layout": "Quadcopter + EO 1080p", "payload": 8}]
    assert fetch_table(client, SWARM, 3, "systems", "systems", id=900)[0]["user_id"] == "GCS-01"
    with pytest.raises(DbQueryError, match="unknown field 'wheels'"):
        fetch_table(client, SWARM, 3, "systems", "systems", wheels=4)
    assert fetch_table(client, SWARM, 3, "common", "corrections") == []  # empty in the seed
    with pytest.raises(DbQueryError, match="unknown field 'wheels'"):
        fetch_table(client, SWARM, 3, "common", "corrections", wheels=4)


def test_errors_come_back_as_error_replies(served: tuple[DatabaseQueryable, zenoh.Session]) -> None:
    q, client = served
    with pytest.raises(DbQueryError, match="no such resource"):
        fetch(client, SWARM, 3, "nonsense")
    with pytest.raises(DbQueryError, match="no such resource"):
        fetch(client, SWARM, 3, "table/systems/cars")
    with pytest.raises(DbQueryError, match=r"no reply within 0\.5 s"):
        fetch(client, SWARM, 4, "profile", timeout_s=0.5)  # nobody serves node 4
    assert q.errors["unknown"] >= 2


def test_a_node_missing_from_its_own_database_says_so(
    sessions: tuple[zenoh.Session, zenoh.Session],
) -> None:
    server, client = sessions
    with SwarmDatabase.memory() as db, DatabaseQueryable(server, db, node_id=77, swarm=SWARM):
        eventually(lambda: fetch_info(client, SWARM, 77, timeout_s=2.0))
        with pytest.raises(DbQueryError, match="no system with id 77"):
            fetch_profile(client, SWARM, 77)


def test_wildcards_reach_every_node(
    sessions: tuple[zenoh.Session, zenoh.Session], zenoh_router: str
) -> None:
    server, client = sessions
    other = open_session(ZenohSettings(connect=(zenoh_router,)))
    dbs = [SwarmDatabase.memory(), SwarmDatabase.memory()]
    qs = [
        DatabaseQueryable(server, dbs[0], node_id=1, swarm=SWARM),
        DatabaseQueryable(other, dbs[1], node_id=12, swarm=SWARM),
        DatabaseQueryable(other, dbs[1], node_id=55, swarm=SWARM),  # no profile: skipped
    ]
    try:
        for n in (1, 12, 55):
            eventually(lambda n=n: fetch_info(client, SWARM, n, timeout_s=2.0))  # type: ignore[misc]
        profiles = fetch_profiles(client, SWARM, timeout_s=3.0)
        assert sorted(profiles) == [1, 12]
        assert profiles[12].model == "Generic Boat"
        nodes = query(client, selector(SWARM, "*"), timeout_s=3.0)
        assert sorted(DATABASE.parse(SWARM, r.key)["node_id"] for r in nodes) == ["1", "12", "55"]  # type: ignore[index]
    finally:
        for q in qs:
            q.close()
        for db in dbs:
            db.close()
        other.close()


def test_plain_zenoh_and_msgspec_read_a_profile(
    served: tuple[DatabaseQueryable, zenoh.Session],
) -> None:
    q, client = served
    replies = list(client.get(f"bandada/{SWARM}/db/3/profile", timeout=5.0))
    assert len(replies) == 1 and replies[0].ok is not None
    sample = replies[0].ok
    assert str(sample.encoding) == "application/msgpack"
    as_dict = msgspec.msgpack.decode(sample.payload.to_bytes())
    assert as_dict["cruise_speed_m_s"] == 26.0 and as_dict["camera"]["hfov_deg"] == 62.0
    assert msgspec.convert(as_dict, VehicleProfile) == q.db.vehicle_profile(3)


def test_the_queryable_sees_changes_and_survives_garbage_queries(
    served: tuple[DatabaseQueryable, zenoh.Session],
) -> None:
    q, client = served
    q.db.add("systems.systems", {"user_id": "ALB-07", "layout": "Albatross 250 VTOL + EO 1.5 Mpx"})
    assert fetch_table(client, SWARM, 3, "systems", "systems", user_id="ALB-07")[0]["id"] == 14
    for sel in (f"bandada/{SWARM}/db/3/table?x=1", f"bandada/{SWARM}/db/3/profile?;;==;"):
        list(client.get(sel, timeout=2.0))
    assert fetch_profile(client, SWARM, 3).vehicle_id == 3
