"""What every benchmark shares: the report's header (command, date, machine), writing the report,
progress lines, resolving a scene path, the environment of child processes (DDS on loopback),
the node's parameters file and a child's CPU time, timing several variants side by side, and
generated trains."""
from __future__ import annotations

import datetime
import json
import math
import os
import platform
import shlex
import sys
import time
from pathlib import Path

from mta_sim_ros.physics.spec import Actuator, Cart, Draft, Rolling, Traction, Train

REPO = Path(__file__).resolve().parents[1]
BENCHMARKS = "docs/benchmarks"  # where the reports go by default, from the repository
DEFAULT_SCENE = "scenes/headland_turn.yaml"
#: namespace fields that are argparse plumbing, not options of a benchmark
_PLUMBING = {"command", "func", "bench", "bench_func", "ros_args"}


def log(msg: str) -> None:
    """A progress line (stderr, so that a benchmark's figures on stdout stay clean)."""
    print(msg, file=sys.stderr, flush=True)


def machine() -> dict[str, str]:
    """CPU count and model, Python, platform and load average: what a figure depends on."""
    model = ""
    try:
        model = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                      if line.startswith("model name")), "")
    except OSError:
        pass
    try:
        load = " / ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        load = "?"
    return {"nproc": str(os.cpu_count()), "cpu": model or platform.processor() or "?",
            "python": platform.python_version(), "platform": platform.platform(), "load": load}


def command_line(args) -> list[str]:
    """``python -m benchmarks <name>`` with every option of ``args`` spelled out (defaults too), so
    that a report says exactly what made it."""
    argv = ["python", "-m", "benchmarks", args.bench]
    for dest, value in vars(args).items():
        if dest in _PLUMBING or value is None or value is False:
            continue
        flag = "--" + dest.replace("_", "-")
        if value is True:
            argv.append(flag)
        elif isinstance(value, (list, tuple)):
            argv += [flag, *map(str, value)]
        else:
            argv += [flag, f"{value:g}" if isinstance(value, float) else str(value)]
    return argv


def header_lines(title: str, args) -> list[str]:
    """The report's title and the table of how it was made."""
    m = machine()
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    source = args.bench_func.__module__.replace(".", "/") + ".py"
    return [
        f"# {title}", "",
        f"Written by `{source}`; re-run the command to refresh it.", "",
        "| | |", "|---|---|",
        f"| command | `{shlex.join(command_line(args))}` |",
        f"| date | {now} |",
        f"| machine | {m['nproc']} CPUs ({m['cpu']}), {m['platform']} |",
        f"| python | {m['python']} |",
        f"| load average at start (1/5/15 min) | {m['load']} |",
        "",
    ]


def table(rows, header, align: str = "") -> list[str]:
    """A Markdown table of ``rows`` (cells, any type) under ``header``; ``align``: 'l' or 'r' a
    column, the last letter for the columns after it (default: every column left)."""
    marks = ["---:" if a == "r" else "---" for a in align.ljust(len(header), (align or "l")[-1])]
    return ["| " + " | ".join(header) + " |", "|" + "|".join(marks) + "|",
            *("| " + " | ".join(str(c) for c in r) + " |" for r in rows)]


def write_report(path, lines: list[str]) -> Path:
    """Write a Markdown report (its folder made if needed) and say where."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")
    print(f"report: {out}", flush=True)
    return out


def resolve_scene(path: str) -> str:
    """A scene path as the node takes it (from the working directory or the config folder), absolute."""
    from mta_sim_ros.config import resolve_config_path

    return str(Path(resolve_config_path(path)).resolve())


def ros_env(domain: int) -> dict[str, str]:
    """The environment of a child process that talks DDS: loopback.loopback_env (discovery on this
    host, the Fast DDS loopback profile, no static peers elsewhere), its own domain, this checkout
    importable."""
    from mta_sim_ros.node.loopback import loopback_env

    env = loopback_env(domain=domain)
    env["PYTHONUNBUFFERED"] = "1"
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH", "")) if p)
    return env


def write_params(path: Path, **params) -> Path:
    """A ROS parameters file for the node 'mta_sim'."""
    lines = ["mta_sim:", "  ros__parameters:"]
    for k, v in params.items():
        value = ("true" if v else "false") if isinstance(v, bool) else json.dumps(v) if isinstance(v, str) else v
        lines.append(f"    {k}: {value}")
    path.write_text("\n".join(lines) + "\n")
    return path


def cpu_seconds(pid: int) -> float | None:
    """User + system CPU time of a live process, s (from /proc)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return None


def side_by_side(variants: dict, rounds: int, calls: int = 1, clock=time.perf_counter) -> dict[str, list[float]]:
    """Seconds per call of each variant (label -> function of no arguments), one figure per round:
    the variants take turns within every round, so that all of them see the same machine.
    ``clock`` None: each call returns the seconds it measured itself (e.g. a run without its set-up)."""
    times: dict[str, list[float]] = {label: [] for label in variants}
    for _ in range(rounds):
        for label, fn in variants.items():
            if clock is None:
                times[label].append(sum(fn() for _ in range(calls)) / calls)
                continue
            t0 = clock()
            for _ in range(calls):
                fn()
            times[label].append((clock() - t0) / calls)
    return times


# -- generated trains ----------------------------------------------------------------------------------

#: the generated trains' traction
GOVERNOR = Traction("governor", set_speed=3.0, max_force=125000.0, max_power=250000.0, kp=60000.0, ki=30000.0)


def random_train(n: int, rng) -> Train:
    """n carts of random size and mass (lengths 2-7 m, each hitch 1.5 m ahead of to 2 m behind its
    cart's axle), rolling resistance on each, a draft with a speed term on the last cart and one on
    the second: the throughput benchmarks' schemes and the reversing envelope's trains."""
    carts = tuple(Cart(f"cart{k + 1}", rng.uniform(2.0, 7.0), rng.uniform(-1.5, 2.0), rng.uniform(0.3, 2.5),
                       rng.uniform(2e3, 2e4), rng.uniform(1e4, 1e5)) for k in range(n))
    drafts = (Draft(carts[-1].name, A=2500.0, B=40.0, C=2.0, width=12.0, depth=1.0),)
    if n > 2:
        drafts += (Draft("cart2", A=rng.uniform(20, 60), B=2.8, C=0.0, soil_factor=1.0, width=20.0, depth=8.0),)
    return Train(name="bench", carts=carts, traction=GOVERNOR, rolling=tuple(Rolling(c.name, 0.08) for c in carts),
                 draft=drafts, actuator=Actuator(time_constant=0.2, max_rate=0.6, max_angle=math.radians(40.0)))
