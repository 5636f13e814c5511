"""``python -m benchmarks fidelity``: each fidelity level's error against the highest (slip) and its cost,
for every shipped scene, with the level ``auto`` picks; the slip level's convergence to the
dynamic one as the cornering stiffness grows; which integrator survives the slip level's
stiffness at low speed. Writes docs/fidelity.md. (Not node-mode runs of ``runs.py``: each level
is run by ``sim.run_scene`` and compared on its outputs.)

Errors (spec.Needs units): poses = largest distance of the same axle centre B_k or A_1 (m);
speed = largest |dV| (m/s); power = RMS of dN over the RMS of N; hitch_angles = largest |dphi|
(rad). Cost = CPU seconds per simulated second (process time, the least of ``--repeats`` runs).
"""
from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from mta_sim_ros.validate import COUNT, number_arg, output_file, path_arg

from ..common import header_lines, table, write_report

HELP = "each fidelity level's error against slip and its cost, per scene"
SCENES = "config/scenes"
OUTPUTS = ("poses", "speed", "power", "hitch_angles")


def add_arguments(p) -> None:
    p.add_argument("--scenes", default=SCENES, help=f"folder of scene YAML files (default {SCENES})")
    p.add_argument("--repeats", type=number_arg(COUNT, int), default=2, help="timed runs per scene and level (default 2)")
    p.add_argument("--out", type=path_arg(output_file), default="docs/fidelity.md", help="Markdown report to write")


def record(scene, level: str, **kw):
    from mta_sim_ros.run.simulation import run_scene

    outs = []
    started = time.process_time()
    sim, err = run_scene(scene, on_output=outs.append, fidelity=level, **kw)
    cpu = time.process_time() - started
    return {
        "stopped": f"stopped at t = {outs[-1].t:.2f} s" if err is not None else "",
        "points": np.array([np.vstack((o.front[:1], o.axle)) for o in outs]),
        "speed": np.array([o.speed for o in outs]),
        "power": np.array([o.power for o in outs]),
        "hitch": np.array([o.hitch_angle for o in outs]),
        "cpu": cpu / scene.duration,
        "method": sim.method,
        "nfev": sim.stepper.nfev,
    }


def errors(run, ref) -> dict[str, float]:
    """Errors over the time both runs cover (a run stopped by a guard is compared up to its stop)."""
    m = min(len(run["speed"]), len(ref["speed"]))
    dp = run["points"][:m] - ref["points"][:m]
    dN = run["power"][:m] - ref["power"][:m]
    return {
        "poses": float(np.max(np.hypot(dp[..., 0], dp[..., 1]))),
        "speed": float(np.max(np.abs(run["speed"][:m] - ref["speed"][:m]))),
        "power": float(np.sqrt(np.mean(dN ** 2) / np.mean(ref["power"][:m] ** 2))),
        "hitch_angles": float(np.max(np.abs(run["hitch"][:m] - ref["hitch"][:m]))) if ref["hitch"].size else 0.0,
    }


def with_stiffness(scene, factor: float):
    """The scene with every axle's cornering stiffness multiplied by ``factor``."""
    from mta_sim_ros.physics.slip import axle_stiffness

    _, rear = axle_stiffness(scene.train)
    carts = tuple(dataclasses.replace(c, cornering_stiffness=factor * float(r)) for c, r in zip(scene.train.carts, rear))
    # the tractor's front axle takes its cart's value: keep its own default ratio by scaling it too
    return dataclasses.replace(scene, train=dataclasses.replace(scene.train, carts=carts))


def slip_eigenvalues(scene, speeds) -> list[tuple[float, float]]:
    """(V, largest |lambda|) of the slip level's Jacobian (central differences) on a straight line."""
    from mta_sim_ros.physics.slip import SlipModel
    from mta_sim_ros.run.simulation import start_state

    model = SlipModel(scene.train)
    out = []
    for v in speeds:
        sc = dataclasses.replace(scene, initial=dataclasses.replace(scene.initial, speed=v, hitch_angles=()))
        y = start_state(sc, model)
        f0 = model.rhs(0.0, y, 0.0, v)
        J = np.empty((y.size, y.size))
        for i in range(y.size):
            h = 1e-6 * max(1.0, abs(y[i]))
            yp, ym = y.copy(), y.copy()
            yp[i] += h
            ym[i] -= h
            J[:, i] = (model.rhs(0.0, yp, 0.0, v) - model.rhs(0.0, ym, 0.0, v)) / (2 * h)
        out.append((v, float(np.max(np.abs(np.linalg.eigvals(J))))))
        del f0
    return out


def low_speed_survival(scene, speed: float, duration: float = 5.0):
    """Run the slip level at a low speed with each method: (method, outcome, CPU s per sim s)."""
    from mta_sim_ros.run.simulation import run_scene

    sc = dataclasses.replace(scene, duration=duration, speed=None,
                             initial=dataclasses.replace(scene.initial, speed=speed, hitch_angles=()))
    sc = dataclasses.replace(sc, train=dataclasses.replace(
        sc.train, traction=dataclasses.replace(sc.train.traction, set_speed=speed)))
    rows = []
    for method in ("rk4", "RK45", "LSODA", "BDF", "Radau"):
        started = time.process_time()
        try:
            sim, err = run_scene(sc, fidelity="slip", method=method, step=0.01)
            outcome = f"stopped: {str(err)[:60]}" if err else f"ok, V = {sim.outputs().speed:.4f} m/s"
            nfev = sim.stepper.nfev
        except Exception as exc:  # noqa: BLE001 - report whatever breaks
            outcome, nfev = f"failed: {type(exc).__name__}", 0
        rows.append((method, outcome, nfev, (time.process_time() - started) / duration))
    return rows


def compare(scene, repeats: int) -> tuple[list, list, list]:
    """(the table's rows of ``scene``: each level's errors against slip with its prediction, cost and
    the auto choice; the outputs measured above their prediction, as "scene level output"; the levels
    compared only up to a stop one run made and the other did not, "scene level": beyond it nothing
    is measured). A scene slip cannot run (a height grid) has no reference: its rows say so."""
    from mta_sim_ros.run.fidelity import LEVELS, choose, estimate

    runs = {}
    for level in LEVELS:
        best = None
        for _ in range(max(1, repeats)):
            try:
                r = record(scene, level)
            except ValueError as err:  # a level that does not take this scene
                r = {"refused": str(err).split(":")[0], "cpu": 0.0, "stopped": ""}
                break
            best = r if best is None or r["cpu"] < best["cpu"] else best
        runs[level] = best or r
    pred = estimate(scene) if scene.train.relief is None else None
    choice = choose(scene)
    needs = scene.needs.asked() if scene.needs else {}
    rows, over, unverified = [], [], []
    for level in LEVELS:
        if "refused" in runs["slip"] or "refused" in runs[level]:
            cells = ["no reference: " + runs["slip"].get("refused", "")] + [""] * 3 if level == "slip" else ["-"] * 4
            ok = False
        else:
            err = errors(runs[level], runs["slip"])
            cells = [f"{err[k]:.3g} ({pred[level][k]:.3g})" for k in OUTPUTS]
            over += [f"{scene.name} {level} {k}" for k in OUTPUTS if err[k] > pred[level][k]]
            if runs[level]["stopped"] != runs["slip"]["stopped"]:
                unverified.append(f"{scene.name} {level} (to {runs[level]['stopped'] or runs['slip']['stopped']})")
            ok = all(err[k] <= tol for k, tol in needs.items())
        stopped = runs[level]["stopped"]
        rows.append((scene.name if level == LEVELS[0] else "", level + (f" ({stopped})" if stopped else ""),
                     *cells, f"{runs[level]['cpu']:.4f}",
                     ("**auto**" if level == choice.level else "") + (" meets" if needs and ok else "")))
    print(f"{scene.name}: auto -> {choice.reason}", flush=True)
    rows.append(("", f"needs: {needs or 'not stated'}", "", "", "", "", "", f"auto: {choice.reason}"))
    return rows, over, unverified


#: generated trains on each of the two scenes
GENERATED = 4


def generated_scenes(folder: Path) -> list:
    """The headland turn and the reversing scene with random trains of 2-5 carts (their own start:
    straight hitches), ``GENERATED`` of each."""
    from mta_sim_ros.physics.loader import load_scene

    from ..common import random_train

    rng = np.random.default_rng(20261207)
    out = []
    for name in ("headland_turn", "reversing"):
        base = load_scene(str(folder / f"{name}.yaml"))
        for i in range(GENERATED):
            train = random_train(2 + i, rng)
            out.append(dataclasses.replace(base, name=f"{name} / {train.n} carts", train=train,
                                           initial=dataclasses.replace(base.initial, hitch_angles=())))
    return out


def main(args) -> int:
    from mta_sim_ros.physics.loader import load_scene
    from mta_sim_ros.physics.slip import DEFAULT_METHOD

    paths = sorted(Path(args.scenes).glob("*.yaml"))
    lines = header_lines("Fidelity levels: error against the slip level and cost", args) + [
             "Reference: the slip level (the highest) with each train's default cornering stiffness, "
             "C_alpha = 5/rad x static axle load (physics/slip.py, CORNERING_COEFFICIENT). Errors: poses = "
             "largest distance between the same axle centre (B_k or A_1), m; speed = largest |dV|, m/s; "
             "power = RMS(dN)/RMS(N); hitch = largest |dphi|, rad. Cost = CPU s per simulated s (least of "
             f"{args.repeats} runs; kinematic and dynamic with the scene's integrator, slip with "
             f"{DEFAULT_METHOD}). `pred.` = fidelity.estimate's prediction, which `auto` uses.", ""]
    rows, over, unverified = [], [], []
    for path in paths:
        scene_rows, scene_over, scene_unverified = compare(load_scene(str(path)), args.repeats)
        rows += scene_rows
        over += scene_over
        unverified += scene_unverified
    generated_rows, generated_over, generated_unverified = [], [], []
    for scene in generated_scenes(Path(args.scenes)):
        scene_rows, scene_over, scene_unverified = compare(scene, 1)
        generated_rows += scene_rows
        generated_over += scene_over
        generated_unverified += scene_unverified
    header = ("scene", "level", "poses m (pred.)", "speed m/s (pred.)", "power rel. (pred.)", "hitch rad (pred.)",
              "CPU s/s", "auto")
    lines += table(rows, header)
    lines += ["", f"Measured above its prediction: {'; '.join(over) or 'none'}. Compared only up to a stop one "
              f"run made and the other did not (nothing measured beyond it): {'; '.join(unverified) or 'none'}.", "",
              "## Generated trains", "", f"{GENERATED} random trains of 2-5 carts (benchmarks.common.random_train) "
              "on the headland turn and on the reversing scene, each level against slip as above (one run each):", ""]
    lines += table(generated_rows, header)
    lines += ["", f"Measured above its prediction: {'; '.join(generated_over) or 'none'}. Compared only up to a "
              f"stop one run made and the other did not: {'; '.join(generated_unverified) or 'none'}.", ""]

    # -- slip -> dynamic as the stiffness grows ---------------------------------------------------
    base = load_scene(str(Path(args.scenes) / "steady_turn.yaml"))
    base = dataclasses.replace(base, duration=30.0)
    dyn = record(base, "dynamic")
    conv = []
    for factor in (1.0, 10.0, 100.0, 1000.0):
        r = record(with_stiffness(base, factor), "slip")
        e = errors(dyn, r)
        conv.append((f"{factor:g}", f"{e['poses']:.4g}", f"{e['hitch_angles']:.4g}", f"{e['power']:.3g}",
                     f"{r['cpu']:.3f}", r["nfev"]))
    lines += ["", "## Slip converges to dynamic as the cornering stiffness grows",
              "", "steady_turn, first 30 s; error of the dynamic level against slip with C_alpha x factor:", ""]
    lines += table(conv, ("C_alpha factor", "poses m", "hitch rad", "power rel.", "slip CPU s/s", "RHS evals"))

    # -- stiffness at low speed -------------------------------------------------------------------
    eig = slip_eigenvalues(base, (3.0, 1.0, 0.3, 0.1, 0.03, 0.0))
    lines += ["", "## Stiffness of the slip level at low speed", "",
              "Largest |eigenvalue| of the slip level's Jacobian (default train, straight line) and the "
              "largest RK4 step that stays stable for it, 2.785/|lambda|:", ""]
    lines += table([(f"{v:g}", f"{lam:.4g}", f"{2.785 / lam:.4g}") for v, lam in eig],
                   ("V m/s", "max abs(lambda) 1/s", "RK4 h_max s"))
    surv = low_speed_survival(base, 0.1)
    lines += ["", "Slip level at V = 0.1 m/s for 5 s (step / largest step 0.01 s, tick 0.02 s):", ""]
    lines += table([(m, o, n, f"{c:.3f}") for m, o, n, c in surv], ("method", "outcome", "RHS evals", "CPU s/s"))
    print("\n".join(lines))
    write_report(args.out, lines)
    return 0
