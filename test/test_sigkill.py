"""What a SIGKILL of the node loses from its bag, in simulated time, stays under the flush
policy's bound (recorder.py: FLUSH_SECONDS of log time in the open chunk, BACKLOG_SECONDS waiting
for the writer, one tick): a property of the policy, not of the machine's speed.

Two cases the policy exists for: real-time factor 0 at 100 Hz (the tick outruns the writer
thread, whose backlog had no bound) and 4x at 10 Hz (a 64 KiB chunk spans over a second of
simulated time there). The measurement is the benchmark's (benchmarks/sigkill.measure): the
node as a process on loopback DDS, frozen with SIGSTOP once it has simulated 8 s, its /clock
drained, SIGKILL, its bag rebuilt by recover.
"""
from __future__ import annotations

import pytest
from dds import DOMAIN, REPO

from benchmarks.node.sigkill import ClockListener, measure
from mta_sim_ros.node.recorder import BACKLOG_SECONDS, FLUSH_SECONDS

SCENE = REPO / "config" / "scenes" / "headland_turn.yaml"

pytestmark = pytest.mark.dds


@pytest.fixture(scope="module")
def listener():
    clock = ClockListener(DOMAIN)
    yield clock
    clock.close()


@pytest.mark.parametrize("factor,rate", [(0.0, 100.0), (4.0, 10.0)])
def test_a_sigkill_loses_less_than_the_flush_bound(tmp_path, listener, factor, rate):
    kill = measure(str(SCENE), rate, factor, 8.0, tmp_path, DOMAIN, listener)
    assert kill.killed_at >= 8.0 and kill.last_logged > 0
    assert kill.lost < FLUSH_SECONDS + BACKLOG_SECONDS + 1.0 / rate + 1e-6, kill
