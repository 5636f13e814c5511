"""``python -m benchmarks sweep-lanes``: a sweep's run across SIMD lanes (run/lanes_batch.py) against the
same run alone, by the width of the batch and the number of carts.

The headland turn (config/scenes/headland_turn.yaml: 70 s, rk4, the step its tolerance 1e-6 m
chooses, 50 Hz) driven by random trains of 2, 3 and 5 carts (the governor, a draft on the last
cart and from 3 carts one on the second; benchmarks/throughput/lanes_rhs.py), fidelity dynamic.
For each number of carts and batch width, side by side in turns (thread CPU time, medians):

- ``alone``: ``batch.run_metrics`` of each scheme, one after the other (a sweep's run before
  issue 24: the step search, the run and its companion at half the step, the metrics);
- ``lanes``: ``lanes_batch.run_metrics_many`` of the batch (what ``mta sweep`` runs now);
- the kernel's part alone: the run at 0.02 s without metrics or companion, ``batch.run_trace`` of
  each scheme against ``lanes_batch.run_traces`` of the batch (vmath).

- the floor (benchmarks/throughput/sweep_floor.py): the run's rk4 steps and nothing else, in C
  (run_floor.c, built here by gcc where there is one: one scheme at a time, and eight a vector with
  glibc's vector math) and in the kernel (one scheme at a time, and across the batch).

ms per run and runs/s/core; the largest relative difference of any metric between the two (the
position error apart, whose round-off is absolute). A sweep worker's memory: for each number of
carts and a task's width (``MEMORY_WIDTHS`` runs), a fresh process (``worker_memory``) runs them
through ``run_metrics_many`` and reports its resident memory before and its peak. Writes
docs/benchmarks/sweep_lanes.md, .json and .png (runs/s/core against width).
"""
from __future__ import annotations

import dataclasses
import json
import math
import resource
import statistics
import time
from pathlib import Path

from mta_sim_ros.validate import COUNT, number_arg, output_file, path_arg

from ..common import header_lines, side_by_side, table, write_report

HELP = "a sweep's run across SIMD lanes against alone: ms per run by batch width and carts"
SCENE = "scenes/headland_turn.yaml"
CARTS, WIDTHS = (2, 3, 5), (8, 64, 256)
#: schemes run alone per round (the per-run cost does not depend on how many)
ALONE = 8
#: a task's runs (a sweep's ``batch:``) whose worker's memory is measured
MEMORY_WIDTHS = (64, 256, 1024)


def add_arguments(p) -> None:
    p.add_argument("--rounds", type=number_arg(COUNT, int), default=3, help="rounds taken in turns (default 3)")
    p.add_argument("--out", type=path_arg(output_file), default="docs/benchmarks/sweep_lanes.md", help="Markdown report")


def schemes(scene, n: int, width: int) -> list:
    """``width`` random trains of n carts on ``scene``."""
    import numpy as np

    from ..common import random_train

    rng = np.random.default_rng(20261206 + n)
    return [dataclasses.replace(scene, train=random_train(n, rng)) for _ in range(width)]


def worst_difference(alone: list, lanes: list) -> float:
    """The largest relative difference of any metric but the position error between the runs."""
    worst = 0.0
    for a, b in zip(alone, lanes):
        for name, want in a.metrics.items():
            got = b.metrics[name]
            if name != "position_error_m" and not (math.isnan(want) and math.isnan(got)):
                worst = max(worst, abs(got - want) / abs(want) if want else abs(got))
    return worst


def measure(scene, rounds: int, floor: dict) -> dict:
    """ms per run of every variant, by carts (in turns, thread CPU), with ``floor`` (sweep_floor.build's
    libraries, or none): the run's steps alone, in the kernel and in C."""
    from mta_sim_ros.run.batch import run_metrics, run_trace
    from mta_sim_ros.run.lanes_batch import run_metrics_many, run_traces

    from .sweep_floor import variants as floor_variants

    figures: dict = {}
    for n in CARTS:
        batch = schemes(scene, n, max(WIDTHS))
        few = batch[:ALONE]
        run_metrics_many(batch[:2], fidelity="dynamic")  # compile (or load) before timing
        diff = worst_difference([run_metrics(s, fidelity="dynamic") for s in few],
                                run_metrics_many(few, fidelity="dynamic"))
        variants = {"alone": lambda: [run_metrics(s, fidelity="dynamic") for s in few],
                    "kernel alone": lambda: [run_trace(s, fidelity="dynamic", step=0.02) for s in few]}
        for w in WIDTHS:
            variants[f"lanes {w}"] = lambda w=w: run_metrics_many(batch[:w], fidelity="dynamic")
            variants[f"kernel lanes {w}"] = lambda w=w: run_traces(batch[:w], fidelity="dynamic", step=0.02)
        steps, checks = floor_variants(floor, batch, ALONE, WIDTHS)
        variants.update({label: call for label, (call, _) in steps.items()})
        times = side_by_side(variants, rounds, clock=time.thread_time)
        per_run = {label: statistics.median(t) * 1e3 / (ALONE if "alone" in label else int(label.split()[-1]))
                   for label, t in times.items()}
        figures[n] = {"ms": per_run, "worst_relative_difference": diff, "floor_checks": checks}
        print(n, {k: round(v, 2) for k, v in per_run.items()}, f"worst {diff:.1e}", flush=True)
    figures["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    figures["memory"] = {f"{n} {w}": measure_memory(n, w) for n in CARTS for w in MEMORY_WIDTHS}
    return figures


def measure_memory(n: int, width: int) -> dict:
    """``worker_memory(n, width)`` in a fresh process: {"before": MB, "peak": MB}."""
    import subprocess
    import sys

    code = f"from benchmarks.throughput.sweep_lanes import worker_memory; worker_memory({n}, {width})"
    done = subprocess.run([sys.executable, "-c", code], cwd=Path(__file__).resolve().parents[2], check=True,
                          capture_output=True, text=True)
    figures = json.loads(done.stdout.strip().splitlines()[-1])
    print(f"memory {n} carts, {width} runs: {figures}", flush=True)
    return figures


def worker_memory(n: int, width: int) -> None:
    """What a sweep worker holds for a task of ``width`` headland runs of n carts: its resident memory
    (MB) once the kernels are loaded (two runs done) and its peak after the task, printed as JSON."""
    from mta_sim_ros.config import resolve_config_path
    from mta_sim_ros.physics.loader import load_scene
    from mta_sim_ros.run.lanes_batch import run_metrics_many

    batch = schemes(load_scene(resolve_config_path(SCENE)), n, width)
    run_metrics_many(batch[:2], fidelity="dynamic")
    before = resident("VmRSS")
    run_metrics_many(batch, fidelity="dynamic")
    print(json.dumps({"before": before, "peak": resident("VmHWM")}))


def resident(field: str) -> float:
    """This process's resident memory (``VmRSS``) or its peak (``VmHWM``), MB, from /proc/self/status.
    Not getrusage's ru_maxrss: Linux keeps that across fork and exec, so a child started by a big
    process reports its parent's peak."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) / 1024
    raise OSError(f"/proc/self/status has no {field}")


def report(figures: dict) -> list[str]:
    rows = []
    for n in CARTS:
        ms = figures[n]["ms"]
        rows.append([n, "sweep's run", f"{ms['alone']:.2f}", *(
            f"{ms[f'lanes {w}']:.2f} ({ms['alone'] / ms[f'lanes {w}']:.2f}x)" for w in WIDTHS),
            f"{figures[n]['worst_relative_difference']:.1e}"])
        rows.append([n, "kernel's run", f"{ms['kernel alone']:.2f}", *(
            f"{ms[f'kernel lanes {w}']:.2f} ({ms['kernel alone'] / ms[f'kernel lanes {w}']:.2f}x)" for w in WIDTHS),
            ""])
    lines = ["", "## ms per run, alone and across lanes", "",
             "A sweep's run: the step search, the run, its companion at half the step and the metrics. The "
             "kernel's run: the run alone at 0.02 s, its trace and nothing else. Each row's figures taken in "
             "turns; the ratio is alone over lanes.", ""]
    lines += table(rows, ["carts", "what", "alone", *(f"{w} lanes" for w in WIDTHS),
                          "largest metric difference"], "rllllr")
    best = {n: 1e3 / min(figures[n]["ms"][f"lanes {w}"] for w in WIDTHS) for n in CARTS}
    lines += ["", "Runs per second per core at the best width: " +
              ", ".join(f"{best[n]:.0f} ({n} carts)" for n in CARTS) +
              f". Peak memory of this process (every variant, the runs alone included): "
              f"{figures['peak_rss_mb']:.0f} MB.", ""]
    memory = figures["memory"]
    lines += ["## A sweep worker's memory", "",
              "A fresh process runs a task of so many headland runs through `run_metrics_many` (what a sweep "
              "worker does with a task of `batch:` runs): its resident memory once the kernels are loaded, and "
              "its peak (MB).", ""]
    lines += table([[n, *(f"{memory[f'{n} {w}']['before']:.0f} / {memory[f'{n} {w}']['peak']:.0f}"
                          for w in MEMORY_WIDTHS)] for n in CARTS],
                   ["carts", *(f"{w} runs: before / peak" for w in MEMORY_WIDTHS)], "r" + "r" * len(MEMORY_WIDTHS))
    lines += [""]
    return lines


def chart(figures: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for n in CARTS:
        ms = figures[n]["ms"]
        line, = ax.plot(WIDTHS, [1e3 / ms[f"lanes {w}"] for w in WIDTHS], "o-", label=f"{n} carts, lanes")
        ax.axhline(1e3 / ms["alone"], color=line.get_color(), ls=":", label=f"{n} carts, alone")
        if "C lanes 8" in ms:  # the floor under a sweep's run: its three runs' steps in C across lanes
            ax.plot(WIDTHS, [1e3 / (3 * ms[f"C lanes {w}"]) for w in WIDTHS], "s--", color=line.get_color(), lw=0.8,
                    label=f"{n} carts, C floor (3 runs' steps)")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("schemes in the batch (lanes)")
    ax.set_ylabel("sweep runs / s / core")
    ax.set_title("headland turn, 70 s: a sweep's run")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(args) -> int:
    from mta_sim_ros.config import resolve_config_path
    from mta_sim_ros.physics.loader import load_scene

    import tempfile

    from .sweep_floor import build
    from .sweep_floor import report as floor_report

    scene = load_scene(resolve_config_path(SCENE))
    with tempfile.TemporaryDirectory() as tmp:
        floor, how = build(Path(tmp))
        figures = measure(scene, args.rounds, floor)
    figures["floor_built"] = how
    lines = header_lines("Sweeps across SIMD lanes: a run's cost by batch width and carts", args) + report(figures)
    lines += floor_report(figures, CARTS, WIDTHS)
    lines += [f"![runs/s/core against the batch's width]({Path(args.out).with_suffix('.png').name})", ""]
    write_report(args.out, lines)
    Path(args.out).with_suffix(".json").write_text(json.dumps({str(k): v for k, v in figures.items()}, indent=1) + "\n")
    chart(figures, Path(args.out).with_suffix(".png"))
    return 0
