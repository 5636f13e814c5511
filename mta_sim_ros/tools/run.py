"""``mta run``: simulate a scene offline as fast as possible and log it to MCAP.

The bag holds the topics the node publishes (``topics.py``) with log_time = simulation time,
and a metadata record ``mta_sim_ros`` with the scene and train files as read and the run's
options, so the run can be repeated from the bag alone. A run stopped by a validity guard
(jackknife, non-finite state) keeps everything up to that point, closes the bag properly, says
what happened and exits with code 3.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from .. import __version__
from ..bag import BagError, BagWriter
from ..fidelity import LEVELS, choose
from ..messages import CommandEncoder, OutputEncoder
from ..model.loader import SpecError, load_scene
from ..sim import run_scene
from ..summary import RunSummary
from ..topics import TOPICS, qualified

EXIT_STOPPED = 3


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", required=True, help="scene YAML (config/scenes/*.yaml)")
    p.add_argument("--bag", help="MCAP file to write (default: bags/<scene name>.mcap)")
    p.add_argument("--report", help="summary Markdown to write (default: beside the bag, .md)")
    p.add_argument("--method", help="integrator, overrides the scene (euler, heun, rk4, RK45, DOP853, LSODA, Radau, BDF)")
    p.add_argument("--step", type=float, help="integrator step, s, overrides the scene")
    p.add_argument("--rate", type=float, help="publish (tick) rate, Hz, overrides the scene")
    p.add_argument("--fidelity", choices=("auto",) + LEVELS,
                   help="model level, overrides the scene's fidelity (auto: the cheapest meeting the scene's needs)")
    p.add_argument("--no-split-kinks", dest="split_kinks", action="store_false", default=None,
                   help="step straight across the kinks of the right-hand side (the steering rate limit letting "
                        "go, a force limit engaging) instead of splitting the step there (the scene's "
                        "integrator.split_kinks, default true)")
    p.add_argument("--frame-id", default="map", help="frame of hitch_poses (default: map)")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no summary on stdout")


class Progress:
    """A one-line progress bar on a terminal; silent otherwise."""

    def __init__(self, total: float, stream=sys.stderr):
        self.total, self.stream = total, stream
        self.enabled = stream.isatty()
        self._last = -1

    def update(self, t: float) -> None:
        if not self.enabled:
            return
        pct = int(100 * t / self.total) if self.total > 0 else 100
        if pct != self._last:
            self._last = pct
            bar = "#" * (pct // 4)
            self.stream.write(f"\r[{bar:<25}] {pct:3d}%  t = {t:7.2f} s")
            self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")


def run_metadata(scene, options: dict) -> dict[str, str]:
    """What it takes to repeat the run: the files as read and the options used."""
    train_path = Path(scene.train.source)
    return {
        "package_version": __version__,
        "scene_file": scene.source,
        "scene_yaml": Path(scene.source).read_text(),
        "train_file": str(train_path),
        "train_yaml": train_path.read_text(),
        **{k: str(v) for k, v in options.items()},
    }


def main(args: argparse.Namespace) -> int:
    try:
        scene = load_scene(args.scene)
    except SpecError as err:
        print(f"mta run: {err}", file=sys.stderr)
        return 2
    bag_path = Path(args.bag or f"bags/{scene.name}.mcap")
    report_path = Path(args.report) if args.report else bag_path.with_suffix(".md")
    fidelity = getattr(args, "fidelity", None)
    try:
        choice = choose(scene, forced=fidelity)
    except ValueError as err:
        print(f"mta run: {err}", file=sys.stderr)
        return 2
    method = args.method
    if choice.level == "slip" and not method:
        from ..model.slip import DEFAULT_METHOD as method  # the slip level's own (its tyres are stiff)
    step = args.step or (1.0 / (args.rate or scene.publish_rate) if choice.level == "slip" and not args.method
                         else scene.integrator.step)  # as Simulation takes them
    split_kinks = getattr(args, "split_kinks", None)
    options = {"method": method or scene.integrator.method, "step": step,
               "rate": args.rate or scene.publish_rate, "algorithm": 2,
               "fidelity": choice.level, "fidelity_reason": choice.reason,
               "split_kinks": scene.integrator.split_kinks if split_kinks is None else split_kinks}
    cart_names = [c.name for c in scene.train.carts]
    tick = 1.0 / options["rate"]
    summary = RunSummary(tuple(cart_names))
    progress = Progress(scene.duration)
    started = time.perf_counter()
    try:
        bag_path.parent.mkdir(parents=True, exist_ok=True)
        with BagWriter(str(bag_path), metadata={"mta_sim_ros": run_metadata(scene, options)}) as bag:
            for topic, type_name in TOPICS.items():
                bag.add_topic(qualified(topic), type_name)
            outputs, commands = OutputEncoder(cart_names, args.frame_id), CommandEncoder()  # the node's encoders

            def record(out):
                stamp_ns = round(out.t * 1e9)
                for topic, data in outputs.encode(out).items():
                    bag.write_raw(qualified(topic), data, stamp_ns)
                if out.t > 0:  # the inputs held over the tick that ended here, stamped at its start
                    for topic, data in commands.encode(out).items():
                        bag.write_raw(qualified(topic), data, round((out.t - tick) * 1e9))
                summary.add(out)
                progress.update(out.t)

            sim, stopped = run_scene(scene, on_output=record, method=args.method, step=args.step, rate=args.rate,
                                     fidelity=choice.level, split_kinks=options["split_kinks"])
    except BagError as err:
        progress.close()
        print(f"mta run: {err}", file=sys.stderr)
        return 1
    progress.close()
    wall = time.perf_counter() - started
    extra = {
        "fidelity": choice.reason,
        "integrator": f"{sim.method}, step {sim.step:g} s, tick {sim.tick:g} s, {sim.stepper.nfev} RHS evaluations, "
                      f"{sim.kinks} kinks split at; {sim.compiled_note}",
        "wall time": f"{wall:.2f} s (x{summary.duration / wall:.0f} real time)" if wall > 0 else "",
        "bag": str(bag_path),
    }
    if stopped:
        extra["stopped early"] = str(stopped)
    text = summary.markdown(f"Run of scene '{scene.name}' ({scene.source})", extra)
    report_path.parent.mkdir(parents=True, exist_ok=True)
    report_path.write_text(text)
    if not args.quiet:
        print(text)
        print(f"bag: {bag_path}\nreport: {report_path}")
    if stopped:
        print(f"mta run: stopped: {stopped}", file=sys.stderr)
        return EXIT_STOPPED
    return 0
