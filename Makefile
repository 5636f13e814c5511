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
# the venv is complete once tf2_msgs and ackermann_msgs are built into it (tools/build_interfaces.sh)
STAMP := $(VENV)/.mta_interfaces.stamp
INTERFACE_FILES := $(shell find interfaces -type f) tools/build_interfaces.sh tools/drop_missing_include_dirs.cmake

# colcon workspace dirs (ignored by git).
COLCON_BASE ?= .
COLCON_ARGS ?=

SCENE ?= config/scenes/headland_turn.yaml
# offline target (make offline): the same scene without ROS, as fast as possible
BAG ?= bags/headland_turn.mcap

.PHONY: venv run offline node test colcon clean distclean help

help:
	@echo "make venv     create $(VENV) (Python 3.11) with requirements.txt + pip install -e ., build interfaces/ into it"
	@echo "make run      the main job: node + manoeuvre for $(SCENE), headless; bag in bags/, report in reports/"
	@echo "make offline  the same scene offline (mta run, no ROS graph) into $(BAG)"
	@echo "make node     start the simulator node (config/sim.yaml), until Ctrl-C"
	@echo "make test     run the test suite (pytest)"
	@echo "make colcon   colcon build into $(COLCON_BASE)/build, install, log"
	@echo "make clean    remove build artifacts (keeps $(VENV)); distclean also removes $(VENV)"

venv: $(STAMP)

# Recreated/updated when requirements.txt, setup.py or setup.cfg change.
$(PIP_STAMP): requirements.txt setup.py setup.cfg
	@command -v $(PYTHON) >/dev/null || { echo "$(PYTHON) not found (set PYTHON=...)" >&2; exit 1; }
	@test -x $(VPY) || { echo "creating $(VENV) with $(PYTHON)"; $(PYTHON) -m venv $(VENV); }
	$(VPY) -m pip install -q -r requirements.txt
	$(VPY) -m pip install -q -e .
	@touch $@

# tf2_msgs and ackermann_msgs have no PyPI wheels: built from interfaces/ with rosidl (~10 s),
# again only when interfaces/ or the build script change, or the venv was updated.
$(STAMP): $(PIP_STAMP) $(INTERFACE_FILES)
	bash tools/build_interfaces.sh $(VENV)
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
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV)
