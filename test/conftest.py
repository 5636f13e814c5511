"""What the tests share: the markers' rule and the fixtures more than one file uses.

Markers (registered in pytest.ini, which passes --strict-markers):

- ``dds``: the test starts ROS processes (the node, a player, a controller) or an rclpy context of
  its own and talks over DDS (loopback, this session's own domain: dds.py). A file that does so in
  every test says it once, ``pytestmark = pytest.mark.dds``; a mixed file marks those tests.
- ``slow``: talks no DDS but takes a second or more on a quiet 2-core machine: whole commands
  as processes (a file of them per case: ``pytestmark``), a colcon build, a venv, a Dask
  cluster, long simulations and searches.

``pytest -m "not dds and not slow"`` runs the quick in-process tests; ``pytest -m "not dds"``
adds the slow ones; ``make test`` runs every test.
Helpers that are plain functions stay in modules of their own (dds.py, trains.py, hostile.py, ...).
"""
from __future__ import annotations

import pytest


@pytest.fixture
def probe(request):
    """The test's own ROS node in a private context (dds.Probe), closed after the test. Only a
    test marked ``dds`` may take it: one that is not would run under ``-m "not dds"``."""
    if request.node.get_closest_marker("dds") is None:
        pytest.fail(f"{request.node.nodeid} takes the probe (DDS) but is not marked dds", pytrace=False)
    from dds import Probe  # imports rclpy: only where a test needs it

    p = Probe()
    yield p
    p.close()
