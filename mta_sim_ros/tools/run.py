"""``mta run``: simulate a scene offline as fast as possible and log it to MCAP.

The bag holds the topics the node publishes (``topics.py``, the frames of the train included, in
the root namespace: no frame prefix) with log_time = simulation time,
and a metadata record ``mta_sim_ros`` with the scene and train files as read and the run's
options, so the run can be repeated from the bag alone. A run stopped by a validity guard
(jackknife, non-finite state) keeps everything up to that point, closes the bag properly, says
what happened and exits with code 3. A bad scene or argument (validate.py) is refused in one line
with exit code 2 before anything is written; the bag and the report are written beside their
place and renamed onto it when complete, so a failed run loses no earlier bag and leaves no
half-written one (exit code 1 when the bag cannot be written).
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from .. import __version__
from ..bag import DEFAULT_QOS_YAML, BagError, BagWriter
from ..config import resolve_config_path
from ..messages import CommandEncoder, FrameEncoder, OutputEncoder, poses_frame
from ..messages.topics import FRAME_TOPICS, LATCHED_QOS_YAML, LATCHED_TOPICS, TOPICS, qualified
from ..messages.urdf import robot_model
from ..node.runlog import terrain_record
from ..physics.loader import load_scene
from ..physics.spec import INTEGRATOR_METHODS
from ..physics.terrain import Stance
from ..run.fidelity import LEVELS, choose
from ..run.following import GovernorWatch
from ..run.margins import MarginGauge
from ..run.accuracy import settle
from ..run.simulation import run_scene
from ..run.summary import RunSummary
from ..validate import (
    EXIT_INPUT,
    FRAME_ID,
    MAX_STEPS_PER_TICK,
    POSITIVE,
    PUBLISH_RATE,
    distinct_output,
    fail,
    number_arg,
    output_file,
    show,
    step_count,
    step_rule,
    tick_count,
)

EXIT_STOPPED = 3


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", required=True, help="scene YAML (config/scenes/*.yaml)")
    p.add_argument("--bag", help="MCAP file to write (default: bags/<scene name>.mcap)")
    p.add_argument("--report", help="summary Markdown to write (default: beside the bag, .md)")
    p.add_argument("--method", choices=INTEGRATOR_METHODS, metavar="METHOD",
                   help=f"integrator, overrides the scene (one of {', '.join(INTEGRATOR_METHODS)})")
    p.add_argument("--step", type=number_arg(POSITIVE),
                   help="integrator step, s, overrides the scene (at most the tick, at least tick / "
                        f"{MAX_STEPS_PER_TICK})")
    p.add_argument("--rate", type=number_arg(PUBLISH_RATE), help="publish (tick) rate, Hz, overrides the scene "
                                                                  f"({PUBLISH_RATE.text})")
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

    def __init__(self, total: float, stream=None):
        self.total, self.stream = total, stream or sys.stderr  # the stderr of the call, not of the import
        self.enabled = self.stream.isatty()
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
        **terrain_record(scene),
        **{k: str(v) for k, v in options.items()},
    }


def output_paths(args: argparse.Namespace, scene) -> tuple[Path, Path]:
    """The bag and report paths, checked before any work: writable files (validate.output_file),
    not the same file, and none of the files the run reads (Scene.input_files: the scene, its train,
    a height grid)."""
    bag = output_file(args.bag or f"bags/{scene.name}.mcap", "--bag")
    report = output_file(args.report, "--report") if args.report else bag.with_suffix(".md")
    if report.resolve() == bag.resolve():
        if not args.report:  # the report's default name is the bag's with .md
            fail("--bag", show(str(bag)), "a file not ending in .md: the report is written beside it as <bag>.md "
                 "unless --report names it")
        fail("--report", show(str(report)), "another file than the bag")
    for field, path in (("--bag", bag), ("--report", report)):
        distinct_output(path, field, scene.input_files())
    return bag, report


def run_options(args: argparse.Namespace, scene, choice) -> dict:
    """What the run uses: method, step, rate, fidelity, split_kinks (the scene's unless given),
    checked against each other (the step within the tick) and the run's size (validate.run_size)."""
    method = args.method
    if choice.level == "slip" and not method:
        from ..physics.slip import DEFAULT_METHOD as method
    rate = args.rate or scene.publish_rate
    step = args.step or (1.0 / rate if choice.level == "slip" and not args.method
                         else scene.integrator.step)  # as Simulation takes them
    if args.step is not None and not step_rule(rate).test(args.step):
        fail("--step", show(args.step), step_rule(rate).text)
    problem = tick_count(scene.duration, rate)  # the scene's own is checked by the loader
    if problem:
        fail("--rate", show(args.rate), f"{problem} for the duration {scene.duration:g} s of {scene.source}")
    problem = step_count(scene.duration, rate, step or 1.0 / rate)  # no step: the tolerance's (accuracy.settle)
    if problem:
        fail("--step" if args.step else "--rate", show(args.step or args.rate), problem)
    split_kinks = getattr(args, "split_kinks", None)
    return {"method": method or scene.integrator.method, "step": step, "rate": rate, "algorithm": 2,
            "fidelity": choice.level, "fidelity_reason": choice.reason,
            "split_kinks": scene.integrator.split_kinks if split_kinks is None else split_kinks}


def partial(path: Path) -> Path:
    """Where ``path`` is written until it is complete (then renamed onto it): a failed run
    leaves no file claiming to be the run, and loses no earlier one."""
    return path.with_name(f".{path.name}.partial")


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through its partial file."""
    tmp = partial(path)
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def main(args: argparse.Namespace) -> int:
    try:
        scene = load_scene(resolve_config_path(args.scene))  # a name as every command takes it
        choice = choose(scene, forced=getattr(args, "fidelity", None))
        options = run_options(args, scene, choice)
        robot = robot_model(scene.train)  # the root namespace's frames: no prefix
        if not FRAME_ID.test(args.frame_id):  # the node's frame_id parameter's rule
            fail("--frame-id", show(args.frame_id), FRAME_ID.text)
        if robot.frame_id_rule(args.frame_id):
            fail("--frame-id", show(args.frame_id), robot.frame_id_rule(args.frame_id))
        bag_path, report_path = output_paths(args, scene)
    except ValueError as err:  # SpecError, InputError, a fidelity level the scene cannot run
        print(f"mta run: {err}", file=sys.stderr)
        return EXIT_INPUT
    try:
        stated = settle_step(args, scene, options)
    except ValueError as err:  # the simulation refuses its options (validate.MAX_STEPS_PER_TICK, ...)
        print(f"mta run: {err}", file=sys.stderr)
        return EXIT_INPUT
    tmp_bag = partial(bag_path)
    try:
        result = simulate(args, scene, choice, options, tmp_bag, robot, stated)
        if isinstance(result, int):
            return result
        sim, stopped, summary, wall = result
        text = summary.markdown(f"Run of scene '{scene.name}' ({scene.source})",
                                report_extra(sim, choice, summary, wall, bag_path, stopped, stated))
        os.replace(tmp_bag, bag_path)
    finally:
        tmp_bag.unlink(missing_ok=True)
    write_atomic(report_path, text)
    if not args.quiet:
        print(text)
        print(f"bag: {bag_path}\nreport: {report_path}")
    if stopped:
        print(f"mta run: stopped: {stopped}", file=sys.stderr)
        return EXIT_STOPPED
    return 0


def settle_step(args: argparse.Namespace, scene, options: dict):
    """The run's accuracy (run/accuracy.py: a companion run states its position error), and with
    no step given the step that meets the scene's tolerance, set into ``options``."""
    run, stated = settle(scene, method=options["method"], step=args.step, rate=args.rate,
                         fidelity=options["fidelity"], split_kinks=options["split_kinks"])
    options["step"] = run[0].step
    return stated


def simulate(args: argparse.Namespace, scene, choice, options: dict, bag_path: Path, robot, stated):
    """Run the scene into the bag at ``bag_path``: (sim, what stopped it or None, summary, wall
    seconds), or an exit code after saying what went wrong in one line. ``robot``: the train's
    robot model (urdf.Robot), whose frames the bag holds as the node's does (/tf, /tf_static,
    joint_states, odom, robot_description; the latched ones at t = 0)."""
    cart_names = [c.name for c in scene.train.carts]
    tick = 1.0 / options["rate"]
    summary = RunSummary(tuple(cart_names), stance=Stance(scene.train),
                         governor=GovernorWatch(scene.train.traction, prescribed=choice.level == "kinematic"))
    progress = Progress(scene.duration)
    started = time.perf_counter()
    try:
        metadata = {**run_metadata(scene, options), **stated.metadata()}
        with BagWriter(str(bag_path), metadata={"mta_sim_ros": metadata}) as bag:
            for topic, type_name in TOPICS.items():
                bag.add_topic(qualified(topic), type_name)
            for topic, type_name in FRAME_TOPICS.items():
                bag.add_topic(qualified(topic), type_name, LATCHED_QOS_YAML if topic in LATCHED_TOPICS
                              else DEFAULT_QOS_YAML)
            plane, relief = scene.train.terrain, scene.train.relief
            outputs = OutputEncoder(cart_names, poses_frame(robot, args.frame_id, plane), relief)  # the node's encoders
            commands = CommandEncoder()
            frames = FrameEncoder(robot, args.frame_id, plane=plane, relief=relief)
            for topic, data in frames.latched(0.0).items():
                bag.write_raw(qualified(topic), data, 0)

            def record(out):
                if out.t > 0:  # the inputs held over the tick that ended here, stamped at its start,
                    for topic, data in commands.encode(out).items():  # so before its outputs
                        bag.write_raw(qualified(topic), data, round((out.t - tick) * 1e9))
                stamp_ns = round(out.t * 1e9)
                for topic, data in outputs.encode(out).items():
                    bag.write_raw(qualified(topic), data, stamp_ns)
                for topic, data in frames.encode(out).items():
                    bag.write_raw(qualified(topic), data, stamp_ns)
                summary.add(out)
                progress.update(out.t)

            gauge = MarginGauge(scene.train)

            def margins(s):  # the state's tip and grip margins into the report (run/margins.py)
                summary.add_margins(gauge.at(s.model, s.y, s.command, s.v_set, s.rate_limit, s.compiled is not False))

            sim, stopped = run_scene(scene, on_output=record, method=args.method, step=options["step"], rate=args.rate,
                                     fidelity=choice.level, split_kinks=options["split_kinks"], on_state=margins)
    except (BagError, OSError) as err:
        progress.close()
        print(f"mta run: {err}", file=sys.stderr)
        return 1
    except ValueError as err:  # the simulation refuses its options (validate.MAX_STEPS_PER_TICK, ...)
        progress.close()
        print(f"mta run: {err}", file=sys.stderr)
        return EXIT_INPUT
    progress.close()
    return sim, stopped, summary, time.perf_counter() - started


def report_extra(sim, choice, summary, wall: float, bag_path: Path, stopped, stated) -> dict[str, str]:
    """The report's lines about the run beyond the summary's figures."""
    extra = {
        "fidelity": choice.reason,
        "accuracy": stated.line(),
        "integrator": f"{sim.method}, step {sim.step:g} s, tick {sim.tick:g} s, {sim.stepper.nfev} RHS evaluations, "
                      f"{sim.kinks} kinks split at; {sim.compiled_note}",
        "wall time": f"{wall:.2f} s (x{summary.duration / wall:.0f} real time)" if wall > 0 else "",
        "bag": str(bag_path),
    }
    if stopped:
        extra["stopped early"] = str(stopped)
    return extra
