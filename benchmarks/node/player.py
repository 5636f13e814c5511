"""The steering player of ``python -m benchmarks realtime``, a process of its own: on every /clock message it
publishes the scene's steering table (and speed table, if any) at the sim time modulo the scene's
loop period, and exits once the sim time reaches --duration, leaving a JSON summary in --result
(/clock messages seen, commands sent, the real-time factor it saw)."""
from __future__ import annotations

import argparse
import json
import math
import signal
import sys
import time
from pathlib import Path


def loop_period(scene) -> float:
    """The player's loop: the scene's duration (its tables, then the hold of their last values
    until the scene ends), at least the tables' ends."""
    ends = [scene.steering.time[-1]] + ([scene.speed.time[-1]] if scene.speed is not None else [])
    return max([scene.duration] + ends)


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.node.player")
    p.add_argument("--scene", required=True)
    p.add_argument("--duration", type=float, required=True)
    p.add_argument("--result", required=True)
    p.add_argument("--progress", type=float, default=10.0, help="wall seconds between progress lines")
    a = p.parse_args(argv)

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Float64

    from mta_sim_ros.physics.loader import load_scene
    from mta_sim_ros.run.simulation import table_value

    scene = load_scene(a.scene)
    period = loop_period(scene)
    rclpy.init()
    node = rclpy.create_node("mta_bench_player")
    steer = node.create_publisher(Float64, "steering_angle", 10)
    speed = node.create_publisher(Float64, "speed_setpoint", 10) if scene.speed is not None else None
    seen = {"clocks": 0, "first": None, "last": None, "published": 0}

    def on_clock(msg: Clock) -> None:
        t = msg.clock.sec + msg.clock.nanosec * 1e-9
        seen["last"] = (time.monotonic(), t)
        seen["first"] = seen["first"] or seen["last"]
        seen["clocks"] += 1
        phase = math.fmod(t, period)
        steer.publish(Float64(data=table_value(scene.steering, phase)))
        if speed is not None:
            speed.publish(Float64(data=table_value(scene.speed, phase)))
        seen["published"] += 1

    node.create_subscription(Clock, "/clock", on_clock, 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    started = time.monotonic()
    next_report = started + a.progress
    try:
        while not stop and (seen["last"] is None or seen["last"][1] < a.duration):
            executor.spin_once(timeout_sec=0.1)
            if time.monotonic() >= next_report:
                next_report += a.progress
                print(progress(seen, a.duration, started), flush=True)
    finally:
        result = dict(seen, period=period)
        (w0, t0), (w1, t1) = seen["first"] or (0, 0), seen["last"] or (0, 0)
        if w1 > w0:
            result["rtf"] = (t1 - t0) / (w1 - w0)
        Path(a.result).write_text(json.dumps(result))
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def progress(seen: dict, duration: float, started: float) -> str:
    if seen["last"] is None:
        return f"  player: waiting for /clock ({time.monotonic() - started:.0f} s)"
    (w0, t0), (w1, t1) = seen["first"], seen["last"]
    rtf = (t1 - t0) / (w1 - w0) if w1 > w0 else math.nan
    return (f"  sim t = {t1:8.2f} s of {duration:g} s  (wall {w1 - started:6.1f} s, real-time factor {rtf:.4f}, "
            f"{seen['published']} commands)")


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
