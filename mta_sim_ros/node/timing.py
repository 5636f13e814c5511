"""Tick timing of the ROS node, in constant memory: it may run for days. No ROS here.

:class:`TickStats` keeps the compute time of every tick in a log-bucketed histogram (whole-run
percentiles, exact count, mean, min and max) and the last ticks in a fixed-size window (for the
1 Hz diagnostics). :class:`RealTimeFactor` measures how fast simulated time advances against a
steady wall clock. :class:`TickTiming` times each tick of a run, wall and CPU; a
:class:`TickProfile` is told where a tick's stages end (the benchmarks'), :class:`NoProfile`
hears nothing.
"""
from __future__ import annotations

import math
import os
import threading
import time
from bisect import bisect_right
from collections import deque
from itertools import accumulate
from typing import Callable, Protocol, Sequence


def interpolated_percentile(ordered: Sequence[float], p: float) -> float:
    """The p-th percentile of sorted values, interpolated linearly between the two nearest
    ranks (numpy.percentile's default method); nan for no values."""
    if not ordered:
        return math.nan
    rank = p / 100.0 * (len(ordered) - 1)
    lo = math.floor(rank)
    hi = min(lo + 1, len(ordered) - 1)
    return ordered[lo] + (rank - lo) * (ordered[hi] - ordered[lo])


def _check_percentile(p: float) -> None:
    if not 0.0 <= p <= 100.0:
        raise ValueError(f"percentile must be in [0, 100], got {p!r}")


class TickStats:
    """Compute-time statistics of the node's ticks, in memory that does not grow with the run.

    Whole run: ``count``, ``mean``, exact ``min`` and ``max``, ``deadline_misses`` and
    :meth:`percentile` from a histogram of ``buckets`` logarithmic buckets spanning
    [``lowest``, ``highest``) seconds, each ``growth`` times wider than the previous (relative
    width 1 %). A percentile is interpolated between the geometric centres of the buckets that
    hold its two nearest ranks, so for samples inside the range it is within
    :attr:`relative_error` (sqrt(growth) - 1, about 0.5 %) of the exact one; the first and last
    ranks are the exact min and max. Samples outside the range count in the end buckets, and
    every percentile is clamped to the exact [min, max].

    Last ticks: a window of the latest ``window`` samples with exact :meth:`window_percentile`
    and :attr:`window_max`.
    """

    def __init__(self, window: int = 1000, lowest: float = 1e-6, highest: float = 10.0,
                 growth: float = 1.01):
        if window < 1:
            raise ValueError(f"window must be >= 1, got {window!r}")
        if not 0.0 < lowest < highest or not growth > 1.0:
            raise ValueError(f"need 0 < lowest < highest and growth > 1, got lowest={lowest!r}, "
                             f"highest={highest!r}, growth={growth!r}")
        self.lowest = lowest
        self.growth = growth
        self._log_lowest = math.log(lowest)
        self._log_growth = math.log(growth)
        buckets = math.ceil(math.log(highest / lowest) / self._log_growth)
        self._counts = [0] * buckets
        self._window: deque[float] = deque(maxlen=window)
        self.count = 0
        self.total = 0.0
        self.min = math.nan
        self.max = math.nan
        self.deadline_misses = 0

    @property
    def relative_error(self) -> float:
        """Bound on the relative error of :meth:`percentile` for samples inside the range."""
        return math.sqrt(self.growth) - 1.0

    def record(self, seconds: float, deadline: float | None = None) -> None:
        """Add one tick's compute time; it misses the ``deadline`` (s) if it took longer.

        Raises:
            ValueError: ``seconds`` is negative or nan.
        """
        if not seconds >= 0.0:
            raise ValueError(f"tick time must be >= 0 s, got {seconds!r}")
        self._counts[self._bucket(seconds)] += 1
        self._window.append(seconds)
        self.total += seconds
        if self.count == 0:
            self.min = self.max = seconds
        else:
            self.min = min(self.min, seconds)
            self.max = max(self.max, seconds)
        self.count += 1
        if deadline is not None and seconds > deadline:
            self.deadline_misses += 1

    @property
    def mean(self) -> float:
        """Mean tick time over the run, s (nan before the first tick)."""
        return self.total / self.count if self.count else math.nan

    def percentile(self, p: float) -> float:
        """The p-th percentile (0..100) of the run's tick times, s (nan before the first tick)."""
        _check_percentile(p)
        if not self.count:
            return math.nan
        cumulative = list(accumulate(self._counts))
        rank = p / 100.0 * (self.count - 1)
        lo = math.floor(rank)
        hi = min(lo + 1, self.count - 1)
        v_lo, v_hi = (self._ranked_value(r, cumulative) for r in (lo, hi))
        value = v_lo + (rank - lo) * (v_hi - v_lo)
        return min(max(value, self.min), self.max)

    def window_percentile(self, p: float) -> float:
        """The exact p-th percentile (0..100) of the last ticks, s (nan before the first)."""
        _check_percentile(p)
        return interpolated_percentile(sorted(self._window), p)

    @property
    def window_max(self) -> float:
        """Longest of the last ticks, s (nan before the first)."""
        return max(self._window, default=math.nan)

    def summary(self) -> dict[str, float | int]:
        """All the statistics, for diagnostics and reports (times in s)."""
        return {
            "count": self.count,
            "mean": self.mean,
            "min": self.min,
            "p50": self.percentile(50.0),
            "p99": self.percentile(99.0),
            "p99.9": self.percentile(99.9),
            "max": self.max,
            "deadline_misses": self.deadline_misses,
            "window_count": len(self._window),
            "window_p50": self.window_percentile(50.0),
            "window_p99": self.window_percentile(99.0),
            "window_max": self.window_max,
        }

    def _bucket(self, seconds: float) -> int:
        """Index of the bucket of a sample, clamped to the end buckets."""
        if seconds <= self.lowest:
            return 0
        index = int((math.log(seconds) - self._log_lowest) / self._log_growth)
        return min(index, len(self._counts) - 1)

    def _ranked_value(self, rank: int, cumulative: list[int]) -> float:
        """The sample of 0-based ``rank`` in sorted order, s: exact for the first and the last
        (min, max), else the geometric centre of its bucket, the first whose cumulative count
        exceeds ``rank``."""
        if rank == 0:
            return self.min
        if rank == self.count - 1:
            return self.max
        index = bisect_right(cumulative, rank)
        return math.exp(self._log_lowest + (index + 0.5) * self._log_growth)


class RealTimeFactor:
    """Simulated time advanced per wall-clock second, over the last ``window`` seconds.

    Call :meth:`update` with the simulation time after each tick. Constant memory: one mark
    (wall time, sim time) is kept every ``window / marks`` seconds of wall time, plus the
    latest update. The factor is measured from the last mark at or before the window's start
    (the first mark while the run is shorter) to the latest update, so once the run is long
    enough the span is ``window`` plus at most one mark spacing (or the gap between two
    updates, when longer). A simulation time that goes backwards (a reset) starts the
    measurement afresh. ``clock`` is the steady wall clock, injectable for tests.
    """

    def __init__(self, window: float = 5.0, marks: int = 20,
                 clock: Callable[[], float] = time.monotonic):
        if not window > 0.0 or marks < 1:
            raise ValueError(f"need window > 0 and marks >= 1, got {window!r}, {marks!r}")
        self.window = window
        self._spacing = window / marks
        self._clock = clock
        self._marks: deque[tuple[float, float]] = deque()
        self._latest: tuple[float, float] | None = None

    def update(self, sim_time: float) -> None:
        """Note that the simulation has reached ``sim_time`` (s) now."""
        now = self._clock()
        if self._latest is not None and sim_time < self._latest[1]:
            self._marks.clear()
        self._latest = (now, sim_time)
        if not self._marks or now - self._marks[-1][0] >= self._spacing:
            self._marks.append(self._latest)
        # Keep one mark at or before the window's start as the anchor of the measurement.
        while len(self._marks) > 1 and self._marks[1][0] <= now - self.window:
            self._marks.popleft()

    @property
    def value(self) -> float:
        """Sim seconds per wall second over the window; nan until wall time has passed."""
        if self._latest is None:
            return math.nan
        wall0, sim0 = self._marks[0]
        wall, sim = self._latest
        return (sim - sim0) / (wall - wall0) if wall > wall0 else math.nan


def reserve_cpu(cpu: int) -> str:
    """Give the calling thread (the node's executor, which runs the tick) the CPU ``cpu`` to
    itself within this process: pin it there and move the process's other threads (DDS, the bag
    writer) to the remaining CPUs. Other processes are not moved: start them elsewhere (taskset)
    for a core truly reserved. Linux only; no privileges needed. Returns what it did.

    Raises:
        ValueError: ``cpu`` is not one this process may run on, or it is the only one.
    """
    allowed = os.sched_getaffinity(0)
    if cpu not in allowed:
        raise ValueError(f"tick_cpu: CPU {cpu} is not available to this process (available: {sorted(allowed)})")
    if len(allowed) < 2:
        raise ValueError(f"tick_cpu: CPU {cpu} is the only one available; nothing could move off it")
    others = allowed - {cpu}
    me = threading.get_native_id()
    moved = 0
    for tid in (int(t) for t in os.listdir("/proc/self/task")):
        if tid != me:
            try:
                os.sched_setaffinity(tid, others)
                moved += 1
            except ProcessLookupError:  # the thread ended meanwhile
                pass
    os.sched_setaffinity(0, {cpu})  # 0 = the calling thread (Linux)
    return f"tick thread pinned to CPU {cpu}; {moved} other threads of the node on CPUs {sorted(others)}"


class TickTiming:
    """The compute time of each tick of a run: wall (``stats``, on ``compute_clock``) and the tick
    thread's CPU (``cpu``, on ``cpu_clock``) over the same work: wall >> CPU means the thread was
    preempted (other processes on the core), not that the tick's code was slow. ``started``: the
    run's start on the steady ``clock``."""

    def __init__(self, clock: Callable[[], float], compute_clock: Callable[[], float] = time.perf_counter,
                 cpu_clock: Callable[[], float] = time.thread_time):
        self.clock, self.compute_clock, self.cpu_clock = clock, compute_clock, cpu_clock
        self.new_run()

    def new_run(self) -> None:
        """Fresh statistics and wall time for a run (start, reset)."""
        self.stats = TickStats()
        self.cpu = TickStats()
        self.started = self.clock()

    def start(self) -> None:
        """A tick's work begins."""
        self._wall, self._cpu = self.compute_clock(), self.cpu_clock()

    def stop(self, period: float) -> None:
        """The tick's work ends; it misses its deadline past ``period`` s (0: no deadline)."""
        cpu = self.cpu_clock() - self._cpu
        self.stats.record(self.compute_clock() - self._wall, deadline=period if period > 0 else None)
        self.cpu.record(cpu)


class TickProfile(Protocol):
    """Where a tick's time goes (``python -m benchmarks realtime --stages``): ``start`` when a tick
    begins, ``mark(stage)`` as each stage ends (advance, outputs, encode, markers, publish,
    bag_write), ``done`` when it ends."""

    def start(self) -> None: ...

    def mark(self, stage: str) -> None: ...

    def done(self) -> None: ...


class NoProfile:
    """A TickProfile that hears nothing (the session's, unless it is given one)."""

    def start(self) -> None:
        pass

    def mark(self, stage: str) -> None:
        pass

    def done(self) -> None:
        pass
