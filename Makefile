# The README's two commands: `make demo` (replay the bundled bag through the shadow) and
# `make test` (lint + the whole test suite). Both create and use the project venv on their own.
SHELL := /bin/bash
PYTHON ?= python3
VENV := $(CURDIR)/.venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

# Network hygiene (DESIGN 7): DDS stays on loopback, in a domain of our own.
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export ROS_DOMAIN_ID ?= $(shell echo $$(( $$PPID % 200 + 20 )))
export AMENT_PREFIX_PATH := $(VENV)
export MPLBACKEND := Agg

DEMO_BAG ?= bags/demo_3d

.PHONY: demo test venv lint bench clean models bags

venv: $(STAMP)

# The installer's own output (hundreds of lines of build warnings on a fresh venv) goes to a log;
# the terminal gets one line now and the log's tail only if the install fails. uv (installed into
# the venv by pip) installs the same versions as pip in about 35 s instead of 55 s, compiled to
# bytecode as pip does (the environment may forbid writing it later, and then every process of
# the suite would compile numpy and scipy anew: 350 s of tests became 410 s without it); where uv
# cannot reach an index that only pip is configured for, pip does it all. Both hold the venv to
# constraints.txt (scipy before 1.17, whose import makes each process of the shadow start slower).
INSTALL_LOG := $(VENV)/install.log
EXTRAS := .[ros,test,fast]

$(STAMP): setup.py setup.cfg pyproject.toml package.xml constraints.txt
	@echo "setting up $(VENV): python packages (under a minute, first run only; log $(INSTALL_LOG))"
	@$(PYTHON) -m venv $(VENV)
	@{ { $(PY) -m pip install "uv>=0.4" && $(VENV)/bin/uv pip install --compile-bytecode --python $(PY) -c constraints.txt -e "$(EXTRAS)"; } \
		|| { echo "uv failed: installing with pip"; $(PY) -m pip install --upgrade pip \
		&& $(PY) -m pip install -c constraints.txt -e "$(EXTRAS)"; }; } \
		> $(INSTALL_LOG) 2>&1 || { tail -n 20 $(INSTALL_LOG); echo "install failed: see $(INSTALL_LOG)"; exit 1; }
	@touch $(STAMP)

demo: $(STAMP)
	@echo "replaying $(DEMO_BAG) through the shadow (bridge-shadow replay $(DEMO_BAG))"
	@$(VENV)/bin/bridge-shadow replay $(DEMO_BAG)

# Two test processes (pytest-xdist; a file's tests stay together, so its fixtures are made once):
# the suite is CPU-bound, and each process confines DDS to its own domain (test/conftest.py).
# The project's own modules are compiled to bytecode first (a second or less; nothing if they are
# current): the installer compiles the packages it installs, but not this editable source, and
# where the environment forbids Python to write bytecode (PYTHONDONTWRITEBYTECODE) every process
# of the suite (the two test processes, each node, CLI and Dask worker they start) compiled the
# modules it imports anew (the node, CLI and fleet test files: 97 s of CPU instead of 89 s).
# Syntax errors are left for pytest to report. Files go to the processes in collection order, the
# heaviest first (test/conftest.py, HEAVIEST_FIRST), so that both finish together.
test: $(STAMP)
	@$(PY) -m compileall -q bridge_shadow test tools benchmarks > /dev/null || true
	$(PY) -m pytest -n 2 --dist loadfile --no-loadscope-reorder

lint: $(STAMP)
	$(VENV)/bin/ruff check bridge_shadow test benchmarks tools
	$(VENV)/bin/ruff format --check bridge_shadow test benchmarks tools

# Regenerate the generated model files after config/bridge.yaml, config/calibration.yaml or the FE
# code change: the uncalibrated FE surrogate, the calibrated default surrogate (with the README's
# calibration figures and the prior-sensitivity table in its provenance) and the bundled bags
# (made with the default surrogate). Commit the results. About 4.5 minutes on 2 cores (README).
# They replace the committed files on purpose, hence --force.
models: $(STAMP)
	$(VENV)/bin/bridge-shadow surrogate --out config/surrogate_fe.yaml --force
	$(VENV)/bin/bridge-shadow calibrate --out config/surrogate.yaml --report docs --prior-sensitivity --force
	$(MAKE) bags

# Rebuild every bag from its command in bags/README.md (the one place the commands are written).
bags: $(STAMP)
	grep -o '`bridge-shadow synth [^`]*`' bags/README.md | tr -d '`' | while read -r cmd; do \
		echo "$$cmd"; $(VENV)/bin/$$cmd || exit 1; done

bench: $(STAMP)
	for b in benchmarks/[!_]*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .ruff_cache
