"""``python -m benchmarks sigkill``: what a SIGKILL of the node loses from its bag, in simulated time, at each
real-time factor and tick rate asked for (default 0, 1 and 4; 10 and 100 Hz).

For each combination the node runs as users run it: a separate process (``mta node``), recording,
on DDS over loopback (loopback.loopback_env) in a domain of its own, while this process listens to
its /clock. Once the node has simulated --sim-seconds it is frozen with SIGSTOP; the /clock
messages it had already sent are drained (until none comes for a while), then it gets SIGKILL.
Nothing of the node runs between the two signals, so the last /clock heard is the simulated time
at the kill (the node publishes a tick's /clock before it hands the tick to the bag writer). The
bag is rebuilt with ``recover`` and the loss is that time less the latest log time in the rebuilt
bag. Each combination is killed --repeats times, each time at a random simulated time in
[--sim-seconds, --sim-seconds + 1) (fixed seed), so the kills land at different phases of the
writer's chunks; the largest loss is reported beside the median.

The bound to compare with (recorder.py): a chunk is written once it spans FLUSH_SECONDS of log
time, and the session holds its ticks while more than BACKLOG_SECONDS of log time waits for the
writer, so a kill loses less than FLUSH_SECONDS + BACKLOG_SECONDS + one tick, whatever the speed.
"""
from __future__ import annotations

import argparse
import os
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from mta_sim_ros.node.params import argument
from mta_sim_ros.validate import COUNT, DURATION, PUBLISH_RATE, Range, number_arg, output_file, path_arg

from ..common import (
    BENCHMARKS,
    DEFAULT_SCENE,
    REPO,
    header_lines,
    log,
    resolve_scene,
    ros_env,
    table,
    write_params,
    write_report,
)

HELP = "simulated time a SIGKILL of the node loses from its bag, per rate and real-time factor"
DEFAULT_DOMAIN = 78
QUIET_SECONDS = 0.5  # after SIGSTOP: no /clock for this long means every one sent has arrived


@dataclass(frozen=True)
class Kill:
    """One SIGKILL: the node's simulated time then, and the latest log time its bag kept (s)."""

    rate: float
    factor: float
    killed_at: float
    last_logged: float

    @property
    def lost(self) -> float:
        return self.killed_at - self.last_logged


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--rates", type=number_arg(PUBLISH_RATE), nargs="+", default=[10.0, 100.0], help="tick rates, Hz (default 10 100)")
    p.add_argument("--factors", type=argument("real_time_factor"), nargs="+", default=[0.0, 1.0, 4.0],
                   help="real-time factors (default 0 1 4; 0 = as fast as possible)")
    p.add_argument("--sim-seconds", type=number_arg(DURATION), default=8.0,
                   help="simulated seconds before the kill, plus a random part of a second (default 8)")
    p.add_argument("--repeats", type=number_arg(COUNT, int), default=3, help="kills per combination (default 3)")
    p.add_argument("--scene", default=DEFAULT_SCENE, help=f"scene (default {DEFAULT_SCENE})")
    p.add_argument("--domain-id", type=number_arg(Range.of(0, 232), int), default=DEFAULT_DOMAIN,
                   help=f"ROS_DOMAIN_ID of the node and the listener (default {DEFAULT_DOMAIN})")
    p.add_argument("--out", type=path_arg(output_file), default=f"{BENCHMARKS}/sigkill.md", help="Markdown report to write")


class ClockListener:
    """This process's node in a private rclpy Context: the latest /clock it heard, and when."""

    def __init__(self, domain: int):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rosgraph_msgs.msg import Clock

        from mta_sim_ros.node.ros_msgs import QOS

        self.rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node("sigkill_bench", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.latest, self.heard_at = -1.0, time.monotonic()
        self.node.create_subscription(Clock, "/clock", self._heard, QOS)

    def _heard(self, msg) -> None:
        self.latest = max(self.latest, msg.clock.sec + msg.clock.nanosec * 1e-9)
        self.heard_at = time.monotonic()

    def spin_until(self, condition, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=0.05)
        return True

    def check_quiet(self, domain: int, seconds: float = 2.0) -> None:
        """Refuse a domain where something already publishes /clock (its time would be taken for
        the node's): listen for ``seconds`` before the first node starts."""
        if self.spin_until(lambda: self.latest >= 0, seconds):
            raise RuntimeError(f"something else publishes /clock on domain {domain}: choose another --domain-id")

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.rclpy.shutdown(context=self.context)


def start_node(params: Path, log_file: Path, domain: int) -> subprocess.Popen:
    """``mta node`` in its own process, on loopback DDS in ``domain`` (common.ros_env)."""
    with log_file.open("w") as out:
        return subprocess.Popen([sys.executable, "-m", "mta_sim_ros.cli", "node", "--params-file", str(params)],
                                env=ros_env(domain), stdout=out, stderr=subprocess.STDOUT, cwd=REPO)


def freeze_and_kill(node: subprocess.Popen, listener: ClockListener, timeout: float = 30.0) -> float:
    """SIGSTOP, drain the /clock messages already sent, SIGKILL: the node's simulated time at the
    kill (the last /clock it published)."""
    node.send_signal(signal.SIGSTOP)
    stopped = time.monotonic()
    listener.spin_until(lambda: time.monotonic() - max(listener.heard_at, stopped) > QUIET_SECONDS, timeout)
    node.send_signal(signal.SIGKILL)
    node.wait(timeout=timeout)
    return listener.latest


def measure(scene: str, rate: float, factor: float, sim_seconds: float, work: Path, domain: int,
            listener: ClockListener, timeout: float = 180.0) -> Kill:
    """Run the node at ``rate`` Hz and real-time factor ``factor`` until it has simulated
    ``sim_seconds``, kill it (freeze_and_kill), rebuild its bag: what the kill lost.

    Raises RuntimeError when the node does not get there (its log says why)."""
    from mta_sim_ros.bag import recover

    work.mkdir(parents=True, exist_ok=True)
    params = write_params(work / "params.yaml", scene_file=scene, bag_dir=str(work / "bags"), publish_rate=rate,
                          real_time_factor=factor, record=True, watchdog_timeout=0.0)
    listener.latest = -1.0
    node = start_node(params, work / "node.log", domain)
    try:
        reached = listener.spin_until(lambda: listener.latest >= sim_seconds or node.poll() is not None, timeout)
        if not reached or node.poll() is not None:
            raise RuntimeError(f"the node did not simulate {sim_seconds:g} s: {(work / 'node.log').read_text()[-2000:]}")
        killed_at = freeze_and_kill(node, listener)
    finally:
        if node.poll() is None:
            node.kill()
            node.wait()
    bags = sorted((work / "bags").glob("*.mcap"))
    if len(bags) != 1:
        raise RuntimeError(f"expected one bag in {work / 'bags'}, found {len(bags)}")
    report = recover(bags[0], work / "recovered.mcap")
    last = report["last_log_time_ns"]
    last_logged = 0.0 if last is None else last * 1e-9
    return Kill(rate, factor, max(killed_at, last_logged), last_logged)


def kills_table(kills: list[Kill]) -> list[str]:
    """The Markdown table: per rate and factor, the kills' simulated time and loss."""
    rows = []
    for rate, factor in dict.fromkeys((k.rate, k.factor) for k in kills):
        lost = [k.lost for k in kills if (k.rate, k.factor) == (rate, factor)]
        at = [k.killed_at for k in kills if (k.rate, k.factor) == (rate, factor)]
        rows.append((f"{rate:g}", f"{factor:g}", len(lost), f"{statistics.median(at):.2f}", f"{max(lost):.3f}",
                     f"{statistics.median(lost):.3f}", round(max(lost) * rate)))
    return table(rows, ["rate (Hz)", "real-time factor", "kills", "simulated s at the kill", "lost s: largest",
                        "lost s: median", "lost ticks: largest"], "r")


def main(args: argparse.Namespace) -> int:
    from mta_sim_ros.node.loopback import loopback_env
    from mta_sim_ros.node.recorder import BACKLOG_SECONDS, FLUSH_SECONDS

    os.environ.update(loopback_env(domain=args.domain_id))  # this process's listener too
    scene = resolve_scene(args.scene)
    kills: list[Kill] = []
    phases = random.Random(0)
    listener = ClockListener(args.domain_id)
    try:
        listener.check_quiet(args.domain_id)
        with tempfile.TemporaryDirectory(prefix="mta_sigkill_") as tmp:
            for rate in args.rates:
                for factor in args.factors:
                    for i in range(args.repeats):
                        kill = measure(scene, rate, factor, args.sim_seconds + phases.random(),
                                       Path(tmp) / f"{rate:g}_{factor:g}_{i}", args.domain_id, listener)
                        kills.append(kill)
                        log(f"{rate:g} Hz, real-time factor {factor:g}: killed at {kill.killed_at:.3f} s, "
                            f"bag up to {kill.last_logged:.3f} s: {kill.lost:.3f} s lost")
    except RuntimeError as err:
        print(f"benchmarks sigkill: {err}", file=sys.stderr)
        return 1
    finally:
        listener.close()
    bound = FLUSH_SECONDS + BACKLOG_SECONDS
    print("\n".join(kills_table(kills)))
    write_report(args.out, header_lines("What a SIGKILL of the node loses from its bag", args) + kills_table(kills) + [
        "",
        f"Simulated time at the kill: the last /clock the node published, heard after SIGSTOP froze it "
        f"(SIGKILL follows; nothing runs in between). Lost: that time less the latest log time in the bag "
        f"`mta recover` rebuilds. The bound: {bound:g} s + one tick (recorder.py: a chunk is written once it "
        f"spans {FLUSH_SECONDS:g} s of log time, and the ticks wait while more than {BACKLOG_SECONDS:g} s "
        f"of it waits for the writer).",
    ])
    return 0
