"""A child process that must not outlive its parent: the node's planner worker.

A node killed with SIGKILL (or by the kernel's OOM killer) runs no shutdown code, so its
`ProcessPoolExecutor` worker would be left computing plans for no one, holding a core
of the companion computer. `exit_with_parent` is the worker's initializer: a daemon
thread polls the parent's pid and ends the worker when it changes (the orphan is
re-parented to init or a subreaper). Polling works on every POSIX system, whichever
thread started the worker (Linux's PR_SET_PDEATHSIG fires when that *thread* ends).
"""

from __future__ import annotations

import os
import threading

POLL_S = 0.5  # how often the worker checks its parent (wall seconds)


def exit_with_parent(parent_pid: int, poll_s: float = POLL_S) -> None:
    """Start the watch (call in the child, with the parent's pid taken in the parent)."""

    def watch() -> None:
        stop = threading.Event()
        while not stop.wait(poll_s):
            if os.getppid() != parent_pid:
                os._exit(0)  # no cleanup to run: the worker holds no state of its own

    if os.getppid() != parent_pid:  # the parent died before we started
        os._exit(0)
    threading.Thread(target=watch, name="parent-watch", daemon=True).start()
