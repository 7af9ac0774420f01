"""A node's planner worker (runtime/node.py `PlanWorker`, runtime/planner_worker.py): it
is started (and imports the planners) once asked, and it does not outlive a node killed
with SIGKILL (before, every SIGKILLed node of the demo and the tests left one running)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

HOST = """
import queue, sys, time
from swarm_node.runtime.node import PlanWorker
done = queue.SimpleQueue()
w = PlanWorker(done.put)
w.start()
pool = w._pool
pool.submit(int, 0).result(timeout=60)  # the worker is up, the planners imported
print(*[p.pid for p in pool._processes.values()], flush=True)
time.sleep(600)
"""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie of ours is gone too
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split()[2] != "Z"
    except FileNotFoundError:
        return False


def test_the_planner_worker_exits_when_its_node_is_killed() -> None:
    host = subprocess.Popen([sys.executable, "-c", HOST], stdout=subprocess.PIPE, text=True)
    try:
        assert host.stdout is not None
        (worker,) = (int(x) for x in host.stdout.readline().split())
        assert _alive(worker)
        host.send_signal(signal.SIGKILL)
        host.wait(10)
        end = time.monotonic() + 15.0
        while _alive(worker) and time.monotonic() < end:
            time.sleep(0.2)
        assert not _alive(worker)
    finally:
        if host.poll() is None:
            host.kill()
