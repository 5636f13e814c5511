"""The steering flood of ``python -m benchmarks flood``, a process of its own: std_msgs/Float64 on
steering_angle at --hz for --seconds (every millisecond the commands due by then, on absolute
deadlines, so the rate holds whatever one publish costs), then a JSON summary in --result: the
steady-clock (CLOCK_MONOTONIC, shared by every process) start and end of the flood, the commands
sent and the rate reached."""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

BATCH = 1e-3  # s between two bursts of the commands due


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.node.flooder")
    p.add_argument("--hz", type=float, required=True)
    p.add_argument("--seconds", type=float, required=True)
    p.add_argument("--result", required=True)
    a = p.parse_args(argv)

    import rclpy
    from std_msgs.msg import Float64

    from mta_sim_ros.node.ros_msgs import QOS

    rclpy.init()
    node = rclpy.create_node("mta_bench_flooder")
    pub = node.create_publisher(Float64, "steering_angle", QOS)
    deadline = time.monotonic() + 30.0
    while pub.get_subscription_count() == 0:
        if time.monotonic() > deadline:
            print("flooder: nobody subscribes steering_angle", file=sys.stderr)
            return 1
        time.sleep(0.05)
    sent, start = 0, time.monotonic()
    end = start + a.seconds
    msg = Float64()
    while (now := time.monotonic()) < end:
        due = math.floor((now - start) * a.hz) + 1  # the commands due by now, the first at the start
        while sent < due:
            msg.data = 0.1 * math.sin(1e-3 * sent)  # within every scene's steering range
            pub.publish(msg)
            sent += 1
        time.sleep(max(0.0, BATCH - (time.monotonic() - start) % BATCH))  # to the next millisecond
    finished = time.monotonic()
    Path(a.result).write_text(json.dumps({"start": start, "end": finished, "sent": sent,
                                          "hz": sent / (finished - start)}))
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
