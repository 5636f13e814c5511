"""``python -m benchmarks work-precision``: every integrator over a sweep of steps (every fixed method, each a
tableau of ``integrate.tableau.TABLEAUX``) or tolerances (RK45, DOP853, LSODA, Radau, BDF) on six
scenes, in two modes:

node  restarted every tick with the command held, exactly as the node runs: ``Simulation.advance``
      (``runs.py``), kinks split. Every fixed method runs twice: the kernel (model/kernel.py) run as
      plain Python (``Simulation(compiled=False)``, the method's name) and the same source compiled
      by numba (``Simulation(compiled=True)``, "<method> compiled"), when numba runs; the adaptive
      ones on the kernel as plain Python.
free  one integration from 0 to T with the inputs applied continuously, no hold: the fixed
      steppers straight through, the adaptive ones as ``scipy.integrate.solve_ivp``. Its inputs
      vary inside a step, so no branch is held and no kink split.

The peer, what a user would otherwise write, is ``solve_ivp(method="RK45")`` on the same model: per
tick with the held command in node mode, one call in free mode. Errors (``runs.py``) against DOP853
at rtol = atol = 1e-13 under the same inputs (cross-checked by Radau at 1e-12); cost as CPU seconds
per simulated second (process time, minimum over repeats, the configurations taking turns in each
repeat) and RHS evaluations.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from mta_sim_ros.validate import COUNT, PUBLISH_RATE, number_arg, output_folder, path_arg

from ..common import BENCHMARKS, REPO, header_lines, log, side_by_side

HELP = "error vs CPU time of every integrator on six scenes, node and free mode"
ADAPTIVE = ("RK45", "DOP853", "LSODA", "Radau", "BDF")
COMPILED = " compiled"  # suffix of the fixed methods run compiled (Simulation(compiled=True))
PEER = "solve_ivp RK45"
TOLERANCE = "rk4 asking 1e-6 m"  # the default: the step its tolerance chose, and its companion at half of it
REF_TOL = 1e-13
CHECK_TOL = 1e-12
TARGET = 1e-6  # m, the equal-error point of the speed-up target
CHEAP = 0.1  # CPU s per simulated s: runs cheaper than this are timed --repeats times, the others once
#: fixed steps tick / k swept, by the method's order (full, --quick)
SUBSTEPS = {1: ((1, 4, 16, 64), (1, 8)), 2: ((1, 2, 4, 8, 16), (1, 4)), 3: ((1, 2, 4, 8, 16), (1, 4)),
            4: ((1, 2, 4, 8), (1, 4))}


def add_arguments(p) -> None:
    p.add_argument("--quick", action="store_true", help="fewer steps and tolerances, one repeat: a smoke run")
    p.add_argument("--repeats", type=number_arg(COUNT, int), default=2,
                   help=f"timed repeats of the runs cheaper than {CHEAP:g} CPU s/s, minimum taken (default 2)")
    p.add_argument("--rate", type=number_arg(PUBLISH_RATE), default=100.0, help="tick rate, Hz (default 100, the node's)")
    p.add_argument("--scenes", nargs="*", help="only scenes whose file contains one of these words")
    p.add_argument("--out-dir", type=path_arg(output_folder), default=str(REPO / BENCHMARKS), help="where to write the .md and .png")


def fixed_methods() -> tuple[str, ...]:
    from mta_sim_ros.integrate.tableau import TABLEAUX

    return tuple(TABLEAUX)


def crossing(costs, errors, target):
    """The cost at which a work-precision curve reaches ``target`` error: log-log interpolation
    between the two measured points that bracket it (the curve sorted by cost); None if it does not."""
    pts = sorted((c, e) for c, e in zip(costs, errors) if math.isfinite(c) and math.isfinite(e) and e > 0)
    if pts and pts[0][1] <= target:
        return pts[0][0]
    for (c0, e0), (c1, e1) in zip(pts, pts[1:]):
        if e0 > target >= e1:
            w = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(c0) + w * (math.log(c1) - math.log(c0)))
    return None


def configurations(quick: bool, tick: float):
    """(method, step, rtol, atol) to sweep, and the tolerances. Fixed steps: tick / k;
    tolerances rtol, atol = rtol / 100 (the implicit ones, costly and far from the front, not the tightest)."""
    from mta_sim_ros.integrate.tableau import TABLEAUX

    tols = (1e-4, 1e-8) if quick else (1e-3, 1e-5, 1e-7, 1e-9)
    out = [(m, tick / k, 0.0, 0.0) for m, tab in TABLEAUX.items() for k in SUBSTEPS[tab.order][quick]]
    for m in ADAPTIVE:
        out += [(m, tick, r, r / 100) for r in (tols[:-1] if m in ("Radau", "BDF") and not quick else tols)]
    return out, tols


def peer_run(case, rtol, atol):
    """solve_ivp(RK45) once per tick with the held command: what a user would write for the node."""
    from scipy.integrate import solve_ivp

    from ..runs import Run

    model = case.model
    Y = np.empty((case.ticks + 1, len(case.y0)))
    Y[0] = y = case.y0
    nfev = 0
    c0 = time.process_time()
    for i, (c, v) in enumerate(case.held):
        sol = solve_ivp(lambda t, yy: model.rhs(t, yy, c, v), (i * case.tick, (i + 1) * case.tick), y,
                        method="RK45", rtol=rtol, atol=atol)
        y = Y[i + 1] = sol.y[:, -1]
        nfev += sol.nfev
    return Run(Y, time.process_time() - c0, nfev, "", None)


def free_run(case, method, step, rtol, atol):
    """One integration over the scene with its inputs continuous: a fixed stepper straight through
    (``reference`` True: DOP853 stepped the same way), an adaptive method as solve_ivp."""
    from scipy.integrate import solve_ivp

    from mta_sim_ros.integrate import FIXED_METHODS, make_stepper
    from mta_sim_ros.run.simulation import speed_setpoint, table_value

    from ..runs import Run

    model, scene = case.model, case.scene

    def f(t, y):
        return model.rhs(t, y, table_value(scene.steering, t), speed_setpoint(scene, t))

    instants = np.arange(case.ticks + 1) * case.tick
    c0 = time.process_time()
    if method in FIXED_METHODS or method == "DOP853-ref":
        stepper = make_stepper("DOP853" if method == "DOP853-ref" else method, step, rtol, atol)
        Y = np.empty((case.ticks + 1, len(case.y0)))
        Y[0] = y = case.y0
        for i in range(case.ticks):  # a fixed stepper keeps no state: the same as one pass
            y = Y[i + 1] = stepper.advance(f, instants[i], y, instants[i + 1])
        nfev = stepper.nfev
    else:
        sol = solve_ivp(f, (0.0, instants[-1]), case.y0, method=method, t_eval=instants, rtol=rtol, atol=atol)
        nfev = sol.nfev
        ok = sol.success and sol.y.shape[1] == len(instants)
        Y = sol.y.T if ok else np.full((len(instants), len(case.y0)), np.nan)
    return Run(Y, time.process_time() - c0, nfev, "", None)


def measure(case, quick: bool, repeats: int, compiled: bool) -> tuple[list[dict], dict | None]:
    """Every configuration of one scene in both modes: rows of errors and costs; the reference
    cross-check (None with ``quick``)."""
    from mta_sim_ros.run.simulation import speed_setpoint, table_value

    tick, seconds = case.tick, case.ticks * case.tick
    ref_node = case.reference(REF_TOL)
    ref_free = free_run(case, "DOP853-ref", tick, REF_TOL, REF_TOL)
    if ref_node.stop:
        log(f"  reference stopped: {ref_node.stop}")
        return [], None
    check = None if quick else case.errors(case.reference(CHECK_TOL, "Radau").states, ref_node.states, case.held_at)
    if check:
        log(f"  Radau {CHECK_TOL:g} vs DOP853 {REF_TOL:g} (node mode): E_pos {check['pos']:.2e} m, "
            f"E_head {check['head']:.2e} rad, E_power {check['power']:.2e}")
    confs, tols = configurations(quick, tick)
    fixed = fixed_methods()
    runners = {("node", m, h, r): (lambda m=m, h=h, r=r, a=a: case.run(method=m, step=h, rtol=r or None, atol=a or None,
                                                                       compiled=False))
               for m, h, r, a in confs}
    runners.update({("node", PEER, tick, r): (lambda r=r: peer_run(case, r, r / 100)) for r in tols})
    if compiled:
        runners.update({("node", m + COMPILED, h, r): (lambda m=m, h=h: case.run(method=m, step=h, compiled=True))
                        for m, h, r, a in confs if m in fixed})
        chosen = tolerance_step(case)
        runners[("node", TOLERANCE, chosen, 0.0)] = lambda: tolerance_run(case, chosen)
    runners.update({("free", PEER if m == "RK45" else m, h, r): (lambda m=m, h=h, r=r, a=a: free_run(case, m, h, r, a))
                    for m, h, r, a in confs})
    continuous = lambda i: (table_value(case.scene.steering, i * tick), speed_setpoint(case.scene, i * tick))  # noqa: E731
    rows = {}
    for key, runner in runners.items():
        mode, method, step, rtol = key
        run = runner()
        ref, inputs = (ref_node, case.held_at) if mode == "node" else (ref_free, continuous)
        err = case.errors(run.states, ref.states, inputs) if not run.stop else \
            dict(pos=math.inf, final=math.inf, head=math.inf, power=math.inf)
        rows[key] = dict(mode=mode, method=method, step=step, rtol=rtol, cpu=[run.cpu / seconds],
                         nfev=run.nfev / seconds, stop=run.stop, **err)
    cheap = {key: (lambda runner=runner: runner().cpu / seconds) for key, runner in runners.items()
             if not rows[key]["stop"] and rows[key]["cpu"][0] <= CHEAP}
    for key, times in side_by_side(cheap, repeats - 1, clock=None).items():
        rows[key]["cpu"] += times
    for row in rows.values():
        row["cpu_min"] = min(row["cpu"])
    return list(rows.values()), check


def tolerance_step(case) -> float:
    """The step the scene takes when it asks for TARGET (run.accuracy.chosen_step), at the case's tick."""
    import dataclasses

    from mta_sim_ros.run.accuracy import chosen_step

    integrator = dataclasses.replace(case.scene.integrator, step=None, tolerance=TARGET)
    return chosen_step(dataclasses.replace(case.scene, integrator=integrator), rate=case.rate, fidelity="dynamic")


def tolerance_run(case, step: float):
    """The run at ``step`` compiled, with the cost of its companion at half the step (the run's error
    estimate, run/accuracy.py) added: what a run asking for a tolerance pays."""
    run = case.run(method="rk4", step=step, compiled=True)
    companion = case.run(method="rk4", step=step / 2, compiled=True, keep=False)
    run.cpu += companion.cpu
    run.nfev += companion.nfev
    return run


def main(args) -> int:
    from mta_sim_ros import jit

    from ..runs import cases

    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    repeats = 1 if args.quick else args.repeats
    jit_note = jit.NOTE if jit.ENABLED else None
    log(f"compiled kernels: {jit_note or 'not available (numba not importable): the kernel as plain Python only'}")
    results, refdiff = {}, {}
    t_start = time.perf_counter()
    for case in cases(args.scenes, args.rate):
        log(f"[{time.perf_counter() - t_start:6.0f} s] {case.label}: {case.ticks} ticks")
        rows, check = measure(case, args.quick, repeats, bool(jit_note))
        if rows:
            results[case.label] = rows
        if check:
            refdiff[case.label] = check
    if not results:
        return 1
    summary = summarize(results, bool(jit_note))
    figs = {mode: figure(results, mode, out_dir, "rk4" + COMPILED if jit_note else "rk4") for mode in ("node", "free")}
    lines = header_lines("Benchmark: work-precision of the integrators", args)
    lines += report(args, results, refdiff, summary, figs, jit_note, repeats)
    (out_dir / "work_precision.md").write_text("\n".join(lines) + "\n")
    log(f"[{time.perf_counter() - t_start:6.0f} s] wrote {out_dir / 'work_precision.md'} and {', '.join(figs.values())}")
    for label, s in summary.items():
        d = s["default"]
        print(f"{label}: default {s['default_method']} 0.01 s E_pos {d['pos'] if d else math.nan:.2e} m, "
              f"CPU {d['cpu_min'] * 100 if d else math.nan:.2f} % of the tick, on front {s['on_front']}; "
              f"best at 1e-6 m: {s['best']} {s['best_cost']:.3g} s/s; solve_ivp RK45 per tick {s['peer']}, "
              f"free {s['free_peer']}; best Python {s['best_py']} {s['best_py_cost']:.3g} s/s")
    return 0


def summarize(results: dict, compiled: bool) -> dict:
    """Per scene: the node default's row, whether it is on the front, the cheapest method (and
    the cheapest on the Python kernel) at TARGET error, the peer's cost there."""
    fixed = fixed_methods()
    methods = fixed + tuple(m + COMPILED for m in fixed) + ADAPTIVE
    default_method = "rk4" + COMPILED if compiled else "rk4"
    summary = {}
    for label, rows in results.items():
        node = [r for r in rows if r["mode"] == "node"]

        def cost(method, mode_rows=node):
            rs = [r for r in mode_rows if r["method"] == method]
            return crossing([r["cpu_min"] for r in rs], [r["pos"] for r in rs], TARGET)

        costs = {m: c for m in methods if (c := cost(m)) is not None}
        python = {m: c for m, c in costs.items() if not m.endswith(COMPILED)}
        best = min(costs, key=costs.get, default=None)
        best_py = min(python, key=python.get, default=None)
        d = next((r for r in node if r["method"] == default_method and abs(r["step"] - 0.01) < 1e-12), None)
        on_front = None if d is None else not any(r is not d and r["cpu_min"] < d["cpu_min"] and r["pos"] < d["pos"]
                                                  for r in node)
        summary[label] = dict(default=d, default_method=default_method, on_front=on_front, best=best,
                              best_cost=costs.get(best, math.inf), best_py=best_py,
                              best_py_cost=python.get(best_py, math.inf),
                              peer=cost(PEER), free_peer=cost(PEER, [r for r in rows if r["mode"] == "free"]),
                              asking=next((r for r in node if r["method"] == TOLERANCE), None))
    return summary


def figure(results: dict, mode: str, out_dir: Path, default_method: str) -> str:
    """One panel per scene of E_pos against CPU s per simulated s, in one mode; the PNG's name."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fixed = fixed_methods()
    colors = dict(zip(fixed + ADAPTIVE, plt.get_cmap("tab20").colors[::2] + plt.get_cmap("tab20").colors[1::2]))
    n = len(results)
    cols = 2 if n > 1 else 1
    rows_n = (n + cols - 1) // cols
    height = 3.6 * rows_n + 1.4  # + the legend's rows
    fig, axes = plt.subplots(rows_n, cols, figsize=(10, height), squeeze=False)
    for ax, (label, rows) in zip(axes.flat, results.items()):
        for method in fixed + tuple(m + COMPILED for m in fixed) + ADAPTIVE + (PEER,):
            pts = sorted((r["cpu_min"], max(r["pos"], 1e-16)) for r in rows
                         if r["mode"] == mode and r["method"] == method and math.isfinite(r["pos"]))
            if not pts:
                continue
            style = dict(color=colors.get(method.removesuffix(COMPILED), "black"), ms=3.5, lw=1.3,
                         marker="o" if method in fixed else "s")
            if method.endswith(COMPILED):
                style.update(marker="^", ms=5, lw=2.2, ls="-.")
            if method == PEER:
                style.update(lw=2.2, ls="--", marker="D")
            ax.loglog(*zip(*pts), label=method, **style)
        default = [r for r in rows if r["mode"] == mode and r["method"] == default_method and abs(r["step"] - 0.01) < 1e-12]
        if mode == "node" and default:
            ax.loglog([default[0]["cpu_min"]], [max(default[0]["pos"], 1e-16)], "*", color="silver", ms=13, mec="k",
                      zorder=5, label=f"{default_method}, 0.01 s (the default before)")
        asking = [r for r in rows if r["mode"] == mode and r["method"] == TOLERANCE]
        if asking:
            ax.loglog([asking[0]["cpu_min"]], [max(asking[0]["pos"], 1e-16)], "*", color="gold", ms=16, mec="k",
                      zorder=6, label="the default: asking 1e-6 m (step chosen, + companion)")
        ax.axhline(1e-3, color="gray", lw=0.8, ls=":")
        ax.axhline(TARGET, color="gray", lw=0.8, ls="-.")
        ax.set_title(label, fontsize=10)
        ax.set_xlabel("CPU s per simulated s")
        ax.set_ylabel("largest hitch position error E_pos (m)")
        ax.grid(True, which="major", alpha=0.3)
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=6, fontsize=8.5, frameon=False)
    fig.suptitle(("Node mode: restarted every tick, command held, kinks split" if mode == "node" else
                  "Free mode: one integration, inputs continuous") + " (dotted 1 mm, dash-dot 1e-6 m)", fontsize=11)
    fig.tight_layout(rect=(0, 1.4 / height, 1, 0.97))
    name = f"work_precision_{mode}.png"
    fig.savefig(out_dir / name, dpi=80)
    plt.close(fig)
    return name


def report(args, results, refdiff, summary, figs, jit_note, repeats) -> list[str]:
    lines = setup(args, results, bool(refdiff), figs, jit_note, repeats)
    if refdiff:
        lines += [f"## Reference cross-check (Radau {CHECK_TOL:g} against DOP853 {REF_TOL:g}, node mode)", "",
                  "| scene | E_pos (m) | E_final (m) | E_head (rad) | E_power |", "|---|---:|---:|---:|---:|"]
        lines += [f"| {lab} | {d['pos']:.2e} | {d['final']:.2e} | {d['head']:.2e} | {d['power']:.2e} |"
                  for lab, d in refdiff.items()]
        lines.append("")
    return lines + headline(summary, "rk4" + COMPILED if jit_note else "rk4") + all_runs(results)


def setup(args, results, cross_checked: bool, figs, jit_note, repeats) -> list[str]:
    """What was run and how it was measured."""
    from ..runs import SCENES

    fixed = fixed_methods()
    tick = 1.0 / args.rate
    lines = ["## Setup", "", f"- ticks of {1e3 * tick:g} ms ({args.rate:g} Hz); scenes:"]
    lines += [f"  - **{lab}**: `config/{p}` ({w})" for lab, p, w in SCENES if lab in results]
    lines += [
        "- node mode: `Simulation.advance` tick by tick with the scene's command held over each tick (the node's "
        "zero-order hold), the dynamic level, kinks split (the default); adaptive methods restarted every tick "
        "and at every kink with largest step = the tick. Free mode: the same model with the input tables applied "
        "continuously (no hold, no kink split), one integration over the scene; the fixed steppers straight "
        "through, the adaptive ones as `scipy.integrate.solve_ivp(method, t_eval=publish instants)`.",
        f"- fixed methods: every tableau of `integrate.tableau.TABLEAUX` ({', '.join(fixed)}). In node mode on the "
        "kernel run as plain Python (the method's name: `Simulation(compiled=False)`) and "
        + (f"the same kernel source compiled (`<method> compiled`: `Simulation(compiled=True)`, {jit_note}); free "
           "mode: Python only." if jit_note else "not compiled (numba not importable here)."),
        "- peer: `scipy.integrate.solve_ivp(method='RK45')` on the same `Model.rhs`; node mode: one call per tick "
        "with the held command; free mode: one call (which is the free RK45 curve).",
        f"- reference: DOP853 at rtol = atol = {REF_TOL:g} under the same inputs (node mode: kinks split); "
        + (f"cross-check: Radau at rtol = atol = {CHECK_TOL:g} (node mode). Their difference bounds what any error "
           "below it means." if cross_checked else "no cross-check (--quick)."),
        "- sweeps: fixed steps tick / k (k by the method's order); tolerances rtol with atol = rtol / 100.",
        f"- cost: CPU time (`time.process_time`) per simulated second, minimum of {repeats} repeats for the runs "
        f"cheaper than {CHEAP:g} CPU s/s (one run for the costlier ones), the configurations taking turns in each "
        "repeat; RHS evaluations per simulated second.",
        "- errors: `E_pos`, `E_final`, `E_head`, `E_power` as defined in `benchmarks/runs.py` "
        "(hitch points A_1 .. A_n and the rear hitch; headings; traction power N = F_A1 V, relative).",
        "", f"![work-precision, node mode]({figs['node']})", "", f"![work-precision, free mode]({figs['free']})", ""]
    return lines


def number(x, f="{:.3g}") -> str:
    return "n/a" if x is None or not math.isfinite(x) else f.format(x)


def ratio(a, b) -> str:
    return number(a / b if a and b and math.isfinite(b) else None, "x{:.1f}")


def headline(summary, default_method: str) -> list[str]:
    """Per scene: the node's default against the best method and the peer at the target error."""
    lines = ["## Headline", "",
             f"| scene | node default {default_method} 0.01 s: E_pos (m) | its CPU share of the tick | on the front | "
             "best method at E_pos = 1e-6 m | its CPU s/s | solve_ivp RK45 per tick at 1e-6 m | ratio | "
             "best Python method at 1e-6 m | its CPU s/s | ratio | solve_ivp RK45 free at 1e-6 m | ratio |",
             "|---|---:|---:|:---:|---|---:|---:|---:|---|---:|---:|---:|---:|"]
    for label, s in summary.items():
        d = s["default"]
        lines.append(
            f"| {label} | {number(d and d['pos'], '{:.2e}')} | {number(d and d['cpu_min'] * 100, '{:.2f} %')} | "
            f"{'yes' if s['on_front'] else 'no' if s['on_front'] is not None else 'n/a'} | {s['best'] or 'none'} | "
            f"{number(s['best_cost'])} | {number(s['peer'])} | {ratio(s['peer'], s['best_cost'])} | "
            f"{s['best_py'] or 'none'} | {number(s['best_py_cost'])} | {ratio(s['peer'], s['best_py_cost'])} | "
            f"{number(s['free_peer'])} | {ratio(s['free_peer'], s['best_cost'])} |")
    lines += ["", "CPU s/s = CPU seconds per simulated second; CPU share of the tick = CPU s/s x 100 % (the "
              "integration alone, not the node's messages). Costs at 1e-6 m are log-log interpolated between the two "
              "measured points of a curve that bracket it. 'on the front': no other configuration of node mode is "
              "both cheaper and more accurate. 'Python method': the fixed methods on the kernel run as plain Python "
              "(`Simulation(compiled=False)`) and the scipy solvers.", ""]
    lines += asking_table(summary)
    ratios = [s["peer"] / s["best_cost"] for s in summary.values() if s["peer"] and s["best"]]
    if ratios:
        lines += ["## Reading it", "",
                  f"- Against `solve_ivp(RK45)` called once per tick with the held command (the same problem, the same "
                  f"reference) the best method is x{min(ratios):.1f} to x{max(ratios):.1f} faster at 1e-6 m; the "
                  "issue's target is x20 " + ("(met on every scene measured)." if min(ratios) >= 20.0 else
                                              "(not met on every scene measured)."), ""]
    return lines


def asking_table(summary) -> list[str]:
    """Per scene: the default (rk4 asking 1e-6 m: the step chosen, the companion's cost added) against
    rk4 at a fixed 10 ms without an estimate, the default before."""
    rows = [(label, s["asking"], s["default"]) for label, s in summary.items() if s["asking"] and s["default"]]
    if not rows:
        return []
    lines = ["## The default asks for 1e-6 m", "",
             "| scene | step chosen (s) | E_pos (m) | CPU s/s with its companion | rk4 0.01 s: E_pos (m) | its CPU s/s | "
             "cost ratio |", "|---|---:|---:|---:|---:|---:|---:|"]
    lines += [f"| {label} | {a['step']:.4g} | {a['pos']:.2e} | {a['cpu_min']:.4f} | {d['pos']:.2e} | "
              f"{d['cpu_min']:.4f} | {ratio(a['cpu_min'], d['cpu_min'])} |" for label, a, d in rows]
    return lines + ["", "The default's cost holds its companion run at half the step (its error estimate, "
                    "docs/accuracy.md); the step is the one `run.accuracy.settle` chooses on the scene's own inputs.",
                    ""]


def all_runs(results) -> list[str]:
    """Every run of both modes, a row each."""
    fixed = fixed_methods()
    lines = []
    for mode in ("node", "free"):
        lines += [f"## All runs, {mode} mode", "",
                  "| scene | method | step (s) / rtol | E_pos (m) | E_final (m) | E_head (rad) | E_power | CPU s/s (min) | RHS / sim s |",
                  "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
        for label, rows in results.items():
            for r in (r for r in rows if r["mode"] == mode):
                par = f"h = {r['step']:.4g}" if r["method"].removesuffix(COMPILED) in fixed else f"rtol = {r['rtol']:.0e}"
                if r["stop"]:
                    lines.append(f"| {label} | {r['method']} | {par} | stopped: {r['stop']} | | | | | |")
                else:
                    lines.append(f"| {label} | {r['method']} | {par} | {r['pos']:.2e} | {r['final']:.2e} | "
                                 f"{r['head']:.2e} | {r['power']:.2e} | {r['cpu_min']:.4f} | {r['nfev']:.0f} |")
        lines.append("")
    return lines
