# train_dynamics: make run | make test | make test-fast | make lint | make bench | make soak | make venv | make bytecode | make clean
#
# Every target creates the virtual environment it needs (.venv, pinned by requirements.txt)
# on first use; later runs skip the install (stamp file) unless requirements.txt, setup.py or
# package.xml changed. Only python3 with venv and pip, and a reachable package index, are needed.

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
.DEFAULT_GOAL := help

PYTHON ?= python3
VENV ?= .venv
VPY := $(VENV)/bin/python
STAMP := $(VENV)/.train_dynamics-installed
PYTEST_ARGS ?=
# parallel test workers (pytest-xdist) for test and test-fast: one per CPU, at most 4 (DDS and
# the node tests gain nothing beyond; each worker takes its own ROS domain, test/conftest.py);
# PYTEST_WORKERS=0 runs the suite in this one process
PYTEST_WORKERS ?= $(shell n=$$(nproc 2>/dev/null || echo 1); echo $$(( n < 4 ? n : 4 )))
# --dist loadgroup: the tests of one xdist group (test/conftest.py: the machine-hungry ones, a
# module's shared fixture) run on one worker; the others go to whichever worker is free
PYTEST_PARALLEL := $(if $(filter-out 0,$(PYTEST_WORKERS)),-n $(PYTEST_WORKERS) --dist loadgroup)
# options of the demo, e.g. make run RUN_ARGS='--rtf 4' (python -m train_dynamics.cli.demo -h)
RUN_ARGS ?=

# rclpy/DDS: never discover beyond this machine, and use a private domain. Tests choose their
# own domain per session (test/conftest.py); for run/bench/soak take the caller's
# ROS_DOMAIN_ID or one derived from make's pid in 70..100 (helpers use 61..69 by hand).
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
ifndef ROS_DOMAIN_ID
ROS_DOMAIN_ID := $(shell echo $$(( 70 + $$PPID % 31 )))
endif
export ROS_DOMAIN_ID
# Keep matplotlib off any display.
export MPLBACKEND ?= Agg

.PHONY: help venv bytecode test test-fast test-floor lint run bench soak clean distclean

help:
	@echo "make run    - the paper's emergency braking through sim_node + brake_valve (DDS on loopback), recorded"
	@echo "make test   - the test suite (pytest, on parallel workers: PYTEST_WORKERS), the ament linters included"
	@echo "make test-fast - the tests not marked slow (pytest -m 'not slow'; the table in test/conftest.py)"
	@echo "make test-floor - the tests at the dependency floor (requirements-floor.txt) in .venv-floor, Python 3.12 if present"
	@echo "make lint   - only the ament linter tests (test/lint/: test_flake8.py, test_pep257.py)"
	@echo "make bench  - benchmarks (bench/run_all.py)"
	@echo "make soak   - long run (bench/soak.py)"
	@echo "make venv   - only create/update .venv"
	@echo "make bytecode - byte-compile the package's modules (test, run, bench and soak do it)"
	@echo "make clean  - remove build products and caches; make distclean also removes .venv"

venv: $(STAMP)

# the typed-message package (msgs/train_dynamics_msgs), built into the venv by tools/build_msgs.sh
MSGS_SOURCES := $(wildcard msgs/train_dynamics_msgs/msg/*.msg) msgs/train_dynamics_msgs/CMakeLists.txt \
  msgs/train_dynamics_msgs/package.xml tools/build_msgs.sh

$(STAMP): requirements.txt requirements-lock.txt setup.py setup.cfg package.xml Makefile $(MSGS_SOURCES)
	@if [ ! -x "$(VPY)" ]; then \
	  echo "creating $(VENV) with $$($(PYTHON) --version)"; \
	  $(PYTHON) -m venv "$(VENV)"; \
	fi
	$(VPY) -m pip install --no-compile -r requirements.txt
	$(VPY) -m pip install --no-deps --no-build-isolation --use-pep517 -e .
	# byte-compile every installed module, on both cores (~15 s): where PYTHONDONTWRITEBYTECODE
	# is set Python never writes a .pyc itself (why and what it costs: docs/development.md,
	# "Python bytecode")
	$(VPY) -m compileall -q -j 0 "$$($(VPY) -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')" >/dev/null \
	  || echo "note: some installed modules did not byte-compile (their imports stay slower)"
	# two things at once (docs/install.md, "First build and first run"): the numba kernels that
	# `make run` needs compile into the user cache (~/.cache/train_dynamics/numba-<code
	# version>, keyed by the sources' content; ~30 s on two cores, once per code version) while
	# the typed messages build: colcon + rosidl into the venv's own prefix (~40 s, mostly
	# waiting on cmake; needs cmake and a C/C++ compiler), where the venv's Python finds them
	# without any setup
	$(VPY) -m train_dynamics.cli.prebuild --variants paper & prebuild=$$!; \
	  trap 'kill $$prebuild 2>/dev/null || true' EXIT; \
	  tools/build_msgs.sh "$(VENV)"; \
	  wait $$prebuild
	$(VPY) -m compileall -q "$$($(VPY) -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')/train_dynamics_msgs" >/dev/null
	@touch "$@"

# every kernel variant compiled (or loaded) before the tests, in this process: no test
# compiles while another is timed, and no background compile competes with the suite; then
# the suite on PYTEST_WORKERS parallel workers
test: venv bytecode
	$(VPY) -m train_dynamics.cli.prebuild
	$(VPY) -m pytest test/ $(PYTEST_PARALLEL) $(PYTEST_ARGS)

# the quick loop while editing: every test but those marked `slow` (test/conftest.py's table
# of the slowest, measured); the tests needing DDS stay in (add -m 'not slow and not ros' by
# hand to leave them out too)
test-fast: venv bytecode
	$(VPY) -m train_dynamics.cli.prebuild
	$(VPY) -m pytest test/ -m 'not slow' $(PYTEST_PARALLEL) $(PYTEST_ARGS)

# the dependency floor (requirements-floor.txt: what rosdep installs on Ubuntu 24.04) in its own
# environment .venv-floor, on python3.12 when there is one (FLOOR_PYTHON=... to choose), the
# package from this checkout through PYTHONPATH; FLOOR_TESTS picks the tests (docs/install.md)
test-floor:
	tools/floor_env.sh all $(PYTEST_ARGS)

# The linter tests carry the pytest mark `linter` and the list of paths they check.
lint: venv
	$(VPY) -m pytest test/ -m linter -q -p no:logging $(PYTEST_ARGS)

# the other variants (error-controlled, pneumatic) compile in a detached background process
# while the demo runs (its log: prebuild.log in the kernel cache folder)
run: venv bytecode
	$(VPY) -m train_dynamics.cli.prebuild --variants paper --rest-in-background
	$(VPY) -m train_dynamics.cli.demo $(RUN_ARGS)

# the package's own modules byte-compiled (what changed since the last time; see the venv step)
bytecode: venv
	$(VPY) -m compileall -q -j 0 train_dynamics >/dev/null

bench: venv bytecode
	$(VPY) bench/run_all.py

soak: venv bytecode
	$(VPY) bench/soak.py

clean:
	rm -rf build install log .pytest_cache *.egg-info
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf "$(VENV)"
