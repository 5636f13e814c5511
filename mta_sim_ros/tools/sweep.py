"""``mta sweep``: compare many hitching schemes (synthesis), on every core or on a Dask cluster.

    mta sweep SPEC.yaml [--out DIR] [--workers N | --scheduler ADDRESS | --scheduler-file FILE | --serial]
    mta sweep report DIR [--x METRIC] [--y METRIC] [--scene NAME] [--best N] [-o FOLDER]
    mta sweep export DIR RUN -o TRAIN.yaml [--spec SPEC.yaml]

The spec (mta_sim_ros/sweep/spec.py, config/sweeps/hitching.yaml) names a base train, scenes, the
factors that vary and how they are sampled. Every run measures its metrics while it runs (no bag;
the spec's ``bags:`` lists runs that write one too) and is one row of DIR/results.parquet and
DIR/results.csv (default DIR: sweeps/<spec name>). A second call with the same spec and DIR runs
only what is missing. By default an embedded Dask LocalCluster with one worker process per core,
on 127.0.0.1; ``--scheduler``/``--scheduler-file`` runs the same sweep on an existing cluster (its
workers need this package installed), ``--serial`` in this process. A run that jackknifes or
leaves the model's domain is a row with its verdict and reason; a scheme a constraint drops is a
row marked dropped. A bad spec is refused in one line naming the field (exit 2).
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from ..validate import COUNT, fail, number_arg, one_line, show

SUBCOMMANDS = ("report", "export")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("target", metavar="SPEC|report|export", help="a sweep spec YAML, or report / export")
    p.add_argument("items", nargs="*", metavar="ARG", help="report: DIR; export: DIR RUN")
    p.add_argument("--out", "-o", help="run: the results folder (default sweeps/<spec name>); report: the "
                                       "report folder (default DIR/report); export: the train file to write")
    engine = p.add_mutually_exclusive_group()
    engine.add_argument("--workers", type=number_arg(COUNT, int), help="worker processes of the embedded "
                                                                       "LocalCluster (default: one per core)")
    engine.add_argument("--scheduler", help="the address of a running Dask scheduler (tcp://HOST:PORT)")
    engine.add_argument("--scheduler-file", help="the scheduler file of a running Dask cluster")
    engine.add_argument("--serial", action="store_true", help="run in this process, no Dask")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.add_argument("--x", help="report: the Pareto front's first metric (minimized; the margin, areas, coverage, "
                               "efficiency and distance maximized); default per scene: a field's time, fuel and "
                               "skipped area, a manoeuvre's energy per ha and headland width (those that vary)")
    p.add_argument("--y", help="report: its second metric (likewise)")
    p.add_argument("--scene", help="report: one scene (default: each)")
    p.add_argument("--best", type=number_arg(COUNT, int), default=10, help="report: schemes in the best table")
    p.add_argument("--spec", help="export: the sweep's spec, if it is no longer where the sweep read it "
                                  "(DIR/spec_path.txt)")


#: the libraries of ``mta sweep`` (setup.py's extra ``sweep``): import name -> distribution
LIBRARIES = {"distributed": "dask[distributed]", "pyarrow": "pyarrow", "pandas": "pandas", "SALib": "SALib"}


def missing_libraries() -> tuple[list[str], str]:
    """(the distributions of LIBRARIES that are not installed here, the first import error of
    one that is but does not import: e.g. a pyarrow built for another numpy)."""
    import importlib
    import importlib.util

    missing, broken = [], ""
    for name, dist in LIBRARIES.items():
        if importlib.util.find_spec(name) is None:
            missing.append(dist)
            continue
        try:
            importlib.import_module(name)
        except ImportError as err:
            broken = broken or f"{name}: {one_line(str(err))}"
    return missing, broken


def main(args: argparse.Namespace) -> int:
    missing, broken = missing_libraries()
    if missing:
        print(f"mta sweep: needs {', '.join(missing)}, not installed here: pip install "
              f"'mta_sim_ros[sweep]' (or {' '.join(repr(m) for m in missing)})", file=sys.stderr)
        return 1
    if broken:
        print(f"mta sweep: {broken} (installed, but it does not import here)", file=sys.stderr)
        return 1
    if args.target == "report":
        return report_main(args)
    if args.target == "export":
        return export_main(args)
    if args.items:
        fail("ARG", show(args.items[0]), "left out when running a spec (report DIR and export DIR RUN take it)")
    return run_main(args)


def run_main(args: argparse.Namespace) -> int:
    from ..config import resolve_config_path
    from ..sweep import engine, spec as sweep_spec
    from ..validate import output_folder

    for option, value in (("--out", args.out), ("--scheduler", args.scheduler), ("--scheduler-file", args.scheduler_file)):
        if value is not None and not value.strip():  # not a silent fall-back to the default
            fail(option, show(value), "not empty (left out, it takes its default)")
    if args.workers is not None:
        check_workers(args.workers)
    spec = sweep_spec.load(resolve_config_path(args.target))  # a path, or a name in the config folder
    out = output_folder(args.out or os.path.join("sweeps", spec.name), "--out")
    schemes = sweep_spec.scheme_count(spec)
    engine.ResultStore(out, spec)  # refuses a folder of another spec's results before saying anything
    if not args.quiet:
        print(f"mta sweep: {spec.name}: {schemes} schemes x {len(spec.scenes)} scenes = "
              f"{schemes * len(spec.scenes)} runs ({spec.method}), into {out}", file=sys.stderr)
    try:
        result = engine.run_sweep(spec, out, workers=args.workers, scheduler=args.scheduler,
                                  scheduler_file=args.scheduler_file, serial=args.serial, quiet=args.quiet)
    except (engine.EngineError, OSError) as err:  # a failed task or cluster, a results folder that cannot be written
        print(f"mta sweep: {one_line(str(err))}", file=sys.stderr)
        return 1
    rate = result.ran / result.wall if result.wall > 0 else 0.0
    print(f"{result.results}: {result.rows} rows ({result.ran} run now in {result.wall:.1f} s, {rate:.1f} runs/s; "
          f"{result.resumed} already there); {result.engine}")
    print(f"{result.csv}")
    if spec.bags:
        for path in write_bags(spec, out):
            print(path)
    return 0


#: a worker's resident memory at its peak, MiB (docs/benchmarks.md: 282 MiB measured, rounded up)
WORKER_MIB = 320


def check_workers(workers: int) -> None:
    """``--workers`` within what this machine can run: at most one per CPU this process may use, and
    as many as its available memory holds at WORKER_MIB each (Linux /proc/meminfo; unknown: the
    CPUs decide). Raises InputError naming both."""
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    memory = available_mib()
    most = max(1, min(cpus, memory // WORKER_MIB if memory else cpus))
    if workers > most:
        held = f", {memory / 1024:.1f} GiB available at {WORKER_MIB} MiB a worker" if memory else ""
        fail("--workers", show(workers), f"at most {most} ({cpus} CPUs this process may use{held})")


def available_mib() -> int:
    """MemAvailable of /proc/meminfo, MiB; 0 where it cannot be read."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) // 1024
    except (OSError, ValueError, IndexError):
        pass
    return 0


def report_main(args: argparse.Namespace) -> int:
    from ..sweep import report

    if len(args.items) != 1:
        fail("report", show(" ".join(args.items)) if args.items else "(missing)", "given one results folder: "
             "mta sweep report DIR")
    for path in report.make_report(args.items[0], x=args.x, y=args.y, scene=args.scene, best=args.best,
                                   out=args.out):
        print(path)
    return 0


def export_main(args: argparse.Namespace) -> int:
    from ..sweep.export import export

    if len(args.items) != 2:
        fail("export", show(" ".join(args.items)) if args.items else "(missing)",
             "given a results folder and a run: mta sweep export DIR RUN -o TRAIN.yaml")
    if not args.out:
        fail("--out", "(missing)", "given: the train file to write")
    if not args.items[1].isdigit():
        fail("RUN", show(args.items[1]), "a run index (the results' run column)")
    for path in export(args.items[0], int(args.items[1]), Path(args.out), spec_path=args.spec):
        print(path)
    return 0


def write_bags(spec, out: Path) -> list[Path]:
    """The bags of the runs the spec's ``bags:`` lists, as ``mta run`` writes them, each from its
    scheme's train and scene files (exported beside: out/bags/run-N/, sweep.export), so the bag's
    metadata holds files that repeat the run: out/bags/run-N.mcap and its report (a bag already
    there is kept: a resumed sweep). A run that fails is said, the others go on."""
    from ..sweep.export import export
    from . import run as run_tool

    written = []
    for run in sorted(spec.bags):
        bag = out / "bags" / f"run-{run}.mcap"
        if bag.exists():  # a resumed sweep: the run and its files are the same
            written.append(bag)
            continue
        folder = out / "bags" / f"run-{run}"
        folder.mkdir(parents=True, exist_ok=True)
        paths = export(out, run, folder / "train.yaml", spec_path=spec.source, all_scenes=True)
        scene = paths[1 + run % len(spec.scenes)]
        args = argparse.Namespace(scene=str(scene), bag=str(bag), report=None, method=None, step=None, rate=None,
                                  fidelity=None, split_kinks=None, frame_id="map", quiet=True)
        code = run_tool.main(args)
        if code not in (0, run_tool.EXIT_STOPPED):
            print(f"mta sweep: the bag of run {run} was not written (mta run exit {code})", file=sys.stderr)
            continue
        written.append(bag)
    return written
