"""``python -m benchmarks kinks``: every method across the right-hand side's kinks, stepping across them and
splitting at them, against a reference that splits; and the default method on every shipped scene.

The kinks (docs/model.md, "Kinks"): the steering actuator's rate limit letting go, the governor
meeting or leaving its force limit, its power limit and that limit's speed floor, a draft's |S| at
S = 0. ``kinks.yaml`` (a 4 t tractor, a 20 t cart, steering steps whose rate limit lets go inside a
step, speed steps through the governor's limits) puts many of them inside the node's 10 ms ticks.

Runs are node-mode (``runs.py``: ``Simulation.advance`` tick by tick with the scene's held inputs,
the dynamic level); the error is the largest distance of any hitch point over the publish instants
from a DOP853 run at rtol = atol = 1e-12 that splits at the kinks (cross-checked by Radau at 1e-12,
also split). Fixed methods (every tableau) at the scene's step and at half of it (the observed
order is log2 of the ratio); adaptive ones at rtol = atol = 1e-8 with their largest step the tick.
"""
from __future__ import annotations

import math
import time

from mta_sim_ros.validate import output_file, path_arg

from ..common import BENCHMARKS, REPO, header_lines, resolve_scene, table, write_report

HELP = "every method across the kinks of the right-hand side, split and not"
REF_TOL = 1e-12
ADAPTIVE_TOL = 1e-8
TARGET = 1e-6  # m: the default method against the reference


def add_arguments(p) -> None:
    p.add_argument("--scene", default="scenes/kinks.yaml", help="the kink scene (default scenes/kinks.yaml)")
    p.add_argument("--out", type=path_arg(output_file), default=str(REPO / BENCHMARKS / "kinks.md"), help="Markdown report to write")


def kink_table(case) -> list[str]:
    from mta_sim_ros.integrate.steppers import ADAPTIVE_METHODS
    from mta_sim_ros.integrate.tableau import TABLEAUX

    ref = case.reference(REF_TOL)
    radau = case.distance(case.reference(REF_TOL, method="Radau"), ref)
    across = case.distance(case.run(method="DOP853", step=case.tick, rtol=REF_TOL, atol=REF_TOL,
                                    split_kinks=False), ref)
    step = case.scene.integrator.step
    fixed, adaptive = [], []
    for method, tableau in TABLEAUX.items():
        cells = []
        for split in (False, True):
            runs = [case.run(method=method, step=h, split_kinks=split) for h in (step, step / 2)]
            e = [case.distance(r, ref) for r in runs]
            cells.append((e, runs[0].nfev / case.ticks))
        (ea, na), (es, ns) = cells
        fixed.append([method, tableau.order, f"{ea[0]:.2e}", f"{ea[1]:.2e}", f"{math.log2(ea[0] / ea[1]):.2f}",
                      f"{es[0]:.2e}", f"{es[1]:.2e}", f"{math.log2(es[0] / es[1]):.2f}", f"{na:.2f} / {ns:.2f}"])
        print(*fixed[-1], flush=True)
    for method in ADAPTIVE_METHODS:
        a, s = (case.run(method=method, step=case.tick, rtol=ADAPTIVE_TOL, atol=ADAPTIVE_TOL, split_kinks=split)
                for split in (False, True))
        adaptive.append([method, f"{case.distance(a, ref):.2e}", f"{case.distance(s, ref):.2e}",
                         f"{a.nfev / case.ticks:.1f} / {s.nfev / case.ticks:.1f}"])
        print(*adaptive[-1], flush=True)
    return [f"Reference: DOP853 at rtol = atol = {REF_TOL:g}, split at {ref.sim.kinks} kinks; Radau at the same "
            f"tolerance, also split, agrees to {radau:.2g} m; the same DOP853 stepping across the kinks is "
            f"{across:.2g} m off it.", "",
            *table(fixed, ["method", "order", f"across: error at {step:g} s", f"at {step / 2:g} s", "observed order",
                           f"split: error at {step:g} s", f"at {step / 2:g} s", "observed order",
                           "RHS per tick, across / split"], "lr"),
            "", f"Adaptive methods at rtol = atol = {ADAPTIVE_TOL:g}, largest step the tick:", "",
            *table(adaptive, ["method", "across: error", "split: error", "RHS per tick, across / split"], "lr")]


def shipped_table() -> list[str]:
    """The default method of every shipped scene, split and across, against its split reference."""
    from mta_sim_ros.physics.loader import load_scene

    from ..runs import Case

    rows = []
    for path in sorted((REPO / "config" / "scenes").glob("*.yaml")):
        case = Case(load_scene(path))
        ref = case.reference(REF_TOL)
        a, b = case.run(split_kinks=False), case.run(split_kinks=True)
        ea, eb = case.distance(a, ref), case.distance(b, ref)
        rows.append([path.stem, ref.sim.kinks, f"{b.sim.method} {b.sim.step:g} s", f"{ea:.2e}", f"{eb:.2e}",
                     "yes" if eb < TARGET else "**no**",
                     f"{a.cpu / case.ticks * 1e6:.1f} / {b.cpu / case.ticks * 1e6:.1f} us"])
        print(*rows[-1], flush=True)
    return table(rows, ["scene", "kinks", "default", "across: error", "split: error", "within 1e-6 m",
                        "CPU per tick, across / split"], "lrlrrlr")


def main(args) -> int:
    from mta_sim_ros.physics.loader import load_scene

    from ..runs import Case

    case = Case(load_scene(resolve_scene(args.scene)))
    started = time.time()
    kinks = kink_table(case)
    shipped = shipped_table()
    lines = header_lines("Kinks: every method split at them and stepping across", args)
    lines += [__doc__.split("\n\n", 1)[1].strip(), "", f"## {case.scene.name} ({args.scene})", ""] + kinks
    lines += ["", "## The default method on every shipped scene", "",
              f"Against DOP853 at rtol = atol = {REF_TOL:g} that splits; CPU per tick of `Simulation.advance` "
              "(process time, one run each).", ""] + shipped
    lines += ["", f"Took {time.time() - started:.0f} s."]
    write_report(args.out, lines)
    return 0
