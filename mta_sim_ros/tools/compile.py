"""``mta compile``: compile the kernels into numba's cache once, after an install.

numba compiles each kernel the first time it is called and keeps the result on disk (jit.py): on
a fresh install the first node start spends ~13 s compiling before its first tick (a quiet 2-core
machine; ~1 s with the cache), the first ``mta run``, sweep or field run likewise. This command
takes that time once: it runs every shipped scene through ``mta run`` (every model level and
integrator the scenes use, the accuracy estimate; one with an adaptive method), a sweep's
whole-run kernel with its metrics (run.batch), a field worked offline (the implement controller's
loop) and one answer of that controller as ``mta follow --field`` gives it live, into a temporary
folder it removes, and says how long it took.

The cache lies beside the package's sources when that folder is writable, else in numba's cache
folder of the user (or ``NUMBA_CACHE_DIR``): run it as the user who runs the node. Without numba
(or with MTA_SIM_NO_JIT=1) there is nothing to compile; it says so and exits 0.

    mta compile [--quiet]
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quiet", action="store_true", help="no line per part, only the total")


def parts(folder: Path) -> list[tuple[str, list[str]]]:
    """(what, the mta command line) of each part: the shipped scenes, a sweep's run, a field run."""
    from ..config import config_dir

    scenes = sorted((config_dir() / "scenes").glob("*.yaml"))
    out = [(f"scene {s.stem}", ["run", "--scene", str(s), "--bag", str(folder / f"{s.stem}.mcap"), "--quiet"])
           for s in scenes]
    out.append(("scene straight_pass, RK45", ["run", "--scene", "scenes/straight_pass.yaml", "--method", "RK45",
                                              "--bag", str(folder / "adaptive.mcap"), "--quiet"]))
    out.append(("field rectangle", ["field", "run", "fieldwork/rectangle.yaml", "--out", str(folder / "field")]))
    return out


def sweep_run() -> None:
    """One run of a sweep: the whole run in one compiled call, and its metrics."""
    from ..config import resolve_config_path
    from ..physics.loader import load_scene
    from ..run.batch import run_metrics

    run_metrics(load_scene(resolve_config_path("scenes/headland_turn.yaml")))


def live_answer() -> None:
    """One answer of the field controller at the start of the rectangle's route (mta follow --field)."""
    from ..config import resolve_config_path
    from ..controllers.implement.design import Settings
    from ..controllers.implement.drive import start_scene
    from ..controllers.implement.tracker import Tracker
    from ..field.plan import plan_field
    from ..field.scene import load_field_or_scene
    from ..physics.loader import load_train
    from ..run.simulation import Simulation

    train = load_train(resolve_config_path("trains/default.yaml"))
    scene = load_field_or_scene(resolve_config_path("fieldwork/rectangle.yaml"))
    route = plan_field(scene.field, train, scene.options(train)).route
    tracker = Tracker(route, train, Settings())
    tracker.answer_state(Simulation(start_scene(train, route, 2.0, Settings())).y)


def main(args: argparse.Namespace) -> int:
    from .. import jit

    if not jit.ENABLED:
        print(f"mta compile: nothing to compile ({jit.NOTE})")
        return 0
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="mta-compile-") as tmp:
        for what, argv in parts(Path(tmp)):
            begun = time.perf_counter()
            done = subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", *argv], capture_output=True, text=True)
            if done.returncode not in (0, 3):  # 3: a scene that stops by design (a guard) compiled all the same
                last = (done.stderr.strip().splitlines() or ["(no message)"])[-1]
                print(f"mta compile: {what}: mta {' '.join(argv)} ended with exit code {done.returncode}: {last}",
                      file=sys.stderr)
                return 1
            if not args.quiet:
                print(f"{what}: {time.perf_counter() - begun:.1f} s")
        for what, part in (("a sweep's run", sweep_run), ("a live field answer", live_answer)):
            begun = time.perf_counter()
            part()
            if not args.quiet:
                print(f"{what}: {time.perf_counter() - begun:.1f} s")
    print(f"mta compile: the kernels are in numba's cache ({jit.NOTE}), {time.perf_counter() - start:.0f} s")
    return 0
