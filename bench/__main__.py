"""Run benchmarks: `python -m bench` (all) or `python -m bench proto radio`."""

from __future__ import annotations

import importlib
import json
import os
import platform
import sys
import time
import traceback
from datetime import UTC, datetime
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
NOT_TOPICS = {"__init__", "__main__", "common"}


def topics() -> list[str]:
    return sorted(
        p.stem for p in HERE.glob("*.py") if p.stem not in NOT_TOPICS and not p.stem.startswith("_")
    )


def run_topic(name: str) -> dict:
    module = importlib.import_module(f"bench.{name}")
    t0 = time.perf_counter()
    figures = module.run()
    meta = {
        "command": f"make bench BENCH={name}",
        "date_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpus": os.cpu_count(),
        "wall_s": round(time.perf_counter() - t0, 2),
    }
    result = {**figures, "_meta": meta}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{name}.json").write_text(json.dumps(result, indent=2, sort_keys=False) + "\n")
    return result


def main(argv: list[str]) -> int:
    wanted = argv or topics()
    unknown = [t for t in wanted if t not in topics()]
    if unknown:
        print(
            f"unknown benchmark(s): {', '.join(unknown)}; have: {', '.join(topics())}",
            file=sys.stderr,
        )
        return 2
    failed = []
    for name in wanted:
        print(f"== bench {name}", flush=True)
        try:
            result = run_topic(name)
        except Exception:
            # one broken benchmark must not hide the others' figures
            traceback.print_exc()
            failed.append(name)
            continue
        print(json.dumps({k: v for k, v in result.items() if k != "_meta"}, indent=2))
    if failed:
        print(f"benchmark(s) failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
