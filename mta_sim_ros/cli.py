"""``mta``: the package's one command-line entry, with subcommands."""
from __future__ import annotations

import argparse
import sys


def check_main(args: argparse.Namespace) -> int:
    from .model.loader import check_files

    return check_files(args.files)


def build_parser() -> argparse.ArgumentParser:
    from .tools import run

    parser = argparse.ArgumentParser(prog="mta", description="Multi-element machine-tractor unit simulator (ROS 2).")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("run", help="simulate a scene offline, as fast as possible, into an MCAP bag",
                       description=run.__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    run.add_arguments(p)
    p.set_defaults(func=run.main)

    p = sub.add_parser("check", help="validate train and scene files without running them")
    p.add_argument("files", nargs="+", help="YAML files (config/trains/*.yaml, config/scenes/*.yaml)")
    p.set_defaults(func=check_main)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
