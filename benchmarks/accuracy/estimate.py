"""``python -m benchmarks estimate``: every run's stated position error against its true error, and
what a run that asks for a tolerance costs against today's fixed step.

For each shipped scene at the 10 ms step every one gave before it asked for a tolerance, and as
shipped (it asks for ``integrator.tolerance``, 1e-6 m; ``run.accuracy.settle`` picks the step), and for the
single-tractor scene and random trains of test/test_accuracy.py: the run's estimate
(``accuracy.settle``), its true error against a DOP853 run at rtol = atol = 1e-12 with kinks split
(the largest distance of any A_k, B_k or the last rear hitch), their ratio, and the wall time of
the whole-run call alone (yesterday's run: the 10 ms step, no estimate) and of ``settle`` (the run,
its companion and the step search), medians side by side. Writes a Markdown table and a chart of
the ratio.
"""
from __future__ import annotations

import statistics
import sys

from mta_sim_ros.validate import output_file, path_arg

from ..common import BENCHMARKS, REPO, header_lines, side_by_side, table, write_report

HELP = "each run's stated position error against the true one, and the cost of asking for a tolerance"


def add_arguments(p) -> None:
    p.add_argument("--rounds", type=int, default=5, help="timing rounds (median), default 5")
    p.add_argument("--out", type=path_arg(output_file), default=str(REPO / BENCHMARKS / "estimate.md"),
                   help="Markdown report to write (the chart beside it, .png)")


def cases():
    """(label, scene at a 10 ms step, the same scene asking for its tolerance) of every case."""
    from mta_sim_ros.physics.loader import load_scene

    sys.path.insert(0, str(REPO / "test"))
    import test_accuracy as ta  # the test's scenes: the same cases the estimate is tested on

    out = []
    for path in sorted((REPO / "config" / "scenes").glob("*.yaml")):
        scene = load_scene(path)  # as shipped: asking for its tolerance
        out.append((path.stem, ta.with_step(scene), scene))
    single = ta.single_tractor_scene(step=0.01)
    out.append(("single tractor (test)", single, ta.without_step(single)))
    for seed in range(len(ta.SIZES)):
        scene = ta.random_scene(seed, step=0.01)
        out.append((f"random {scene.train.n} carts (seed {seed})", scene, ta.without_step(scene)))
    return out, ta


def main(args) -> int:
    from mta_sim_ros.run import accuracy
    from mta_sim_ros.run.batch import run_trace

    rows, ratios = [], []
    found, ta = cases()
    for label, fixed, asking in found:
        for kind, scene in (("10 ms step", fixed), ("tolerance", asking)):
            run, stated = accuracy.settle(scene)
            true = ta.true_error(scene, run)
            ratio = stated.error / true if true > ta.REFERENCE else float("nan")
            ratios.append((f"{label}, {kind}", ratio))
            times = side_by_side({"run": lambda s=fixed: run_trace(s), "settle": lambda s=scene: accuracy.settle(s)},
                                 args.rounds)
            base, cost = statistics.median(times["run"]), statistics.median(times["settle"])
            rows.append([label, kind, f"{run[0].stepper_step:.4g}", f"{stated.error:.2e}", f"{true:.2e}",
                         f"{ratio:.2f}", "yes" if stated.meets else "NO", f"{base * 1e3:.1f}", f"{cost * 1e3:.1f}",
                         f"{cost / base:.1f}"])
            print(*rows[-1], flush=True)
    lines = header_lines("Each run's stated position error against its true error", args)
    lines += ["The estimate (run/accuracy.py) against the true error (DOP853 at 1e-12, split); times are "
              "medians of the whole-run call at the scene's own step (today's run, no estimate) and of "
              "`accuracy.settle` (the run, its companion at half the step, and with no step the search for "
              "the step), side by side.", "",
              *table(rows, ["scene", "step from", "step, s", "estimate, m", "true, m", "estimate / true",
                            "meets 1e-6 m", "run, ms", "settle, ms", "settle / run"], "llr")]
    out = write_report(args.out, lines)
    chart(ratios, out.with_suffix(".png"))
    return 0


def chart(ratios, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 0.25 * len(ratios) + 1.5))
    labels = [label for label, _ in ratios]
    ax.barh(range(len(ratios)), [r for _, r in ratios], color="tab:blue")
    for x, style in ((1.0, "-"), (10.0, "--")):
        ax.axvline(x, color="k", linestyle=style, linewidth=1)
    ax.set_yticks(range(len(ratios)), labels, fontsize=7)
    ax.set_xscale("log")
    ax.set_xlim(0.5, 20)
    ax.set_xlabel("stated error / true error (must lie in [1, 10])")
    ax.invert_yaxis()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"chart: {path}", flush=True)
