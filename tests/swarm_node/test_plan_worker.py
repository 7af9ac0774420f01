"""The node's planner worker process ends with the node, even a node killed by SIGKILL
(no shutdown code runs): before, the demo's killed node left its worker running."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

NODE = """
import os, sys
from swarm_node.runtime.node import PlanWorker
if __name__ == "__main__":
    w = PlanWorker(lambda _: None, "process")
    w.start()
    print(w._pool.submit(os.getpid).result(), flush=True)  # the worker runs
    sys.stdin.read()  # until killed
"""


def _alive(pid: int) -> bool:
    """Running, not a zombie (an orphan's zombie may wait for a non-reaping init)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state not in ("Z", "X")


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
def test_worker_exits_when_its_node_is_sigkilled() -> None:
    node = subprocess.Popen(
        [sys.executable, "-c", NODE], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        assert node.stdout is not None
        worker = int(node.stdout.readline())
        assert worker != node.pid and _alive(worker)
        node.send_signal(signal.SIGKILL)
        node.wait()
        deadline = time.monotonic() + 30.0  # a bound, not a timing claim: polls every 0.5 s
        while _alive(worker) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _alive(worker), "the planner worker outlived its killed node"
    finally:
        node.kill()


def test_worker_lives_while_its_node_does() -> None:
    """The watch does not end a worker whose parent is alive (a second job still runs)."""
    from swarm_node.runtime.node import PlanWorker

    w = PlanWorker(lambda _: None, "process")
    w.start()
    try:
        assert w._pool is not None
        first = w._pool.submit(os.getpid).result(timeout=60)
        time.sleep(1.2)  # a few of the watch's polls
        assert w._pool.submit(os.getpid).result(timeout=60) == first
    finally:
        w.close()
