"""Tick statistics and real-time factor of the node (mta_sim_ros.node.timing), without sleeping."""
from __future__ import annotations

import math

import numpy as np
import pytest

from mta_sim_ros.node.timing import RealTimeFactor, TickStats, interpolated_percentile

PERCENTILES = (0.0, 1.0, 25.0, 50.0, 90.0, 99.0, 99.9, 100.0)


def lognormal(n, median=2e-3, sigma=0.6, seed=1):
    """Tick times of a plausible node: 2 ms typical, a long right tail."""
    return np.random.default_rng(seed).lognormal(math.log(median), sigma, n)


def recorded(samples, **options) -> TickStats:
    stats = TickStats(**options)
    for s in samples:
        stats.record(float(s))
    return stats


@pytest.mark.parametrize("n", [1, 2, 7, 1000, 100_000])
def test_percentiles_within_the_bucket_width(n):
    samples = lognormal(n)
    stats = recorded(samples)
    assert stats.relative_error <= 0.005
    for p in PERCENTILES:
        exact = np.percentile(samples, p)
        assert abs(stats.percentile(p) - exact) <= stats.relative_error * exact * (1 + 1e-9), p
    assert stats.count == n
    assert stats.max == samples.max() and stats.min == samples.min()  # exact
    assert stats.mean == pytest.approx(samples.mean(), rel=1e-12)


def test_percentiles_of_a_wide_spread():
    """From 2 us to 5 s: every decade of the range in one run."""
    samples = np.exp(np.random.default_rng(2).uniform(math.log(2e-6), math.log(5.0), 50_000))
    stats = recorded(samples)
    for p in PERCENTILES:
        exact = np.percentile(samples, p)
        assert abs(stats.percentile(p) / exact - 1) <= stats.relative_error * (1 + 1e-9), p


def test_samples_outside_the_range_clamp_but_max_is_exact():
    stats = recorded([1e-9, 2e-3, 2e-3, 3e-3, 60.0])
    assert stats.max == 60.0 and stats.min == 1e-9
    assert stats.percentile(100.0) == 60.0
    assert stats.percentile(0.0) == 1e-9
    assert stats.percentile(50.0) == pytest.approx(2e-3, rel=stats.relative_error)
    assert len(stats._counts) == len(TickStats()._counts)
    # all samples beyond the range: the percentiles stay inside the exact [min, max]
    slow = recorded([20.0, 30.0, 40.0])
    assert all(20.0 <= slow.percentile(p) <= 40.0 for p in PERCENTILES)


def test_memory_is_constant():
    stats = TickStats(window=1000)
    buckets = len(stats._counts)
    assert buckets == math.ceil(math.log(10.0 / 1e-6) / math.log(1.01))  # 1620 for 1 us .. 10 s
    samples = lognormal(1_000_000, seed=3)
    for s in samples.tolist():
        stats.record(s)
    assert len(stats._counts) == buckets
    assert len(stats._window) == 1000
    assert stats.count == 1_000_000 and sum(stats._counts) == 1_000_000
    assert stats.max == samples.max()
    exact = np.percentile(samples, 99.9)
    assert abs(stats.percentile(99.9) - exact) <= stats.relative_error * exact * (1 + 1e-9)


def test_deadline_misses():
    stats = TickStats()
    for s in (0.005, 0.02, 0.021, 0.5, 0.001):
        stats.record(s, deadline=0.02)
    stats.record(1.0)  # no deadline given: never a miss
    assert stats.deadline_misses == 2  # exactly on the deadline is in time


def test_window_holds_the_last_ticks():
    stats = TickStats(window=10)
    for i in range(100):
        stats.record(1e-3 * (i + 1))
    last = [1e-3 * (i + 1) for i in range(90, 100)]
    assert list(stats._window) == last
    for p in (0.0, 50.0, 99.0, 100.0):
        assert stats.window_percentile(p) == pytest.approx(np.percentile(last, p), rel=1e-12)
    assert stats.window_max == 0.1
    stats.record(5.0)  # one slow tick: in the window's max until ten more ticks push it out
    assert stats.window_max == 5.0
    for _ in range(10):
        stats.record(1e-3)
    assert stats.window_max == 1e-3
    assert stats.max == 5.0  # the whole run remembers it


def test_summary():
    stats = TickStats(window=3)
    assert all(math.isnan(v) for k, v in stats.summary().items()
               if k not in ("count", "deadline_misses", "window_count"))
    for s in (0.001, 0.002, 0.003, 0.004):
        stats.record(s, deadline=0.0025)
    summary = stats.summary()
    assert summary == {
        "count": 4, "mean": pytest.approx(0.0025), "min": 0.001,
        "p50": pytest.approx(0.0025, rel=stats.relative_error),
        "p99": pytest.approx(np.percentile([1, 2, 3, 4], 99) * 1e-3, rel=stats.relative_error),
        "p99.9": pytest.approx(np.percentile([1, 2, 3, 4], 99.9) * 1e-3, rel=stats.relative_error),
        "max": 0.004, "deadline_misses": 2, "window_count": 3,
        "window_p50": pytest.approx(0.003), "window_p99": pytest.approx(0.00398),
        "window_max": 0.004,
    }


def test_bad_input():
    stats = TickStats()
    for bad in (-1e-3, math.nan):
        with pytest.raises(ValueError, match="tick time"):
            stats.record(bad)
    assert stats.count == 0
    for p in (-1.0, 100.5):
        with pytest.raises(ValueError, match="percentile"):
            stats.percentile(p)
    with pytest.raises(ValueError):
        TickStats(window=0)
    with pytest.raises(ValueError):
        TickStats(growth=1.0)


def test_interpolated_percentile_is_numpys():
    values = sorted(lognormal(37, seed=4).tolist())
    for p in PERCENTILES:
        exact = np.percentile(values, p)
        assert interpolated_percentile(values, p) == pytest.approx(exact, rel=1e-12)
    assert math.isnan(interpolated_percentile([], 50.0))


class FakeClock:
    """A steady clock the test moves by hand."""

    def __init__(self, now=1000.0):
        self.now = now

    def __call__(self):
        return self.now


def test_real_time_factor_steady_rate():
    clock = FakeClock()
    rtf = RealTimeFactor(window=5.0, clock=clock)
    assert math.isnan(rtf.value)
    rtf.update(0.0)
    assert math.isnan(rtf.value)  # no wall time has passed yet
    for tick in range(1, 501):  # 50 Hz wall, 0.04 s of sim per tick: twice real time
        clock.now += 0.02
        rtf.update(0.04 * tick)
        assert rtf.value == pytest.approx(2.0)
        if clock.now - 1000.0 >= 5.0:  # measured over the window plus at most one mark spacing
            assert 5.0 <= clock.now - rtf._marks[0][0] <= 5.0 + 5.0 / 20 + 0.02 + 1e-9
    assert len(rtf._marks) <= 22  # window / spacing + the anchor: constant memory


def test_real_time_factor_follows_a_change_within_the_window():
    clock = FakeClock()
    rtf = RealTimeFactor(window=5.0, marks=20, clock=clock)
    sim = 0.0
    for _ in range(1000):  # 20 s at real time
        clock.now += 0.02
        sim += 0.02
        rtf.update(sim)
    assert rtf.value == pytest.approx(1.0)
    for _ in range(150):  # 3 s at half real time: a mix of both rates
        clock.now += 0.02
        sim += 0.01
        rtf.update(sim)
    assert 0.5 < rtf.value < 1.0
    for _ in range(300):  # 6 s more: only the new rate is left in the window
        clock.now += 0.02
        sim += 0.01
        rtf.update(sim)
    assert rtf.value == pytest.approx(0.5)
    for _ in range(300):  # paused: sim time stands still
        clock.now += 0.02
        rtf.update(sim)
    assert rtf.value == 0.0


def test_real_time_factor_restarts_after_a_reset():
    clock = FakeClock()
    rtf = RealTimeFactor(window=5.0, clock=clock)
    for tick in range(100):
        clock.now += 0.01
        rtf.update(0.05 * tick)
    clock.now += 0.01
    rtf.update(0.0)  # the simulation was reset
    assert math.isnan(rtf.value)
    clock.now += 0.1
    rtf.update(0.1)
    assert rtf.value == pytest.approx(1.0)


def test_real_time_factor_bad_arguments():
    with pytest.raises(ValueError):
        RealTimeFactor(window=0.0)
    with pytest.raises(ValueError):
        RealTimeFactor(marks=0)


RESERVE = """
import json, os, threading
from mta_sim_ros.node.timing import reserve_cpu
stop = threading.Event()
other = threading.Thread(target=stop.wait)
other.start()  # returns once the thread runs and has its native id
cpus = sorted(os.sched_getaffinity(0))
try:
    note = reserve_cpu(cpus[-1])
    result = {"note": note, "main": sorted(os.sched_getaffinity(0)),
              "other": sorted(os.sched_getaffinity(other.native_id)), "cpus": cpus}
except ValueError as err:
    result = {"error": str(err), "cpus": cpus}
stop.set()
print(json.dumps(result))
"""


def test_reserve_cpu_pins_the_tick_thread_and_moves_the_others_off_it():
    """In a child process (pytest's own affinity stays): the calling thread ends up on the
    chosen CPU alone, every other thread of the process on the remaining CPUs; on a one-CPU
    machine it refuses, saying why. A CPU the process may not use is refused, naming it."""
    import json
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", RESERVE], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    r = json.loads(done.stdout)
    if len(r["cpus"]) < 2:
        assert "the only one available" in r["error"]
    else:
        assert r["main"] == [r["cpus"][-1]]
        assert r["other"] == r["cpus"][:-1] and r["cpus"][-1] not in r["other"]
        assert f"CPU {r['cpus'][-1]}" in r["note"]
    from mta_sim_ros.node.timing import reserve_cpu

    with pytest.raises(ValueError, match="tick_cpu: CPU 4095 is not available"):
        reserve_cpu(4095)
