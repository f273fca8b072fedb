# wristmark: `make run` (main job) and `make test` (whole suite) set up .venv when needed.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp

.PHONY: setup run test lint typecheck pytest bench results browser rtsp-server clean examples

setup: $(STAMP)

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

lint: setup
	$(VENV)/bin/ruff check wristmark wristmark_testing tests bench examples

typecheck: setup
	$(VENV)/bin/mypy wristmark

pytest: setup browser rtsp-server
	$(PY) -m pytest

test: lint typecheck pytest

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
