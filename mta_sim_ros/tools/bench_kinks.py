"""``mta bench kinks``: every method across the right-hand side's kinks, stepping across them and
splitting at them, against a reference that splits; and the default method on every shipped scene.

The kinks (docs/model.md, "Kinks"): the steering actuator's rate limit letting go, the governor
meeting or leaving its force limit, its power limit and that limit's speed floor, a draft's |S| at
S = 0. ``kinks.yaml`` (a 4 t tractor, a 20 t cart, steering steps whose rate limit lets go inside a
step, speed steps through the governor's limits) puts many of them inside the node's 10 ms ticks.

Runs are node-mode (``Simulation.advance`` tick by tick with the scene's held inputs, the dynamic
level); the error is the largest distance of any hitch point A_1..A_n, A_{n+1} over the publish
instants from a DOP853 run at rtol = atol = 1e-12 that splits at the kinks (cross-checked by
Radau at 1e-12, also split). Fixed methods at the scene's 10 ms and at 5 ms (the observed order is
log2 of the ratio); adaptive ones at rtol = atol = 1e-8 with their largest step the tick.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import time
import warnings
from pathlib import Path

import numpy as np

from ..validate import output_file, path_arg

REPO = Path(__file__).resolve().parents[2]
REF_TOL = 1e-12
ADAPTIVE_TOL = 1e-8
TARGET = 1e-6  # m: the default method against the reference


def add_kinks(sub) -> None:
    p = sub.add_parser("kinks", help="every method across the kinks of the right-hand side, split and not",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scene", default="scenes/kinks.yaml", help="the kink scene (default scenes/kinks.yaml)")
    p.add_argument("--out", type=path_arg(output_file), default=str(REPO / "docs" / "benchmarks" / "kinks.md"),
                   help="Markdown report to write")
    p.set_defaults(bench_func=main)


def with_tolerance(scene, tol):
    return dataclasses.replace(scene, integrator=dataclasses.replace(scene.integrator, rtol=tol, atol=tol))


def run(scene, **options):
    """(hitch points per tick, Simulation, CPU s) of a node-mode run on the dynamic level."""
    from ..sim import Simulation

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(scene, fidelity="dynamic", **options)
    points = []
    c0 = time.process_time()
    for _ in range(int(math.floor(scene.duration / sim.tick + 1e-9))):
        sim.advance(*sim.scheduled_inputs(sim.t))
        out = sim.outputs()
        points.append(np.vstack([out.front, out.rear_hitch[None]]))
    return np.array(points), sim, time.process_time() - c0


def distance(a, b) -> float:
    return float(np.max(np.linalg.norm(a - b, axis=2)))


def kink_table(scene) -> tuple[list[str], dict]:
    from ..integrate.steppers import ADAPTIVE_METHODS
    from ..integrate.tableau import TABLEAUX

    ref, ref_sim, _ = run(with_tolerance(scene, REF_TOL), method="DOP853", split_kinks=True)
    check, _, _ = run(with_tolerance(scene, REF_TOL), method="Radau", split_kinks=True)
    ref_across, _, _ = run(with_tolerance(scene, REF_TOL), method="DOP853", split_kinks=False)
    figures = {"kinks": ref_sim.kinks, "radau": distance(check, ref), "reference_across": distance(ref_across, ref)}
    step = scene.integrator.step
    lines = [f"Reference: DOP853 at rtol = atol = {REF_TOL:g}, split at {ref_sim.kinks} kinks; Radau at the same "
             f"tolerance, also split, agrees to {figures['radau']:.2g} m; the same DOP853 stepping across the "
             f"kinks is {figures['reference_across']:.2g} m off it.", "",
             f"| method | order | across: error at {step:g} s | at {step / 2:g} s | observed order | "
             f"split: error at {step:g} s | at {step / 2:g} s | observed order | RHS per tick, across / split |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    rows = {}
    for method, tab in TABLEAUX.items():
        e = {}
        for split in (False, True):
            runs = [run(scene, method=method, step=h, split_kinks=split) for h in (step, step / 2)]
            e[split] = [distance(p, ref) for p, _, _ in runs] + [runs[0][1].stepper.nfev / runs[0][1].ticks]
        rows[method] = e
        lines.append(f"| {method} | {tab.order} | {e[False][0]:.2e} | {e[False][1]:.2e} | "
                     f"{math.log2(e[False][0] / e[False][1]):.2f} | {e[True][0]:.2e} | {e[True][1]:.2e} | "
                     f"{math.log2(e[True][0] / e[True][1]):.2f} | {e[False][2]:.2f} / {e[True][2]:.2f} |")
        print(lines[-1], flush=True)
    lines += ["", f"Adaptive methods at rtol = atol = {ADAPTIVE_TOL:g}, largest step the tick:", "",
              "| method | across: error | split: error | RHS per tick, across / split |", "|---|---:|---:|---:|"]
    for method in ADAPTIVE_METHODS:
        e = {split: run(with_tolerance(scene, ADAPTIVE_TOL), method=method, split_kinks=split) for split in (False, True)}
        rows[method] = {split: (distance(p, ref), s.stepper.nfev / s.ticks) for split, (p, s, _) in e.items()}
        lines.append(f"| {method} | {rows[method][False][0]:.2e} | {rows[method][True][0]:.2e} | "
                     f"{rows[method][False][1]:.1f} / {rows[method][True][1]:.1f} |")
        print(lines[-1], flush=True)
    figures["rows"] = rows
    return lines, figures


def shipped_table() -> list[str]:
    """The default method of every shipped scene, split and across, against its split reference."""
    from ..model.loader import load_scene

    lines = ["| scene | kinks | default | across: error | split: error | within 1e-6 m | CPU per tick, across / split |",
             "|---|---:|---|---:|---:|---|---:|"]
    for path in sorted((REPO / "config" / "scenes").glob("*.yaml")):
        scene = load_scene(path)
        ref, ref_sim, _ = run(with_tolerance(scene, REF_TOL), method="DOP853", split_kinks=True)
        a, sim_a, cpu_a = run(scene, split_kinks=False)
        b, sim_b, cpu_b = run(scene, split_kinks=True)
        ea, eb = distance(a, ref), distance(b, ref)
        lines.append(f"| {path.stem} | {ref_sim.kinks} | {sim_b.method} {sim_b.step:g} s | {ea:.2e} | {eb:.2e} | "
                     f"{'yes' if eb < TARGET else '**no**'} | {cpu_a / sim_a.ticks * 1e6:.1f} / "
                     f"{cpu_b / sim_b.ticks * 1e6:.1f} us |")
        print(lines[-1], flush=True)
    return lines


def main(args: argparse.Namespace) -> int:
    from ..model.loader import load_scene
    from .bench import header_lines, resolve_scene

    scene = load_scene(resolve_scene(args.scene))
    started = time.time()
    kinks, _ = kink_table(scene)
    shipped = shipped_table()
    lines = header_lines("Kinks: every method split at them and stepping across", ["mta", "bench", "kinks",
                                                                                   "--scene", args.scene])
    lines += [__doc__.split("\n\n", 1)[1].strip(), "", f"## {scene.name} ({args.scene})", ""] + kinks
    lines += ["", "## The default method on every shipped scene", "",
              f"Against DOP853 at rtol = atol = {REF_TOL:g} that splits; CPU per tick of `Simulation.advance` "
              "+ `outputs` (process time, one run each).", ""] + shipped
    lines += ["", f"Took {time.time() - started:.0f} s."]
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")
    return 0
