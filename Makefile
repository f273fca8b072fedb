# wristmark: `make run` (main job), `make check` (fast tests, while working) and `make test`
# (whole suite, as CI runs it) set up .venv when needed. Tests: docs/testing.md.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp

.PHONY: setup compiled help run check test lint typecheck pytest pytest-fast bench results browser rtsp-server pbr clean examples

setup: $(STAMP) compiled

# The stereo pose solve compiled to C (cvs.tracking.compiled_function: the same results, faster, and
# the arms' solves side by side): ~40 s once per source change, then found in ~/.cache/wristmark.
# Without a C compiler the solvers evaluate with CasADi (slower).
compiled: $(STAMP)
	@$(PY) -m wristmark.cvs.tracking.compiled_pose || echo "the pose solve is not compiled: CasADi evaluates it"

help:
	@echo "make run          the cube experiment, open vs closed loop, on the simulated rig (runs/latest)"
	@echo "make check        ruff, mypy and the fast tests: no slow, wallclock, browser, network or pbr ones"
	@echo "make test         ruff, mypy and every test (CI): the wallclock ones alone, after the rest"
	@echo "make pytest-fast  the fast tests only;  make pytest  every test (PYTEST_WORKERS=$(PYTEST_WORKERS))"
	@echo "make examples     examples/*.py in their fast mode;  make bench  bench/*.py into runs/bench"
	@echo "Tests, markers and timings: docs/testing.md"

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,ros2]'
	touch $(STAMP)

# Main job: the paper's cube experiment, open vs closed loop, on the simulated rig. Each run
# writes a new folder runs/cube-YYYYmmdd-HHMMSS (result.json, log.csv, plots); runs/latest links it.
run: setup
	$(VENV)/bin/wristmark experiment cube --view

browser:
	bash scripts/ensure-chromium.sh

# GStreamer's RTSP server for Debian's Python: the RTSP tests serve frames with it.
rtsp-server:
	bash scripts/ensure-rtsp-server.sh

# The path tracer (`wristmark render --engine pbr`: the optional extra pbr, Mitsuba 3, and Debian's
# libllvm19) in .venv: the `pbr` test renders a pair with it end to end.
pbr: $(STAMP)
	bash scripts/ensure-pbr.sh

lint: $(STAMP)
	$(VENV)/bin/ruff check wristmark wristmark_testing tests bench examples

typecheck: $(STAMP)
	$(VENV)/bin/mypy wristmark

# Test markers (pyproject.toml, docs/testing.md): slow, wallclock (times real events), browser
# (headless Chromium), network (loopback servers), pbr (the path tracer). `make check` runs the
# tests with none of them (~1600 of ~1850), in one process: lint, types and tests in ~5 min here,
# without Chromium, the RTSP server or the path tracer (it does not depend on `browser`,
# `rtsp-server` and `pbr`).
FAST_TESTS := not slow and not wallclock and not browser and not network and not pbr
# Processes for the tests that do not time real events (pytest-xdist). A module's tests stay in
# one process (--dist loadfile), so its module-scoped fixtures are built once.
PYTEST_WORKERS ?= 2

check: lint typecheck pytest-fast

pytest-fast: setup
	$(PY) -m pytest -m "$(FAST_TESTS)"

# The whole suite in two pytest runs: every test but the wallclock ones on $(PYTEST_WORKERS)
# processes, then the wallclock ones alone, so that their timing asserts do not compete with the
# rest of the suite for the cores.
# Both always run (unless the first was interrupted); the exit status is non-zero if either
# failed, and a failed first run's summary line is repeated at the end.
pytest: setup browser rtsp-server pbr
	@set -o pipefail; log=$$(mktemp); \
	echo "== pytest on $(PYTEST_WORKERS) processes: all but the wallclock tests"; \
	$(PY) -m pytest -n $(PYTEST_WORKERS) --dist loadfile --durations=20 -m "not wallclock" 2>&1 | tee $$log; first=$$?; \
	if [ $$first -eq 2 ] || [ $$first -eq 3 ] || [ $$first -eq 4 ]; then rm -f $$log; exit $$first; fi; \
	echo "== pytest alone: the wallclock tests"; \
	$(PY) -m pytest -p no:xdist --durations=10 -m wallclock; second=$$?; \
	if [ $$first -ne 0 ]; then echo "== the first run (all but the wallclock tests) FAILED: $$(tail -n 1 $$log)"; fi; \
	rm -f $$log; \
	[ $$first -eq 0 ] && [ $$second -eq 0 ]

# The whole suite, as CI runs it (.ci/run): ruff and mypy (one core) while, beside them, the
# stereo pose solve is compiled (`compiled`), numba compiles the tracker's and the renderer's
# kernels into its disk cache (scripts/compile_kernels.py: once, instead of in each test process
# that needs them first) and Chromium and the RTSP server are installed when missing; then
# `pytest` above (whose own `setup browser rtsp-server` then find everything in place).
test: $(STAMP)
	@logs=$$(mktemp -d); \
	$(MAKE) --no-print-directory compiled > $$logs/solve 2>&1 & solve=$$!; \
	$(PY) scripts/compile_kernels.py > $$logs/kernels 2>&1 & kernels=$$!; \
	$(MAKE) --no-print-directory browser rtsp-server pbr > $$logs/installs 2>&1 & installs=$$!; \
	$(MAKE) --no-print-directory lint typecheck; checks=$$?; \
	wait $$solve; wait $$kernels; compiled=$$?; wait $$installs; installed=$$?; \
	cat $$logs/solve $$logs/kernels $$logs/installs; rm -rf $$logs; \
	if [ $$compiled -ne 0 ]; then echo "== scripts/compile_kernels.py FAILED"; fi; \
	if [ $$installed -ne 0 ]; then echo "== make browser rtsp-server pbr FAILED"; fi; \
	[ $$checks -eq 0 ] && [ $$compiled -eq 0 ] && [ $$installed -eq 0 ] && $(MAKE) --no-print-directory pytest

# The examples of the public API (examples/*.py), each in its fast mode as CI runs them.
examples: setup
	for e in examples/*.py; do echo "== $$e"; $(PY) $$e --fast || exit 1; done

bench: setup
	mkdir -p runs/bench
	for b in bench/*.py; do [ $$b = bench/results.py ] && continue; echo "== $$b"; $(PY) $$b | tee runs/bench/$$(basename $$b .py).json; done

# docs/results.md's generated tables and the README's results table, from the canonical commands
# (bench/results.py --list); ONLY=name runs one of them.
results: setup
	$(PY) bench/results.py $(if $(ONLY),--only $(ONLY))

clean:
	rm -rf $(VENV) runs .pytest_cache .mypy_cache .ruff_cache *.egg-info
