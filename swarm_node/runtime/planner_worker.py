"""What a node's planner worker process runs first (`PlanWorker`, runtime/node.py): a
watch on its parent. A node killed with SIGKILL (a crash, the demo's failing vehicle)
cannot shut its pool down, and the worker, blocked on its call queue, would outlive it
for good; it exits once its parent is gone (it is then re-parented)."""

from __future__ import annotations

import os
import threading
import time

#: how often the worker looks for its parent (wall seconds)
PARENT_POLL_S = 1.0


def watch_parent(parent_pid: int) -> None:
    """ProcessPoolExecutor initializer: a daemon thread that ends the process when its
    parent is no longer `parent_pid`."""

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(PARENT_POLL_S)
        os._exit(0)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()
