# bandada: the two commands a new user runs are `make demo` and `make test`.
# Every target creates .venv (python3 -m venv) and installs the project into it first.

PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.bandada-installed
BENCH  ?=
PYTEST_ARGS ?=

# Python caches the bytecode of what it imports; an environment that turns that off
# (PYTHONDONTWRITEBYTECODE, set on some CI images) makes every process of the suite, each
# node and gcs it starts among them, compile numpy, pymavlink's dialect and the project
# from source again: 0.9 s of CPU per process, several minutes over the suite
unexport PYTHONDONTWRITEBYTECODE

.PHONY: all demo test checks lint typecheck unit fuzz test-stress bench soak scale docs clean install sitl-check sitl-fleet faults browser

all: test

# uv (from PyPI, into the venv) installs the project and its test tools in a fifth of
# pip's time (6 s against 37 s on 2 cores), which is most of a fresh clone's setup
$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check 'uv>=0.5'
	$(BIN)/python -m uv pip install --quiet --python $(BIN)/python -e '.[test]'
	@touch $(STAMP)

install: $(STAMP)

## browser: headless Chromium and its driver, for `gcs map`'s browser tests
## (tests/gcs_cli/test_map_browser.py) and `make bench BENCH=map`. Installed with
## apt-get where they are missing and this is root on Debian/Ubuntu (CI); otherwise
## said here, and those tests fail under CI (CI set) or skip, saying why, elsewhere.
browser:
	@if command -v chromium >/dev/null 2>&1 && command -v chromedriver >/dev/null 2>&1; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "browser: installing chromium and chromium-driver (apt-get)"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
	    --no-install-recommends chromium chromium-driver >/dev/null; \
	else \
	  echo "browser: chromium and chromedriver are missing and cannot be installed here" \
	    "(not root, or no apt-get): the map's browser tests fail under CI, skip otherwise"; \
	fi

## demo: a simulated swarm flying a mission, on this machine, in fast time
demo: $(STAMP)
	$(BIN)/swarm-sim demo

## test: lint, type check and the test suite (CI runs exactly this). The checks run beside
## the suite (mypy takes a core for half a minute while the suite's first tests wait on
## their processes): their few lines may fall among the suite's progress dots
test: $(STAMP) browser
	@$(MAKE) --no-print-directory -j2 checks unit

checks: $(STAMP)
	@$(MAKE) --no-print-directory lint typecheck
	@echo "checks passed"

SOURCES := swarm_proto swarm_node radio_gateway gcs_cli swarm_sim bench tests

lint: $(STAMP)
	$(BIN)/ruff check $(SOURCES)
	$(BIN)/ruff format --check $(SOURCES)

typecheck: $(STAMP)
	$(BIN)/mypy

## the suite mostly waits (processes, Zenoh, simulated radios): three workers keep 2 cores
## busy while one waits (4:30 against 5:36 with two); TEST_WORKERS=0 runs it in one process
TEST_WORKERS ?= 3
## tests marked `timing` (real-time TDM on pseudo-terminals) run alone, after the others.
## The test modules are collected once first: pytest caches each module with its asserts
## rewritten, which a fresh clone's three workers would otherwise each do (10 s of CPU each)
## the second part collects only the modules that mark tests `timing` (collecting the
## whole suite again costs 4-5 s of CPU for five tests); with PYTEST_ARGS, what they say
TIMING_FILES = $(shell grep -rlE 'mark\.timing' tests --include='*.py' | sort)
unit: $(STAMP) browser
	$(BIN)/python -m pytest -qq --collect-only -p no:cacheprovider $(PYTEST_ARGS) >/dev/null
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadgroup -m "not soak and not scale and not timing" $(PYTEST_ARGS)
	$(BIN)/python -m pytest -q -m "timing and not soak and not scale" $(or $(PYTEST_ARGS),$(TIMING_FILES))

## fuzz: the property tests exploring (hypothesis profile `fuzz`, tests/conftest.py): random
## examples, 20 times as many, an example database in .hypothesis/ that replays what it
## found. A failure it finds goes back to its test as an @example (make test never explores)
fuzz: $(STAMP)
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) -m "hypothesis and not soak and not scale" --hypothesis-profile=fuzz $(PYTEST_ARGS)

## test-stress: the stress gate, run before resolving an issue: `make test` five times from
## a fresh clone of HEAD with one core kept busy; writes bench/results/test_stress.json
test-stress:
	$(PYTHON) -m bench test_stress

## bench: every benchmark, or one with BENCH=<topic>; writes bench/results/<topic>.json
bench: $(STAMP) browser
	$(BIN)/python -m bench $(BENCH)

## faults: the fault campaign (docs/reliability.md): faults x missions in
## FastFleet and over real processes, writes bench/results/faults.json (about 50 min).
## BANDADA_FAULTS=fast runs only the FastFleet part; the smoke subset is in `make test`.
faults: $(STAMP)
	$(BIN)/python -m bench faults

## soak / scale: the long suites, kept out of `make test`
soak: $(STAMP)
	$(BIN)/python -m pytest -q -m soak $(PYTEST_ARGS)

scale: $(STAMP)
	$(BIN)/python -m pytest -q -m scale $(PYTEST_ARGS)

## sitl-check: the nodes against real ArduPilot SITL (docs/sitl.md); not part of `make test`.
## Needs ARDUPILOT_SITL_BIN (a directory with arducopter and arduplane); SITL_ARGS=--sim
## runs it against swarm-sim vehicles instead. Writes bench/results/sitl.json.
SITL_ARGS ?=
sitl-check: $(STAMP)
	$(BIN)/python -m swarm_sim.sitl_check $(SITL_ARGS)

## sitl-fleet: the paper's experiment flown by several SITL vehicles at once (docs/sitl.md);
## not part of `make test`. Same ARDUPILOT_SITL_BIN; SITL_ARGS=--sim flies swarm-sim
## vehicles instead. Writes bench/results/sitl_fleet.json.
sitl-fleet: $(STAMP)
	$(BIN)/python -m swarm_sim.sitl_fleet $(SITL_ARGS)

## docs: regenerate the generated documents (keyspace, state diagrams)
docs: $(STAMP)
	$(BIN)/python -m swarm_proto.keyspace_doc > docs/keyspace.md
	$(BIN)/python -m swarm_node.docs_gen docs/state-machine.md

clean:
	rm -rf $(VENV) .mypy_cache .ruff_cache .pytest_cache .hypothesis *.egg-info
