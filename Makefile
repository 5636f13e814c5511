# mta_sim_ros developer entry points. CI runs `make test` via .ci/run.

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
.DEFAULT_GOAL := venv

# Network rule: DDS stays on loopback for every target: discovery on this host, and the Fast DDS
# profile that binds every listening socket to 127.0.0.1 (Fast DDS 2.x reads FASTRTPS_, 3.x FASTDDS_).
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export FASTRTPS_DEFAULT_PROFILES_FILE := $(CURDIR)/config/fastdds_loopback.xml
export FASTDDS_DEFAULT_PROFILES_FILE := $(CURDIR)/config/fastdds_loopback.xml
# Default domain; a test or caller may override it (make ROS_DOMAIN_ID=7 ...).
ROS_DOMAIN_ID ?= 42
export ROS_DOMAIN_ID
# No prompts (CI has no stdin); no "new pip available" noise.
export PIP_NO_INPUT := 1
export PIP_DISABLE_PIP_VERSION_CHECK := 1

PYTHON ?= python3.11
VENV ?= .venv
VPY := $(VENV)/bin/python
PIP_STAMP := $(VENV)/.mta_sim_ros.stamp
# the venv is complete once tf2_msgs, ackermann_msgs and simulation_interfaces are built into it (tools/build_interfaces.sh)
STAMP := $(VENV)/.mta_interfaces.stamp
INTERFACE_FILES := $(shell find interfaces -type f) tools/build_interfaces.sh tools/drop_missing_include_dirs.cmake
# The second stack (make test-noble): Ubuntu 24.04's numpy, scipy, matplotlib and numba, the
# versions a ROS 2 Jazzy install has, by constraints-noble.txt over the same requirements.txt.
NOBLE_VENV ?= .venv-noble
NOBLE_PIP_STAMP := $(NOBLE_VENV)/.mta_sim_ros.stamp
NOBLE_STAMP := $(NOBLE_VENV)/.mta_interfaces.stamp

# colcon workspace dirs (ignored by git).
COLCON_BASE ?= .
COLCON_ARGS ?=

SCENE ?= config/scenes/headland_turn.yaml
# offline target (make offline): the same scene without ROS, as fast as possible
BAG ?= bags/headland_turn.mcap

.PHONY: venv venv-noble run offline node test test-noble colcon clean distclean help

help:
	@echo "make venv     create $(VENV) (Python 3.11) with requirements.txt + pip install -e ., build interfaces/ into it"
	@echo "make run      the main job: node + manoeuvre for $(SCENE), headless; bag in bags/, report in reports/"
	@echo "make offline  the same scene offline (mta run, no ROS graph) into $(BAG)"
	@echo "make node     start the simulator node (config/sim.yaml), until Ctrl-C"
	@echo "make test     run the test suite (pytest)"
	@echo "make test-noble  the test suite on Ubuntu 24.04's numpy/scipy/matplotlib/numba, in $(NOBLE_VENV)"
	@echo "make colcon   colcon build into $(COLCON_BASE)/build, install, log"
	@echo "make clean    remove build artifacts (keeps the venvs); distclean also removes $(VENV) and $(NOBLE_VENV)"

venv: $(STAMP)
venv-noble: $(NOBLE_STAMP)

# One recipe for both venvs (the venv is the stamp's folder, $(@D)); recreated/updated when
# requirements.txt, setup.py or setup.cfg change, the noble one also when its constraints do.
$(NOBLE_PIP_STAMP): CONSTRAINTS := -c constraints-noble.txt
$(NOBLE_PIP_STAMP): constraints-noble.txt
$(PIP_STAMP) $(NOBLE_PIP_STAMP): requirements.txt setup.py setup.cfg
	@command -v $(PYTHON) >/dev/null || { echo "$(PYTHON) not found (set PYTHON=...)" >&2; exit 1; }
	@test -x $(@D)/bin/python || { echo "creating $(@D) with $(PYTHON)"; $(PYTHON) -m venv $(@D); }
	$(@D)/bin/python -m pip install -q -r requirements.txt $(CONSTRAINTS)
	$(@D)/bin/python -m pip install -q -e . $(CONSTRAINTS)
	@touch $@

# tf2_msgs, ackermann_msgs and simulation_interfaces have no PyPI wheels: built from interfaces/ with rosidl into each
# venv, again only when interfaces/ or the build script change, or the venv was updated.
$(STAMP): $(PIP_STAMP)
$(NOBLE_STAMP): $(NOBLE_PIP_STAMP)
# Then the kernels compiled into numba's cache (mta compile, ~25 s), so that the first node start
# ticks within ~1 s; the noble venv's numba keeps its own cache (test-noble's NUMBA_CACHE_DIR).
$(STAMP) $(NOBLE_STAMP): $(INTERFACE_FILES)
	bash tools/build_interfaces.sh $(@D)
	$(if $(filter $(NOBLE_STAMP),$@),NUMBA_CACHE_DIR=$(abspath $(NOBLE_VENV))/numba-cache) $(@D)/bin/mta compile --quiet
	@touch $@

run: $(STAMP)
	$(VENV)/bin/mta session --scene $(SCENE) --bag-dir bags --report-dir reports

offline: $(STAMP)
	@mkdir -p $(dir $(BAG))
	$(VENV)/bin/mta run --scene $(SCENE) --bag $(BAG)

node: $(STAMP)
	$(VENV)/bin/mta node --params-file config/sim.yaml

test: $(STAMP)
	$(VPY) -m pytest -q test

# numba's disk cache of the kernels in the venv: each venv keeps its own compiled code (numba
# drops a cache written by another numba version, so sharing would recompile on every switch).
test-noble: $(NOBLE_STAMP)
	NUMBA_CACHE_DIR=$(abspath $(NOBLE_VENV))/numba-cache $(NOBLE_VENV)/bin/python -m pytest -q test

# --paths (not --base-paths): build exactly this package; a recursive crawl
# would also find the package.xml files shipped inside $(VENV).
colcon: $(STAMP)
	$(VENV)/bin/colcon --log-base $(COLCON_BASE)/log build \
		--paths . \
		--build-base $(COLCON_BASE)/build \
		--install-base $(COLCON_BASE)/install \
		$(COLCON_ARGS)

clean:
	rm -rf build install log .pytest_cache *.egg-info
	find . \( -path ./$(VENV) -o -path ./$(NOBLE_VENV) \) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV) $(NOBLE_VENV)
