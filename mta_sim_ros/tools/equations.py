"""``mta equations TRAIN.yaml``: the scheme's equations of motion as the article states them
(mta_sim_ros/equations.py): the element lists, the per-cart recursion, the structural matrices,
M, Q, dM/dt and the Cauchy form; built by sympy from the model's own code, so what is printed is
what the simulator computes. The recursion prints for any number of carts (about a second for 30);
the expanded forms (kapC_k, kapT_k, kapB_k, M, Q, dM/dt, V') grow about 3x per cart, so they print
for trains of at most ``--expand-up-to`` carts (default 2; at most 5: 235 kB of text, a second).

    mta equations TRAIN.yaml [--format markdown|latex] [--numbers] [--expand-up-to N] [--out FILE]
"""
from __future__ import annotations

import argparse
import sys

from ..validate import distinct_output, fail, output_file, path_arg, show
from ..writing import write_output

#: the most carts whose expanded forms are printed (5 carts: 235 kB of text, ~1 s; 6: ~0.7 MB)
EXPAND_LIMIT = 5


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("train", help="train YAML (config/trains/*.yaml), or a scene YAML (its train)")
    p.add_argument("--format", choices=("markdown", "latex"), default="markdown", help="default markdown")
    p.add_argument("--numbers", action="store_true", help="the train file's numbers in place of l_k, a_k, c_k, m_k, J_k")
    p.add_argument("--expand-up-to", default="2", metavar="N",
                   help=f"print the expanded forms for trains of at most N carts (0..{EXPAND_LIMIT}; default 2)")
    p.add_argument("--out", type=path_arg(output_file), help="write to this file (default: print)")


def main(args: argparse.Namespace) -> int:
    from ..config import resolve_config_path
    from ..physics import spec
    from ..physics.loader import load_file
    from ..symbolic.equations import build, render

    expand = args.expand_up_to.strip()
    if not expand.isdigit() or int(expand) > EXPAND_LIMIT:
        fail("--expand-up-to", show(args.expand_up_to), f"a whole number from 0 to {EXPAND_LIMIT} (the expanded "
             "forms grow about 3x per cart; the recursion prints for any train)")
    source = resolve_config_path(args.train)
    loaded = load_file(source)
    train = loaded.train if isinstance(loaded, spec.Scene) else loaded
    if args.out:  # before any work: never the train or scene it reads
        distinct_output(args.out, "--out", (source, train.source))
    text = render(build(train), args.format, args.numbers, int(expand))
    if not args.out:
        print(text)
        return 0
    try:
        write_output(args.out, lambda path: path.write_text(text + "\n"))
    except OSError as err:  # a full disk, a device that takes no file: the output is as it was
        print(f"mta equations: --out {args.out} cannot be written ({err.strerror or err})", file=sys.stderr)
        return 1
    print(args.out)
    return 0
