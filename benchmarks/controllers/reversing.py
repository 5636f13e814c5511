"""``python -m benchmarks reversing``: where the reversing controller (controllers/reversing/) holds and where it fails.

Offline, the dynamic level, 50 Hz, the gain designed at each run's speed (default weights): the
default unit backs 100 m along y = 0 from a start 0.5 m to the side with its hitches at +-2 deg,
measured like ``mta follow``: the largest and RMS lateral error of the seeder's axle after 30 m,
the largest hitch angle and steering angle, the share of ticks the command hit the actuator's
max_angle, and the verdict (a jackknife: where and why). Then, at 1 m/s: every cart's length
scaled (a shorter or longer train), and larger starting offsets. Then the envelope on generated
trains (reversing_envelope.py): where the controller's check (controllers/reversing/envelope.py)
holds a train and refuses it, against the dynamic level's run. Writes docs/benchmarks/reversing.md,
docs/reversing.png (the paths of the tractor and the seeder from 2 m to the side) and
docs/reversing_envelope.png.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from mta_sim_ros.validate import output_file, path_arg

from ..common import header_lines, table, write_report
from .reversing_envelope import chart, envelope_lines, generated

HELP = "the reversing controller: speeds, train lengths and offsets where it holds and where it folds"
SPEEDS = (-0.5, -1.0, -2.0, -3.0, -5.0, -8.0)
SCALES = (0.4, 0.6, 1.0, 1.5, 2.0)
OFFSETS = (0.5, 2.0, 5.0, 10.0, 20.0)


def add_arguments(p) -> None:
    p.add_argument("--out", type=path_arg(output_file), default="docs/benchmarks/reversing.md", help="Markdown report")
    p.add_argument("--plot", type=path_arg(output_file), default="docs/reversing.png", help="trajectory plot")
    p.add_argument("--envelope", type=path_arg(output_file), default="docs/reversing_envelope.png",
                   help="chart of the generated trains held, by carts and speed")


def scene(train, speed: float, offset: float, distance: float = 100.0):
    from mta_sim_ros.physics import loader

    data = {"name": "backing", "train": "unused.yaml", "duration": 10 * distance / abs(speed) + 60,
            "initial": {"y": offset, "speed": speed, "hitch_angles_deg": [2, -2][:train.n - 1]},
            "steering": {"maneuver": "straight"}, "speed": speed,
            "integrator": {"method": "rk4", "step": 0.01}, "publish_rate": 50, "fidelity": "dynamic"}
    return loader.scene_from_data(data, "backing scene", train)


def curve_scene(train, gains, offset: float = 0.3):
    """The train on its steady reversing circle about the origin, A_1 ``offset`` m outside it."""
    from mta_sim_ros.physics import loader
    from mta_sim_ros.physics.steady import steady_circle

    initial = {"x": gains.R_A1 + offset, "y": 0.0, "heading": float(gains.point[1]), "speed": gains.speed,
               "steering": gains.steering,
               "hitch_angles": [float(v) for v in steady_circle(train, gains.steering).hitch_angles]}
    data = {"name": "curve", "train": "unused.yaml", "duration": 1000 / abs(gains.speed) + 60, "initial": initial,
            "steering": {"maneuver": "straight"}, "speed": gains.speed,
            "integrator": {"method": "rk4", "step": 0.01}, "publish_rate": 50, "fidelity": "dynamic"}
    return loader.scene_from_data(data, "curve scene", train)


def scaled(train, factor: float):
    carts = tuple(dataclasses.replace(c, length=c.length * factor, hitch_offset=c.hitch_offset * factor,
                                      com_offset=c.com_offset * factor) for c in train.carts)
    return dataclasses.replace(train, carts=carts, name=f"{train.name} x{factor:g}")


def within(run, bound: float = 0.05, radius: float | None = None) -> str:
    """m the last axle travelled until its error stayed within ``bound`` ('-' if it never did): the
    error its y (straight), or its radial offset from ``radius`` about the origin (a circle)."""
    t = run.trace
    if run.stopped or not len(t):
        return "-"
    if radius is None:
        error, along = t[:, 2], t[0, 1] - t[:, 1]
    else:
        error = np.hypot(t[:, 1], t[:, 2]) - radius
        along = np.concatenate(([0.0], np.cumsum(np.hypot(np.diff(t[:, 1]), np.diff(t[:, 2])))))
    outside = np.flatnonzero(np.abs(error) >= bound)
    if not outside.size:
        return "0"
    if outside[-1] == len(t) - 1:
        return "-"
    return f"{along[outside[-1] + 1]:.0f}"


def row(label: str, run, radius: float | None = None, check: str = "-") -> tuple:
    verdict = "holds" if not run.stopped else "folds: " + run.stopped.split(";")[0].split(" (limit")[0]
    return (label, f"{run.distance:.0f}", within(run, radius=radius), f"{run.max_error * 100:.1f}", f"{run.rms_error * 100:.1f}",
            f"{run.max_hitch_deg:.1f}", f"{run.max_steering_deg:.1f}", f"{100 * run.saturated:.0f}", check, verdict)


def straight(train, speed: float, start, gains=None, label: str = "") -> tuple:
    """The row of backing ``train`` from scene ``start`` with ``gains`` (the default design, unchecked),
    with the controller's check of those gains (controller.unheld_on_both: what mta reverse would say)."""
    from mta_sim_ros.controllers.reversing.controller import design, reverse, unheld_on_both

    gains = gains or design(train, speed, check=False)
    run = reverse(start, gains, 100.0, settle=30.0)
    return row(label, run, check="holds" if not unheld_on_both(train, gains) else "refuses")


HEADER = ["run", "reversed, m", "until within 5 cm, m", "max error after 30 m, cm", "RMS, cm", "largest hitch, deg",
          "largest steering, deg", "ticks at max_angle, %", "mta reverse's check", "verdict"]


def main(args) -> int:
    from mta_sim_ros.config import resolve_config_path
    from mta_sim_ros.controllers.reversing.controller import MAX_ERROR, design, design_curve, reverse, reverse_curve
    from mta_sim_ros.physics.loader import load_train

    train = load_train(resolve_config_path("trains/default.yaml"))
    lines = header_lines("Backing up: where the reversing controller holds", args)
    rows = []
    for speed in SPEEDS:
        rows.append(straight(train, speed, scene(train, speed, 0.5), label=f"{speed:g} m/s"))
        print(rows[-1], flush=True)
    lines += ["## Speeds (default unit, 0.5 m to the side)", "", *table(rows, HEADER, "lrrrrrrrll"), ""]
    rows = []
    for factor in SCALES:
        t = scaled(train, factor)
        rows.append(straight(t, -1.0, scene(t, -1.0, 0.5),
                             label=f"lengths x{factor:g} ({sum(c.length for c in t.carts):.1f} m of carts)"))
        print(rows[-1], flush=True)
    lines += ["## Train lengths (every l, a, c scaled; -1 m/s)", "", *table(rows, HEADER, "lrrrrrrrll"), ""]
    rows = []
    for offset in OFFSETS:
        rows.append(straight(train, -1.0, scene(train, -1.0, offset), label=f"{offset:g} m to the side"))
        print(rows[-1], flush=True)
    lines += ["## Starting offsets (default unit, -1 m/s; the gain sees at most "
              f"{MAX_ERROR:g} m of error)", "", *table(rows, HEADER, "lrrrrrrrll"), ""]
    rows = []
    for offset in OFFSETS[:3]:
        gains = dataclasses.replace(design(train, -1.0, check=False), max_error=math.inf)
        rows.append(straight(train, -1.0, scene(train, -1.0, offset), gains, f"{offset:g} m to the side, the whole error"))
        print(rows[-1], flush=True)
    for hitch in (10.0, 20.0, 30.0):
        start = dataclasses.replace(scene(train, -1.0, 0.5), initial=dataclasses.replace(
            scene(train, -1.0, 0.5).initial, hitch_angles=(math.radians(hitch), -math.radians(hitch))))
        rows.append(straight(train, -1.0, start, label=f"hitches at +-{hitch:g} deg at the start"))
        print(rows[-1], flush=True)
    lines += ["## Where it folds (-1 m/s)", "",
              "The linear gain shown the whole of a large offset asks for more steering than the actuator's "
              "40 deg: saturated, the loop is no longer the designed one and the train folds. Bent hitches "
              "at the start likewise.", "", *table(rows, HEADER, "lrrrrrrrll"), ""]
    rows = []
    for radius, side, speed in ((100.0, 1.0, -1.0), (50.0, 1.0, -1.0), (50.0, -1.0, -3.0), (30.0, 1.0, -1.0),
                                (20.0, 1.0, -1.0), (15.0, 1.0, -1.0)):
        label = f"circle of {radius:g} m ({'left' if side > 0 else 'right'}), {speed:g} m/s"
        try:
            gains = design_curve(train, speed, radius, side)
        except ValueError as err:
            rows.append((label, "-", "-", "-", "-", "-", "-", "-", "-", f"no steady turn: {err}"))
            continue
        run = reverse_curve(curve_scene(train, gains), gains, (0.0, 0.0), 100.0, settle=30.0)
        rows.append(row(label + f": psi_0 {math.degrees(gains.steering):.2f} deg", run, radius))
        print(rows[-1], flush=True)
    lines += ["## Along a curve (the gain designed about the steady reversing turn; 0.3 m outside the circle)", "",
              "The error is the last axle's radial offset from its circle; 'until within 5 cm' counts arc length.", "",
              *table(rows, HEADER, "lrrrrrrrll"), ""]
    envelope_rows, figures = generated()
    lines += envelope_lines(envelope_rows)
    chart(figures, Path(args.envelope))
    lines += [f"![held, by carts](../{Path(args.envelope).name})" if Path(args.envelope).parent.name == "docs" else
              f"Chart: {args.envelope}", ""]
    trajectory = reverse(scene(train, -1.0, 2.0), design(train, -1.0), 100.0, settle=30.0)
    plot(trajectory, train, Path(args.plot))
    lines += [f"![the paths](../{Path(args.plot).name})" if Path(args.plot).parent.name == "docs" else
              f"Plot: {args.plot}", ""]
    write_report(args.out, lines)
    return 0


def plot(run, train, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    t = run.trace
    ax.plot(t[:, 1], t[:, 2], label=f"{train.carts[-1].name}'s axle B_n")
    ax.axhline(0.0, color="grey", lw=0.8, ls="--", label="the line")
    ax.set_ylabel("lateral position, m")
    ax.legend(loc="upper right")
    ax.set_title(f"{train.name}: backing up at 1 m/s from 2 m to the side (LQR)")
    for k in range(train.n - 1):
        bx.plot(t[:, 1], [math.degrees(v) for v in t[:, 3 + k]], label=f"hitch {k + 2}")
    bx.plot(t[:, 1], [math.degrees(v) for v in t[:, -1]], label="steering psi_1", ls=":")
    bx.set_xlabel("x of B_n, m (backing towards -x)")
    bx.set_ylabel("deg")
    bx.legend(loc="upper right")
    ax.invert_xaxis()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
