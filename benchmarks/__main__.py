"""``python -m benchmarks NAME [options]``: run one benchmark (registry.py lists them).

Faults of an argument are one line and exit code 2, as for ``mta`` (cli.Parser)."""
from __future__ import annotations

import argparse
import importlib
import sys

from mta_sim_ros.cli import Parser

from .registry import MODULES


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="python -m benchmarks", description=__doc__,
                    formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="bench", required=True, metavar="BENCH")
    for name in MODULES:
        module = importlib.import_module(f".{MODULES[name]}", __package__)
        p = sub.add_parser(name.replace("_", "-"), help=module.HELP, description=module.__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(p)
        p.set_defaults(bench_func=module.main)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(sys.argv[1:] if argv is None else argv)
    try:
        return args.bench_func(args)
    except KeyboardInterrupt:
        print(f"python -m benchmarks {args.bench}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
