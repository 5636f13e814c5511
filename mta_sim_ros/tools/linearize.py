"""``mta linearize TRAIN.yaml``: the train's linear model x' = A x + B u (mta_sim_ros/linear.py).

    mta linearize TRAIN.yaml --about straight --speed V            (V < 0: reversing)
    mta linearize TRAIN.yaml --about turn --steering PSI --speed V

States: the tractor's lateral offset and heading (about a turn: its radial offset from the steady
circle and its heading against the circle's tangent), each hitch angle, the steering angle; input:
the steering command. Exact derivatives of the model's own chain equations at the operating point
(forward-mode dual numbers through the chain: milliseconds for any train; equal to sympy's Jacobian
to round-off, test_linear); prints A, B and the eigenvalues with what each is, as Markdown; ``--out PREFIX`` also writes
PREFIX.md, PREFIX.json and PREFIX.npz (A, B, eigenvalues, states).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

from ..validate import Range, distinct_output, fail, number_arg, output_file, show
from ..writing import write_together

SPEED = Range.of(-100.0, 100.0, "m/s")
STEERING = Range.of(-math.pi / 2, math.pi / 2, "rad")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("train", help="train YAML (config/trains/*.yaml), or a scene YAML (its train)")
    p.add_argument("--about", choices=("straight", "turn"), default="straight", help="operating point (default straight)")
    p.add_argument("--speed", type=number_arg(SPEED), default=3.0, help="V, m/s (negative: reversing; default 3)")
    p.add_argument("--steering", type=number_arg(STEERING), default=None, help="psi_0 of the steady turn, rad (--about turn)")
    p.add_argument("--out", help="write PREFIX.md, PREFIX.json and PREFIX.npz too")


def outputs(prefix: str, inputs) -> dict:
    """PREFIX.md, .json and .npz, checked before any work: PREFIX names files (not a folder, not
    ending in a separator: 'adir/' would write adir/.md), each writable and none an input."""
    if not prefix or prefix.endswith(("/", os.sep)) or os.path.isdir(prefix) or not os.path.basename(prefix):
        fail("--out", show(prefix), "a file name prefix (PREFIX.md, PREFIX.json, PREFIX.npz are written), not a folder")
    return {suffix: distinct_output(output_file(f"{prefix}.{suffix}", "--out"), "--out", inputs)
            for suffix in ("md", "json", "npz")}


def main(args: argparse.Namespace) -> int:
    from ..config import resolve_config_path
    from ..physics import spec
    from ..physics.loader import load_file
    from ..physics.steady import SteadyStateError
    from ..symbolic.linear import linearize, markdown

    source = resolve_config_path(args.train)
    loaded = load_file(source)
    train = loaded.train if isinstance(loaded, spec.Scene) else loaded
    if args.speed == 0.0:
        fail("--speed", show(args.speed), "nonzero: a train standing still has no motion to linearize about")
    if args.about == "turn":
        if args.steering is None or args.steering == 0.0:
            fail("--steering", show(args.steering) if args.steering is not None else "(missing)",
                 "given and nonzero for --about turn (the steady turn's steering angle, rad)")
        if abs(args.steering) > train.actuator.max_angle:
            fail("--steering", show(args.steering), f"within the train's max_angle {train.actuator.max_angle:.4g} rad")
    elif args.steering not in (None, 0.0):
        fail("--steering", show(args.steering), "left out for --about straight")
    out = outputs(args.out, (source, train.source)) if args.out is not None else {}
    try:
        model = linearize(train, args.about, args.speed, args.steering or 0.0)
    except SteadyStateError as err:
        fail("--steering", show(args.steering), f"a steering angle with a steady turn ({err})")
    text = markdown(model, train)
    print(text, end="")
    if out:
        def write(tmp: dict) -> None:
            tmp["md"].write_text(text)
            tmp["json"].write_text(json.dumps({"train": train.name, **model.as_dict()}, indent=1) + "\n")
            with open(tmp["npz"], "wb") as stream:
                np.savez(stream, A=model.A, B=model.B, eigenvalues=model.eigenvalues, states=np.array(model.states),
                         point=model.point, speed=model.speed, steering=model.steering)

        try:
            write_together(out, write)  # all three or none
        except OSError as err:
            print(f"mta linearize: --out {args.out} cannot be written ({err.strerror or err})", file=sys.stderr)
            return 1
        for path in out.values():
            print(path)
    return 0
