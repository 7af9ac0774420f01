"""A restarted router does not split the swarm for good, over real node
processes: two nodes, Zenoh clients of a router on 127.0.0.1, see each other; the
router is closed and opened again 3 s later on the same endpoint; both nodes reconnect
by themselves and see each other again.

This is the reduced form, in `make test`, of the fault campaign's row "restart the
router (down 3 s)" (`swarm_sim/fault_processes.py`, `make faults`), which flies three
quadcopters through it and measures one fleet again from the nodes' reconnection; a
fleet's merge after a partition is proven in fast time (tests/swarm_sim/test_partition_heals.py)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from swarm_proto.session import ZenohSettings, open_session
from tests.conftest import free_tcp_port
from tests.swarm_node.processes import peers_of, plain_session, start_node, stop, wait_until

pytestmark = pytest.mark.network


def test_nodes_see_each_other_again_after_the_router_restarts(
    tmp_path: Path, swarm_db: object
) -> None:
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    swarm = f"rr{time.monotonic_ns() % 100000}"
    router = open_session(ZenohSettings(mode="router", listen=(endpoint,)))
    logs = {i: tmp_path / f"node-{i}.log" for i in (7, 8)}
    # clients of the router, as on a field LAN with a lab router (and the demo)
    procs = {i: start_node(i, endpoint, swarm, "--mode", "client", log=logs[i]) for i in logs}
    watcher = plain_session(endpoint)

    def both() -> bool:
        return peers_of(watcher, swarm, 7) == [8] and peers_of(watcher, swarm, 8) == [7]

    def said(i: int, text: str) -> int:
        return logs[i].read_text(errors="replace").count(text)

    try:
        assert wait_until(both, 60) is not None
        router.close()
        # each node loses the other (nothing relays between clients but the router)
        lost = lambda: said(7, "peer 8 lost") and said(8, "peer 7 lost")  # noqa: E731
        assert wait_until(lost, 15) is not None
        time.sleep(3.0)
        joined = (said(7, "peer 8 joined"), said(8, "peer 7 joined"))
        router = open_session(ZenohSettings(mode="router", listen=(endpoint,)))
        # every client (the nodes, the watcher) reconnects by itself
        back = lambda: said(7, "peer 8 joined") > joined[0] and said(8, "peer 7 joined") > joined[1]  # noqa: E731
        assert wait_until(back, 60) is not None, logs[7].read_text()[-2000:]
        assert wait_until(both, 30) is not None
    finally:
        watcher.close()
        codes = {i: stop(p) for i, p in procs.items()}
        router.close()
    assert all(c != -999 for c in codes.values()), f"a node hung at exit: {codes}"
