"""``mta equations TRAIN.yaml``: the scheme's equations of motion as the article states them
(mta_sim_ros/equations.py): the element lists, the per-cart recursion, the structural matrices,
M, Q, dM/dt and the Cauchy form, V' expanded for trains of 1 or 2 carts; built by sympy from the
model's own code, so what is printed is what the simulator computes.

    mta equations TRAIN.yaml [--format markdown|latex] [--numbers] [--out FILE]
"""
from __future__ import annotations

import argparse

from ..validate import output_file, path_arg


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("train", help="train YAML (config/trains/*.yaml), or a scene YAML (its train)")
    p.add_argument("--format", choices=("markdown", "latex"), default="markdown", help="default markdown")
    p.add_argument("--numbers", action="store_true", help="the train file's numbers in place of l_k, a_k, c_k, m_k, J_k")
    p.add_argument("--out", type=path_arg(output_file), help="write to this file (default: print)")


def main(args: argparse.Namespace) -> int:
    from ..config import resolve_config_path
    from ..physics import spec
    from ..physics.loader import load_file
    from ..symbolic.equations import build, render

    loaded = load_file(resolve_config_path(args.train))
    train = loaded.train if isinstance(loaded, spec.Scene) else loaded
    text = render(build(train), args.format, args.numbers)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")
        print(args.out)
    else:
        print(text)
    return 0
