"""Where a tick's time goes: a ``timing.TickProfile`` that the node's own tick tells where each
stage ends (``RunSession(profile=...)``, ``node.main(argv, profile=...)``), nothing patched.

Per tick it keeps one row of ``COLUMNS``: the tick's wall time (perf_counter) and its thread's CPU
time (thread_time), the time of each stage of ``STAGES`` (advance, outputs, encode, markers,
publish, bag_write: each from the end of the one before, the first from the tick's start),
the time spent in the garbage collector within the tick (``gc.callbacks``) and the tick thread's
voluntary and involuntary context switches (``resource.getrusage(RUSAGE_THREAD)``). A tick that
halts (a model error) leaves no row.

Run as a module it is the node with the profile (``python -m benchmarks realtime --stages`` starts it as a
process of its own): the rows go to an .npy file when the node exits.
"""
from __future__ import annotations

import argparse
import gc
import resource
import sys
import time

STAGES = ("advance", "outputs", "encode", "markers", "publish", "bag_write")
COLUMNS = ("wall", "thread_cpu", *STAGES, "gc", "voluntary_cs", "involuntary_cs")
LABELS = {"wall": "whole tick (wall)", "thread_cpu": "thread CPU time", "not on CPU": "wall - CPU (preempted)",
          "encode": "encode (CDR templates)", "markers": "markers (encode, at marker_rate)",
          "publish": "publish, every topic and /clock", "bag_write": "bag (hand-over to its thread)",
          "other": "rest of the tick", "gc": "of which garbage collection"}


class StageProfile:
    """The rows of every tick profiled (see the module docstring); a context manager that hooks
    into the garbage collector while it is open."""

    def __init__(self):
        self.rows: list[tuple[float, ...]] = []
        self._index = {name: i for i, name in enumerate(STAGES)}
        self._stages = [0.0] * len(STAGES)
        self._in_tick = False
        self._gc = self._gc_started = 0.0

    def __enter__(self) -> "StageProfile":
        gc.callbacks.append(self._on_gc)
        return self

    def __exit__(self, *exc) -> None:
        gc.callbacks.remove(self._on_gc)

    def _on_gc(self, phase: str, info) -> None:
        if self._in_tick:
            if phase == "start":
                self._gc_started = time.perf_counter()
            else:
                self._gc += time.perf_counter() - self._gc_started

    def start(self) -> None:
        self._gc = 0.0
        self._in_tick = True
        self._usage = resource.getrusage(resource.RUSAGE_THREAD)
        self._cpu = time.thread_time()
        self._started = self._last = time.perf_counter()

    def mark(self, stage: str) -> None:
        now = time.perf_counter()
        self._stages[self._index[stage]] = now - self._last
        self._last = now

    def done(self) -> None:
        wall, cpu = time.perf_counter() - self._started, time.thread_time() - self._cpu
        usage = resource.getrusage(resource.RUSAGE_THREAD)
        self._in_tick = False
        self.rows.append((wall, cpu, *self._stages, self._gc, usage.ru_nvcsw - self._usage.ru_nvcsw,
                          usage.ru_nivcsw - self._usage.ru_nivcsw))

    def table(self, skip: int = 0):
        """The rows from tick ``skip`` on as an array (ticks x COLUMNS, s and counts)."""
        import numpy as np

        return np.array(self.rows[skip:], dtype=float).reshape(-1, len(COLUMNS))


def column(data, name: str):
    """One column of a table of rows, by name (``COLUMNS``)."""
    return data[:, COLUMNS.index(name)]


def stage_report(data) -> tuple[list[str], list[str]]:
    """Where the tick time goes, from a table of rows: (printed lines, Markdown lines)."""
    import numpy as np

    if not len(data):
        return ["no ticks recorded"], ["No ticks recorded."]
    cols = {name: column(data, name) for name in COLUMNS}
    wall = cols["wall"]
    cols["other"] = wall - sum(cols[name] for name in STAGES)
    cols["not on CPU"] = np.clip(wall - cols["thread_cpu"], 0.0, None)  # preempted, waiting
    p99, p999 = np.percentile(wall, 99), np.percentile(wall, 99.9)
    slow99, slow = wall >= p99, wall >= p999
    md = ["| stage | median, us | mean, us | p99.9, us | mean in the slowest 1 % of ticks, us | "
          "mean in the slowest 0.1 %, us |", "|---|---:|---:|---:|---:|---:|"]
    text = [f"  {'stage':<28} {'median':>9} {'mean':>9} {'p99.9':>9} {'slow 1%':>9} {'slow 0.1%':>9}  (us)"]
    for name in ("wall", "thread_cpu", "not on CPU", *STAGES, "other", "gc"):
        v = cols[name] * 1e6
        row = (np.median(v), v.mean(), np.percentile(v, 99.9), v[slow99].mean(), v[slow].mean())
        md.append(f"| {LABELS.get(name, name)} | " + " | ".join(f"{x:.1f}" for x in row) + " |")
        text.append(f"  {LABELS.get(name, name)[:28]:<28} " + " ".join(f"{x:9.1f}" for x in row))
    vol, invol, cpu = cols["voluntary_cs"], cols["involuntary_cs"], cols["thread_cpu"]
    summary = [
        "",
        "The node's tick (`run_session.RunSession.tick`) says where each stage ends (`RunSession(profile=...)`, "
        "`benchmarks/stages.py`); each stage runs from the end of the one before. `publish` is "
        "one stage: every topic, /clock included.", "",
        f"{len(wall)} ticks; the slowest 0.1 % are the {int(slow.sum())} ticks of {p999 * 1e3:.3f} ms or more, "
        f"the slowest 1 % the {int(slow99.sum())} of {p99 * 1e3:.3f} ms or more. In the slowest 0.1 % the thread "
        f"was on the CPU {100 * cpu[slow].sum() / wall[slow].sum():.0f} % of the tick's wall time "
        f"(all ticks: {100 * cpu.sum() / wall.sum():.0f} %); garbage collection ran in "
        f"{int((cols['gc'] > 0).sum())} ticks ({int((cols['gc'][slow] > 0).sum())} of the slowest 0.1 %). "
        f"Context switches of the tick's thread: voluntary (it blocked: a lock, I/O) in "
        f"{100 * (vol > 0).mean():.1f} % of all ticks and {100 * (vol[slow] > 0).mean():.0f} % of the slowest 0.1 %; "
        f"involuntary (preempted) in {100 * (invol > 0).mean():.1f} % of all ticks and "
        f"{100 * (invol[slow] > 0).mean():.0f} % of the slowest 0.1 %.",
    ]
    return text + summary, md + summary


def profiled_node_main(argv: list[str]) -> int:
    """The node (``node.main``) with a StageProfile; its rows saved to --stages-out at exit."""
    import numpy as np

    from mta_sim_ros.node import sim_node as node

    p = argparse.ArgumentParser(prog="python -m benchmarks.stages")
    p.add_argument("--params-file", required=True)
    p.add_argument("--stages-out", required=True)
    a = p.parse_args(argv)
    with StageProfile() as profile:
        try:
            return node.main(["mta_node", "--ros-args", "--params-file", a.params_file], profile=profile)
        finally:
            np.save(a.stages_out, profile.table())


if __name__ == "__main__":
    sys.exit(profiled_node_main(sys.argv[1:]))
