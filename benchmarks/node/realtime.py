"""``python -m benchmarks realtime``: the simulator node in real time (real_time_factor 1) as users run it: a
separate process, publishing and recording at 100 Hz, steered over DDS by a second process
(``player.py``) that plays the scene's own steering (and speed) table against the node's /clock,
looped, until the simulated time reaches --duration; then SIGTERM. The figures are the node's own
whole-run tick statistics (bag metadata record ``mta_sim_ros.run``). Target (the issue): no
deadline misses and tick compute p99.9 under 10 % of the tick.

``--stages`` runs the node with a tick profile (``stages.py``: the node's tick says where each of
its stages ends) and reports where the tick time goes; ``--floor`` measures the machine's noise
floor after the run. Both processes get ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and the domain
--domain-id: DDS traffic stays on loopback and off other sessions' domains.
"""
from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mta_sim_ros.validate import DURATION, PUBLISH_RATE, Range, number_arg, output_file, output_folder, path_arg

from ..common import (
    BENCHMARKS,
    DEFAULT_SCENE,
    REPO,
    cpu_seconds,
    header_lines,
    resolve_scene,
    ros_env,
    write_params,
    write_report,
)

HELP = "the node at real-time factor 1, steered over DDS; tick statistics"
DEFAULT_DOMAIN = 77
TARGET_SHARE = 0.10  # p99.9 of the tick compute time must stay under this share of the tick


def add_arguments(p) -> None:
    p.add_argument("--duration", type=number_arg(DURATION), default=600.0, help="simulated seconds to run (default 600)")
    p.add_argument("--rate", type=number_arg(PUBLISH_RATE), default=100.0, help="publish (tick) rate, Hz (default 100)")
    p.add_argument("--scene", default=DEFAULT_SCENE, help=f"scene YAML (default {DEFAULT_SCENE})")
    p.add_argument("--out", type=path_arg(output_file), default=f"{BENCHMARKS}/node_realtime.md", help="Markdown report to write")
    p.add_argument("--domain-id", type=number_arg(Range.of(0, 232), int), default=DEFAULT_DOMAIN,
                   help=f"ROS_DOMAIN_ID of the node and the player (default {DEFAULT_DOMAIN})")
    p.add_argument("--keep", metavar="DIR", type=path_arg(output_folder), help="keep the bag and logs in DIR (default: a temp dir, removed)")
    p.add_argument("--pin", action="store_true",
                   help="reserve the last CPU for the node's tick: node parameter tick_cpu = that CPU (the "
                        "node's other threads move off it) and the player started on the other CPUs")
    p.add_argument("--floor", action="store_true",
                   help="after the node's run, measure the machine's noise floor for as long: constant Python "
                        "work as long as the node's median tick, paced at the same rate on the same CPU")
    p.add_argument("--stages", action="store_true",
                   help="profile: the node's tick reports where each of its stages ends (advance, outputs, "
                        "encode, markers, publish, bag write; thread CPU time; garbage collection) and the "
                        "report says where the tick time goes (adds ~1 us per stage to every tick)")


def run_processes(args, scene_path: str, work: Path, tick_cpu: int) -> tuple[str, float, dict]:
    """Start the node and the player, wait for the player (or a failure), SIGTERM both.
    Returns (failure or '', wall seconds, {'node': CPU s, 'player': CPU s})."""
    params = write_params(work / "params.yaml", scene_file=scene_path, bag_dir=str(work / "bags"),
                          publish_rate=float(args.rate), real_time_factor=1.0, record=True, tick_cpu=tick_cpu)
    player_cpus = set(os.sched_getaffinity(0)) - {tick_cpu}
    env = ros_env(args.domain_id)
    if args.stages:
        node_cmd = [sys.executable, "-m", "benchmarks.stages", "--params-file", str(params),
                    "--stages-out", str(work / "stages.npy")]
    else:
        node_cmd = [sys.executable, "-m", "mta_sim_ros.cli", "node", "--params-file", str(params)]
    node = subprocess.Popen(node_cmd, env=env, stdout=(work / "node.log").open("w"), stderr=subprocess.STDOUT,
                            cwd=REPO)
    player = subprocess.Popen([sys.executable, "-m", "benchmarks.node.player", "--scene", scene_path,
                               "--duration", repr(args.duration), "--result", str(work / "player.json")],
                              env=env, cwd=REPO, preexec_fn=lambda: os.sched_setaffinity(0, player_cpus))
    deadline = time.monotonic() + args.duration * 1.5 + 120.0
    failure, cpu = "", {}
    started = time.monotonic()
    try:
        while player.poll() is None:
            if node.poll() is not None:
                failure = f"the node exited early (code {node.returncode}); log: {work / 'node.log'}"
                break
            if time.monotonic() > deadline:
                failure = "timed out waiting for the simulated time to reach the duration"
                break
            cpu = {"node": cpu_seconds(node.pid), "player": cpu_seconds(player.pid)}
            time.sleep(0.5)
        wall = time.monotonic() - started
    finally:
        for proc in (player, node):
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        for proc, patience in ((node, 60), (player, 30)):
            try:
                proc.wait(timeout=patience)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
                failure = failure or f"a process did not exit within {patience} s of SIGTERM"
    if node.returncode != 0 and not failure:
        failure = f"the node exited with code {node.returncode}"
    return failure, wall, cpu


def main(args) -> int:
    from mta_sim_ros.bag import read_metadata, summary
    from mta_sim_ros.physics.loader import SpecError, load_scene

    from .player import loop_period

    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    scene_path = resolve_scene(args.scene)
    try:
        scene = load_scene(scene_path)
    except SpecError as err:
        print(f"benchmarks: {err}", file=sys.stderr)
        return 2
    tick = 1.0 / args.rate
    tmp = None if args.keep else tempfile.TemporaryDirectory(prefix="mta_bench_")
    work = Path(args.keep or tmp.name)
    work.mkdir(parents=True, exist_ok=True)
    cpus = sorted(os.sched_getaffinity(0))
    tick_cpu = cpus[-1] if args.pin and len(cpus) > 1 else -1
    print(f"benchmarks realtime: scene '{scene.name}' ({scene_path}), {args.rate:g} Hz, real-time factor 1, "
          f"{args.duration:g} s of simulated time; steering table looped every {loop_period(scene):g} s; "
          f"ROS_DOMAIN_ID={args.domain_id}, discovery LOCALHOST; work dir {work}", flush=True)
    failure, wall, cpu = run_processes(args, scene_path, work, tick_cpu)
    log_text = (work / "node.log").read_text(errors="replace")
    bags = sorted((work / "bags").glob("*.mcap"))
    if failure or len(bags) != 1:
        failure = failure or f"expected one bag in {work / 'bags'}, found {len(bags)}"
        print(f"benchmarks realtime: {failure}\n"
              f"--- node log ---\n{log_text[-4000:]}", file=sys.stderr)
        return 1
    bag = bags[0]
    f = {k: float(v) for k, v in read_metadata(bag).get("mta_sim_ros.run", {}).items()}
    counts = summary(bag)
    played = json.loads((work / "player.json").read_text()) if (work / "player.json").exists() else {}
    rows, verdict, met = result_rows(f, tick, wall, cpu, played, bag, counts)

    print()
    width = max(len(r[0]) for r in rows)
    for name, value, note in rows:
        print(f"  {name:<{width}}  {value:>12}  {note}")
    print("  bag message counts:")
    for topic in sorted(counts):
        print(f"    {topic:<22} {counts[topic]['count']:>8}  {counts[topic]['type']}")
    print(verdict)

    lines = header_lines(f"Benchmark: the node in real time ({scene.name}, {args.rate:g} Hz)", args)
    lines += setup_lines(args, scene, tick, tick_cpu, loop_period(scene), set(cpus) - {tick_cpu})
    lines += ["## Result", "", "| quantity | value | |", "|---|---:|---|",
              *[f"| {a} | {b} | {c} |" for a, b, c in rows], "", f"**{verdict}**", "",
              "## Bag", "", "| topic | type | messages |", "|---|---|---:|",
              *[f"| `{t}` | {counts[t]['type']} | {counts[t]['count']} |" for t in sorted(counts)], ""]
    last_info = [line for line in log_text.splitlines() if "ticks: compute" in line]
    if last_info:
        lines += ["The node's own line at exit:", "", "```", last_info[-1].strip(), "```", ""]
    if args.floor and f.get("tick_count"):
        lines += floor_lines(noise_floor(f["tick_p50"], tick, args.duration, tick_cpu), f, tick, args, tick_cpu)
    if args.stages and (work / "stages.npy").exists():
        import numpy as np

        from ..stages import stage_report

        text, md = stage_report(np.load(work / "stages.npy"))
        print("where the tick time goes (the node's tick profile):")
        print("\n".join(text))
        lines += ["## Where the tick time goes (`--stages`: the node's tick profile, in this run)", "", *md, ""]
    write_report(args.out, lines)
    if args.keep:
        print(f"bag kept: {bag}")
    return 0 if met else 4


def result_rows(f: dict, tick: float, wall: float, cpu: dict, played: dict, bag: Path, counts: dict):
    """(rows of (quantity, value, note), verdict line, target met) of a run's figures."""
    n = int(f.get("tick_count", 0))
    misses = int(f.get("tick_deadline_misses", -1))
    p999 = f.get("tick_p99.9", math.nan)
    rtf = f["run_sim_time"] / f["run_wall_time"] if f.get("run_wall_time") else math.nan
    rows = [("ticks", f"{n}", "")]
    for prefix, label in (("tick_", "tick compute"), ("tick_cpu_", "tick thread CPU time")):
        for key in ("p50", "p99", "p99.9", "max", "mean"):
            if prefix + key in f:
                v = f[prefix + key]
                rows.append((f"{label} {key}", f"{v * 1e3:.3f} ms", f"{100 * v / tick:.1f} % of the tick"))
    if "recorder_thread_cpu" in f and n:  # the MCAP writing, on the bag writer's own thread (not in the tick)
        v = f["recorder_thread_cpu"] / n
        rows.append(("bag writer thread CPU per tick (mean; off the tick)", f"{v * 1e3:.3f} ms",
                     f"{100 * v / tick:.1f} % of the tick"))
    rows += [
        ("deadline misses (compute > tick period)", f"{misses}",
         f"tick period {f.get('tick_period', math.nan) * 1e3:.2f} ms"),
        ("achieved real-time factor (node: run sim time / run wall time)", f"{rtf:.4f}",
         f"{f.get('run_sim_time', math.nan):.2f} s sim in {f.get('run_wall_time', math.nan):.2f} s wall"),
        ("real-time factor seen by the player (/clock)", f"{played.get('rtf', math.nan):.4f}",
         f"{played.get('clocks', 0)} /clock messages received, {played.get('published', 0)} commands published"),
    ]
    for who, seconds in cpu.items():
        if seconds is not None:
            rows.append((f"{who} process CPU (user + system)", f"{seconds:.1f} s",
                         f"{100 * seconds / wall:.1f} % of one core over {wall:.0f} s wall"))
    rows.append(("bag", f"{bag.stat().st_size / 1e6:.1f} MB", f"{sum(c['count'] for c in counts.values())} messages"))
    met = misses == 0 and p999 < TARGET_SHARE * tick
    verdict = (f"target (0 deadline misses and p99.9 < {TARGET_SHARE:.0%} of the {tick * 1e3:g} ms tick = "
               f"{TARGET_SHARE * tick * 1e3:g} ms): {'MET' if met else 'MISSED'} "
               f"({misses} misses, p99.9 {p999 * 1e3:.3f} ms = {100 * p999 / tick:.1f} %)")
    return rows, verdict, met


def setup_lines(args, scene, tick: float, tick_cpu: int, period: float, player_cpus) -> list[str]:
    return [
        "## Setup", "",
        f"- node: `python -m mta_sim_ros.cli node --params-file <tmp>` with scene_file `{args.scene}` "
        f"(train `{Path(scene.train.source).name}`), publish_rate {args.rate:g} Hz (tick {tick * 1e3:g} ms), "
        f"real_time_factor 1.0, recording to a temp bag dir; other parameters as in `config/sim.yaml` "
        f"(integrator: the scene's, {scene.integrator.method} step {scene.integrator.step:g} s; markers 10 Hz; "
        f"diagnostics 1 Hz)" + ("; with `--stages` the same node with a tick profile "
                                "(`python -m benchmarks.stages`)." if args.stages else "."),
        f"- steering: a second process plays the scene's steering table"
        f"{' and speed table' if scene.speed is not None else ''} against the node's /clock (one command per "
        f"/clock message, the table at sim time mod {period:g} s), until the sim time reaches "
        f"{args.duration:g} s; then SIGTERM to the node.",
        "- figures: the node's own whole-run tick statistics, read from the bag's metadata record "
        "`mta_sim_ros.run` (compute time of the tick: advance, outputs, encode the messages, markers, "
        "publish and record; histogram percentiles within 0.5 %).",
        "- both processes: ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, their own ROS_DOMAIN_ID.",
        (f"- CPUs (`--pin`): the node's tick thread alone on CPU {tick_cpu} (node parameter tick_cpu; the "
         f"node's other threads moved off it), the player on CPUs {sorted(player_cpus)}; other processes of the "
         f"machine not moved." if tick_cpu >= 0 else
         "- CPUs: no pinning; the kernel places the node's threads and the player on any CPU."),
        "",
    ]


def noise_floor(work_seconds: float, period: float, duration: float, cpu: int) -> dict:
    """Constant pure-Python work lasting about ``work_seconds`` back to back, run once per ``period``
    for ``duration`` s (sleeping in between) on ``cpu`` (-1: anywhere); its wall-time percentiles."""
    import numpy as np

    if cpu >= 0:
        os.sched_setaffinity(0, {cpu})

    def work(n: int) -> int:
        s = 0
        for i in range(n):
            s += i * i
        return s

    n, spent = 1000, 0.0
    while spent < 0.2:  # calibrate: iterations per second, back to back
        t0 = time.perf_counter()
        work(n)
        spent = time.perf_counter() - t0
        n *= 2
    iterations = max(1, round(work_seconds * (n / 2) / spent))
    b2b = []
    for _ in range(200):
        t0 = time.perf_counter()
        work(iterations)
        b2b.append(time.perf_counter() - t0)
    times, starts = [], []
    begin = time.perf_counter()
    due = begin + period
    while due - begin < duration:
        pause = due - time.perf_counter()
        if pause > 0:
            time.sleep(pause)
        t0 = time.perf_counter()
        work(iterations)
        times.append(time.perf_counter() - t0)
        starts.append(t0 - begin)
        due = max(due + period, time.perf_counter())
    w = np.array(times)
    slow = w >= np.percentile(w, 99.9)
    return {"work": f"`sum(i * i for i < {iterations})` as a loop", "count": len(w),
            **{k: float(np.percentile(w, q)) for k, q in (("p50", 50), ("p99", 99), ("p99.9", 99.9), ("max", 100))},
            "b2b": float(np.median(b2b)), "slow_at": ", ".join(f"{t:.1f}" for t in np.array(starts)[slow])}


def floor_lines(floor: dict, f: dict, tick: float, args, tick_cpu: int) -> list[str]:
    ms = {k: floor[k] * 1e3 for k in ("p50", "p99", "p99.9", "max", "b2b")}
    print(f"noise floor: {floor['work']} ({floor['count']} times): p50/p99/p99.9/max "
          f"{ms['p50']:.3f}/{ms['p99']:.3f}/{ms['p99.9']:.3f}/{ms['max']:.3f} ms")
    return [
        "## The machine's noise floor (`--floor`, measured after the node's run)", "",
        f"The same measurement on work that never changes: {floor['work']}, calibrated to the node's median "
        f"tick ({f['tick_p50'] * 1e3:.3f} ms), run once per {tick * 1e3:g} ms with `time.sleep` in between for "
        f"{args.duration:g} s, in the bench process{f' pinned to CPU {tick_cpu}' if tick_cpu >= 0 else ''}, "
        "with no node and no player running. Whatever tail it has comes from the machine (other virtual "
        "machines on the host, the hypervisor), not from the code.", "",
        "| constant work, paced | p50 | p99 | p99.9 | max | back to back p50 |", "|---|---:|---:|---:|---:|---:|",
        f"| {floor['count']} runs | {ms['p50']:.3f} ms | {ms['p99']:.3f} ms | {ms['p99.9']:.3f} ms | "
        f"{ms['max']:.3f} ms | {ms['b2b']:.3f} ms |", "",
        f"Slowest 0.1 % at (s from the start): {floor['slow_at']}", ""]
