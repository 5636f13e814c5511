"""``python -m benchmarks scaling``: tick cost against the number of carts and the publish rate, cost per
simulated second against the length of a run, and the peak memory of a 1-hour run. Offline (no
DDS): measurements, not tests. Prints progress to stderr; writes Markdown and PNG figures.

The tick is the node's own: a ``run_session.RunSession`` (ROS-free) on a scene file written for the
train, with the node's default parameters, recording its bag (MCAP, on the bag writer's thread as
in the node), its ``publish`` a no-op (no DDS), its clock the real steady clock. Before each tick
the two commands a steering player sends go in through ``RunSession.command`` (recorded as the
node records them; not part of the tick's time, as they are not in the node); then
``RunSession.tick`` runs, and its tick profile (``stages.py``) gives the tick's wall and thread
CPU time and the time of each of its stages. Not included: DDS and the 1 Hz diagnostics.

(a) Tick compute time against n carts (1..100) and publish rate (50, 100, 200 Hz), ticks back to
    back. max real-time factor := tick / p99(tick compute wall time): the factor by which a node
    could run faster than real time with 99 % of its ticks still inside their (shortened) period.
    Besides, the default train at 100 Hz is measured paced (one tick per 10 ms of wall time, as
    the node's timer runs it), and with the garbage collector frozen after the warm-up (as the node
    does after start-up).
(b) Cost per simulated second against simulated time: one long run (default train, 100 Hz,
    --long-duration s, 3600 by default) of the same session, in a child process; CPU time
    (process_time) and wall time every 10 s of simulated time.
(c) Peak resident memory of that run: the child's VmHWM (/proc/self/status) and ru_maxrss at its
    end, and VmRSS at every checkpoint.

Trains: ``default.yaml`` (tractor, air cart, seeder) for n = 3; n = 1 the tractor, n = 2 tractor and
air cart; n > 3 tractor, n - 2 copies of the air cart, the seeder last. The speed governor's
gains and force and power limits are scaled with the total mass so every train holds 3 m/s.
Steering: A sin(2 pi t / 60 s) with A = half the largest steering angle that still has a steady
circle for that train (at most 0.25 rad), looped; speed set-point 3 m/s with a dip to 2.5 m/s.
rk4 with step 0.01 s, or the tick where it is shorter (200 Hz).
"""
from __future__ import annotations

import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mta_sim_ros.validate import COUNT, DURATION, MAX_TICKS, Range, number_arg, output_file, path_arg

from . import scaling_report
from ..common import BENCHMARKS, header_lines, log, ros_env
from ..stages import STAGES

HELP = "tick cost vs carts and publish rate; cost per simulated second vs run length; peak memory of a 1-hour run (offline)"
CARTS = (1, 2, 3, 5, 10, 20, 50, 100)
RATES = (50.0, 100.0, 200.0)
#: s: the scenes' duration when a session runs until stopped: past any measurement, and a run of
#: it at the highest rate within validate.MAX_TICKS
ENDLESS = MAX_TICKS / max(RATES)
METHOD, STEP = "rk4", 0.01  # the node's default (config/sim.yaml, scenes)
STEER_PERIOD = 60.0  # s
CHECKPOINT = 10.0  # s of simulated time between the long run's samples


def add_arguments(p) -> None:
    p.add_argument("--ticks", type=number_arg(COUNT, int), default=4000, help="timed ticks per (carts, rate) case (default 4000)")
    p.add_argument("--paced-ticks", type=number_arg(Range.of(0, COUNT.high), int), default=1500,
                   help="ticks of the paced measurement (default train and n = 100 at 100 Hz; default 1500)")
    p.add_argument("--long-duration", type=number_arg(DURATION), default=3600.0,
                   help="simulated seconds of the long run with bag writing (default 3600)")
    p.add_argument("--out", type=path_arg(output_file), default=f"{BENCHMARKS}/scaling.md", help="Markdown report to write (PNGs beside it)")
    p.add_argument("--quick", action="store_true",
                   help="smoke run: n = 1, 3, 10; 100 Hz; 300 ticks; 100 paced; 60 s long run")
    p.add_argument("--replot", metavar="JSON", help="no measuring: rewrite --out and its figures from the raw "
                                                   "figures a run saved beside its report (<out>.json)")


# -- trains and scenes -----------------------------------------------------------------------

def _default_train_data() -> dict:
    import yaml

    from mta_sim_ros.config import config_dir

    return yaml.safe_load((config_dir() / "trains" / "default.yaml").read_text())


def default_train():
    from mta_sim_ros.config import config_dir
    from mta_sim_ros.physics.loader import load_train

    return load_train(config_dir() / "trains" / "default.yaml")


def train_data(n: int) -> dict:
    """The default train file's data cut or lengthened to n carts (see the module docstring)."""
    data = _default_train_data()
    tractor, air_cart, seeder = data["carts"]
    if n <= 2:
        carts = [tractor, air_cart][:n]
    else:
        carts = [tractor] + [dict(air_cart, name=f"air_cart_{k}") for k in range(1, n - 1)] + [seeder]
        if n == 3:
            carts[1] = air_cart
    forces = data["forces"]
    coefficient = {r["cart"]: r["coefficient"] for r in forces["rolling"]}
    names = [c["name"] for c in carts]
    scale = sum(c["mass"] for c in carts) / sum(c["mass"] for c in data["carts"])
    traction = dict(forces["traction"])
    for key in ("kp", "ki", "max_force", "max_power"):
        traction[key] *= scale
    forces = dict(traction=traction, draft=[d for d in forces["draft"] if d["cart"] in names],
                  rolling=[{"cart": name, "coefficient": coefficient.get(name, coefficient[air_cart["name"]])}
                           for name in names])
    return dict(data, name=f"{data['name']}_{n}", carts=carts, forces=forces)


def scaled_train(n: int):
    """The n-cart train of ``train_data`` as the loader reads it."""
    import yaml

    from mta_sim_ros.physics.loader import load_train_text

    data = train_data(n)
    return load_train_text(yaml.safe_dump(data), f"{data['name']}.yaml")


def steering_amplitude(train) -> float:
    """Half the largest steering angle with a steady circle for this train, at most 0.25 rad."""
    from mta_sim_ros.physics.steady import SteadyStateError, steady_circle

    lo, hi = 1e-4, min(train.actuator.max_angle, 1.5)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        try:
            steady_circle(train, mid)
            lo = mid
        except SteadyStateError:
            hi = mid
    return min(0.5 * lo, 0.25)


def scene_data(train, rate: float, duration: float, train_file: str) -> dict:
    """The bench's scene for ``train`` at ``rate`` as scene-file data."""
    amp = steering_amplitude(train)
    times = [i * 0.5 for i in range(int(STEER_PERIOD / 0.5) + 1)]
    return {"name": f"scaling_{train.n}", "train": train_file, "duration": duration, "initial": {"speed": 3.0},
            "steering": {"table": {"time": times,
                                   "angle": [amp * math.sin(2 * math.pi * t / STEER_PERIOD) for t in times]}},
            "speed": {"table": {"time": [0.0, 20.0, 22.0, 40.0, 42.0, 60.0], "speed": [3.0, 3.0, 2.5, 2.5, 3.0, 3.0]}},
            "integrator": {"method": METHOD, "step": min(STEP, 1.0 / rate)}, "publish_rate": rate}


def bench_scene(train, rate: float, duration: float):
    """The bench's scene for ``train`` (see ``scene_data``) as the loader reads it."""
    import yaml

    from mta_sim_ros.physics.loader import load_scene_text

    return load_scene_text(yaml.safe_dump(scene_data(train, rate, duration, f"{train.name}.yaml")),
                           f"scaling_{train.n}.yaml", train)


def write_scene(folder: Path, n: int, rate: float, duration: float) -> Path:
    """The n-cart train and its scene as files in ``folder`` (what the node's scene_file names)."""
    import yaml

    data = train_data(n)
    train_file = folder / f"{data['name']}.yaml"
    train_file.write_text(yaml.safe_dump(data))
    scene_file = folder / f"scaling_{n}_{rate:g}.yaml"
    scene_file.write_text(yaml.safe_dump(scene_data(scaled_train(n), rate, duration, train_file.name)))
    return scene_file


# -- the tick: the node's own ----------------------------------------------------------------

class SessionTicks:
    """The node's run session on the n-cart scene at ``rate``, recording into ``folder``; with
    ``profile`` a StageProfile hears every tick (and ``markers`` says which ticks drew markers)."""

    def __init__(self, n: int, rate: float, folder: Path, profile: bool = True, duration: float = ENDLESS):
        import logging

        from mta_sim_ros.node.params import PARAMS
        from mta_sim_ros.node.run_session import RunSession

        from ..stages import StageProfile

        cfg = {p.name: p.default for p in PARAMS}
        cfg.update(scene_file=str(write_scene(folder, n, rate, duration)), bag_dir=str(folder / "bags"),
                   publish_rate=rate, record=True)
        self.profile = StageProfile() if profile else None
        self.session = RunSession(cfg, clock=time.monotonic, publish=lambda msgs: None,
                                  log=logging.getLogger("benchmarks scaling"), profile=self.profile)
        self.n, self.resets, self.markers = n, 0, []

    def tick(self) -> None:
        """The two commands of a steering player (the scene's tables looped), then one tick; a
        model error (not expected: gentle steering) is counted and the session reset."""
        s = self.session
        command, v_set = s.sim.scheduled_inputs(math.fmod(s.sim.t, STEER_PERIOD))
        s.command("steering_angle", command)
        s.command("speed_setpoint", v_set)
        s.tick()
        if s.halted:
            log(f"n = {self.n}: {s.halted}; reset")
            self.resets += 1
            s.reset()
        elif self.profile is not None:
            self.markers.append(s.messages.ticks_since_markers == 0)


def percentiles(v) -> dict[str, float]:
    import numpy as np

    return {"p50": float(np.percentile(v, 50)), "p99": float(np.percentile(v, 99)),
            "p99.9": float(np.percentile(v, 99.9)), "max": float(v.max()), "mean": float(v.mean())}


def measure_case(n: int, rate: float, ticks: int, paced: bool = False, freeze: bool = False) -> dict:
    """Tick statistics of one (carts, rate) case: back to back, or paced one tick per period.
    ``freeze``: gc.collect(); gc.freeze() after the warm-up (what the node does after start-up:
    the collector then no longer walks the objects of numpy, scipy and rclpy at every full
    collection)."""
    import gc

    import numpy as np

    from ..stages import column

    with tempfile.TemporaryDirectory(prefix="mta_scaling_") as folder:
        run = SessionTicks(n, rate, Path(folder))
        warm = min(200, ticks // 5)
        period = 1.0 / rate
        next_start = time.perf_counter()
        with run.profile:
            for i in range(warm + ticks):
                if paced:
                    next_start += period
                    time.sleep(max(0.0, next_start - time.perf_counter()))
                if freeze and i == warm:
                    gc.collect()
                    gc.freeze()
                run.tick()
        if freeze:
            gc.unfreeze()
        run.session.close()
    data = run.profile.table(skip=warm)
    marker = np.array(run.markers[warm:])
    wall, cpu = column(data, "wall"), column(data, "thread_cpu")
    sim = run.session.sim
    res = {"n": n, "rate": rate, "tick": 1.0 / rate, "ticks": ticks, "paced": paced, "freeze": freeze,
           "resets": run.resets, "nfev_per_tick": sim.stepper.nfev / max(1, sim.ticks), "level": sim.level,
           "wall": percentiles(wall), "cpu": percentiles(cpu),
           "stages_median": {s: float(np.median(column(data, s))) for s in STAGES}}
    plain = ~marker
    res["wall_plain"] = {"p50": float(np.percentile(wall[plain], 50)), "p99": float(np.percentile(wall[plain], 99))}
    res["cpu_plain_p99"] = float(np.percentile(cpu[plain], 99))
    res["marker_tick_median"] = float(np.median(wall[marker])) if marker.any() else 0.0
    res["advance_p99"] = float(np.percentile(column(data, "advance"), 99))
    res["max_rtf"] = res["tick"] / res["wall"]["p99"]
    res["max_rtf_cpu"] = res["tick"] / res["cpu"]["p99"]  # the same with the thread's CPU time: no preemption
    res["sustained_rtf"] = res["tick"] / res["cpu"]["mean"]  # throughput: simulated s per CPU s
    return res


def rhs_costs(ns, repeats: int = 7) -> dict[int, float]:
    """us per Model.rhs call (algorithm 2) at a state of the bench's run, min over repeats."""
    from mta_sim_ros.physics.dynamics import Model
    from mta_sim_ros.run.simulation import Simulation

    out = {}
    for n in ns:
        train = scaled_train(n)
        sim = Simulation(bench_scene(train, 100.0, 1e9))
        for _ in range(300):
            sim.advance(*sim.scheduled_inputs(math.fmod(sim.t, STEER_PERIOD)))
        model, y = Model(train), sim.y.copy()
        inner = max(50, 20000 // (n + 3))
        best = math.inf
        for _ in range(repeats):
            c0 = time.thread_time()
            for _ in range(inner):
                model.rhs(0.0, y, 0.05, 3.0)
            best = min(best, (time.thread_time() - c0) / inner)
        out[n] = best * 1e6
    return out


# -- the long run (child process) ------------------------------------------------------------

def proc_status_kb(field: str) -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return float(line.split()[1])
    return math.nan


def long_run(duration: float, out_json: str) -> int:
    """The child: the default train at 100 Hz for ``duration`` simulated s with its bag (no profile:
    it would keep a row per tick)."""
    rss_start = proc_status_kb("VmRSS")
    with tempfile.TemporaryDirectory(prefix="mta_scaling_") as folder:
        run = SessionTicks(3, 100.0, Path(folder), profile=False)
        ticks, every = round(duration * 100.0), round(CHECKPOINT * 100.0)
        samples = [(0.0, time.process_time(), time.perf_counter(), proc_status_kb("VmRSS"))]
        for i in range(1, ticks + 1):
            run.tick()
            if i % every == 0 or i == ticks:
                samples.append((i / 100.0, time.process_time(), time.perf_counter(), proc_status_kb("VmRSS")))
                if i % (every * 30) == 0:
                    log(f"long run: {i / 100.0:.0f} / {duration:.0f} s simulated, RSS {samples[-1][3] / 1024:.1f} MB")
        run.session.close()
        bag_bytes = sum(p.stat().st_size for p in (Path(folder) / "bags").glob("*.mcap"))
        messages = run.session.recorder.messages
    result = {"duration": duration, "samples": samples, "rss_start_kb": rss_start,
              "vm_hwm_kb": proc_status_kb("VmHWM"), "ru_maxrss_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
              "bag_bytes": bag_bytes, "messages": messages, "resets": run.resets}
    Path(out_json).write_text(json.dumps(result))
    return 0


def run_long_child(duration: float) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "long.json"
        subprocess.run([sys.executable, "-m", "benchmarks.throughput.scaling", "--long-run", str(duration),
                        "--json", str(out)], check=True, env=ros_env(os.environ.get("ROS_DOMAIN_ID", "0")))
        return json.loads(out.read_text())


# -- the benchmark ---------------------------------------------------------------------------

def main(args) -> int:
    if args.replot:  # the figures and Markdown again from the raw figures of a run (``<out>.json``)
        raw = json.loads(Path(args.replot).read_text())
        raw["rhs"] = {int(k): v for k, v in raw["rhs"].items()}
        return scaling_report.write(Path(args.out), raw, time.monotonic())
    quick = args.quick
    carts, rates = ((1, 3, 10), (100.0,)) if quick else (CARTS, RATES)
    ticks, paced_ticks = (300, 100) if quick else (args.ticks, args.paced_ticks)
    long_duration = 60.0 if quick else args.long_duration
    started = time.monotonic()
    ms = lambda s: f"{s * 1e3:.3f} ms"  # noqa: E731
    # (a) the grid, ticks back to back; then paced, and with the garbage collector frozen
    cases = []
    for rate in rates:
        for n in carts:
            c = measure_case(n, rate, ticks)
            cases.append(c)
            w = c["wall"]
            log(f"n = {n:3d}, {rate:5.0f} Hz: p50 {ms(w['p50'])}, p99 {ms(w['p99'])}, p99.9 {ms(w['p99.9'])}, "
                f"max {ms(w['max'])}; max RTF {c['max_rtf']:.1f}")
    paced, frozen = [], []
    for n in ((3,) if quick else (3, 100)):
        paced.append(c := measure_case(n, 100.0, paced_ticks, paced=True))
        log(f"paced n = {n}, 100 Hz: p50 {ms(c['wall']['p50'])}, p99 {ms(c['wall']['p99'])}; "
            f"advance p50 {c['stages_median']['advance'] * 1e6:.0f} us")
        frozen.append(c := measure_case(n, 100.0, ticks, freeze=True))  # the collector's share of the tail
        log(f"gc.freeze() n = {n}, 100 Hz: CPU p99 {ms(c['cpu']['p99'])}, p99.9 {ms(c['cpu']['p99.9'])}, "
            f"max {ms(c['cpu']['max'])}")
    log("rhs cost per call against n")
    rhs = rhs_costs(carts)
    # (b), (c)
    log(f"long run: {long_duration:g} s simulated in a child process")
    raw = {"cases": cases, "paced": paced, "frozen": frozen, "rhs": rhs, "long": run_long_child(long_duration),
           "head": header_lines("Benchmark: scaling, long runs, memory", args)}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).with_suffix(".json").write_text(json.dumps(raw))
    return scaling_report.write(Path(args.out), raw, started)


def _child_main(argv: list[str]) -> int:
    import argparse

    p = argparse.ArgumentParser(prog="python -m benchmarks.throughput.scaling")
    p.add_argument("--long-run", type=float, required=True)
    p.add_argument("--json", required=True)
    a = p.parse_args(argv)
    return long_run(a.long_run, a.json)


if __name__ == "__main__":
    sys.exit(_child_main(sys.argv[1:]))
