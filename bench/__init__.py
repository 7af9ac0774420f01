"""Benchmarks. Each topic is a module `bench/<topic>.py` with `run() -> dict` returning
its figures (units in the key names) and the baseline measured in the same run.
`python -m bench [topic ...]` (or `make bench [BENCH=topic]`) writes
`bench/results/<topic>.json`."""
