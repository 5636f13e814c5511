"""Controllers in the loop over real DDS (loopback, own domain): the node and its controller as
separate processes, in lockstep (session.py's protocol), the bags read back.

What the session decides (the conversions, precedence, the protocol's steps) is tested with a set
clock in test_controllers.py; here: that an unmodified controller (``mta follow``) runs in
lockstep, that the run is a function of the commands (two runs, the same records), that it goes
faster than real time, and that cmd_vel and ackermann_cmd steer the path the equivalent Float64
commands steer."""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest
from dds import REPO, Probe, bags_in, read_bag, start_mta, start_node, start_python, stop, value, write_params
from rosgraph_msgs.msg import Clock
from test_controllers import raw_messages

from mta_sim_ros.node.run_session import message_commands
from mta_sim_ros.physics.loader import load_scene
from mta_sim_ros.run.simulation import speed_setpoint

SCENE = REPO / "config" / "scenes" / "headland_turn.yaml"
RATE = 50.0

pytestmark = pytest.mark.dds


def lockstep_params(tmp_path: Path, name: str, **extra) -> Path:
    return write_params(tmp_path / f"{name}.yaml", scene_file=str(SCENE), bag_dir=str(tmp_path / name),
                        publish_rate=RATE, lockstep=True, lockstep_timeout=5.0, record=True, **extra)


def follow_once(tmp_path: Path, name: str, probe: Probe) -> tuple[Path, float, float]:
    """One lockstep run of ``mta follow`` (node and follower as processes): its bag, and the
    simulated and wall seconds between the first and last /clock the test's node heard."""
    node = start_node(lockstep_params(tmp_path, name), tmp_path / f"{name}.log")
    heard: list[tuple[float, int]] = []  # (wall s, sim ns)
    sub = probe.node.create_subscription(
        Clock, "/clock", lambda m: heard.append((time.monotonic(), m.clock.sec * 10**9 + m.clock.nanosec)), 10)
    try:
        follower = start_mta("follow", "--passes", 2, "--length", 40)
        assert probe.spin_until(lambda: follower.poll() is not None or node.poll() is not None, 600.0), \
            "the controller did not finish"
        assert follower.returncode == 0, follower.stdout.read()
        assert "lateral error" in follower.stdout.read()
    finally:
        assert stop(node) == 0
        probe.node.destroy_subscription(sub)
    [bag] = bags_in(tmp_path / name)
    sim = (heard[-1][1] - heard[0][1]) * 1e-9
    return bag, sim, heard[-1][0] - heard[0][0]


def test_two_lockstep_runs_of_mta_follow_record_the_same_messages_faster_than_real_time(tmp_path, probe):
    """An unmodified controller (one steering command per hitch_poses received) drives the node
    in lockstep; two runs give bags whose message records are the same, bit for bit: the same
    topics, and for every topic but /diagnostics the same messages at the same log times with
    the same bytes. /diagnostics is left out of the comparison (it carries wall-time figures:
    tick compute times, the measured real-time factor, the command age), and so are /run_metadata
    (the run's record, which names each run's bag folder) and the closing metadata record (tick
    timings): none is a message of the run's physics or commands.
    Each run simulates faster than real time: more than twice as many simulated seconds as
    wall seconds between the first and last /clock heard (a bound far below what it does,
    not a timing to meet)."""
    runs = [follow_once(tmp_path, name, probe) for name in ("first", "second")]
    records = []
    for bag, _, _ in runs:
        records.append([(topic, t, bytes(data)) for topic, t, data in raw_messages(bag)
                        if topic not in ("/diagnostics", "/run_metadata")])
    first, second = records
    assert {r[0] for r in first} == {r[0] for r in second}
    assert len(first) == len(second) and first == second
    topics = {r[0] for r in first}
    assert {"/hitch_poses", "/steering_angle", "/clock", "/markers"} <= topics
    poses = sum(1 for r in first if r[0] == "/hitch_poses")
    commands = sum(1 for r in first if r[0] == "/steering_angle")
    assert poses > 40 * RATE / 3.0 / 2  # the 2 x 40 m passes and a turn at 3 m/s: well over 13 s of ticks
    assert commands in (poses - 1, poses)  # one answer a tick (the last outputs may be unanswered)
    for bag, sim, wall in runs:
        print(f"lockstep mta follow: {sim:.2f} s simulated in {wall:.2f} s wall: {sim / wall:.1f}x real time")
        assert sim > 2.0 * wall


# -- cmd_vel and ackermann_cmd against Float64 ---------------------------------------------------

#: The scripted controller: answers each new hitch_poses (by its stamp: a re-published one is not
#: answered twice) with the command of the schedule at that tick, in one of three conventions,
#: stops answering after ANSWERS ticks, and waits until the node has run the tick of its last answer.
CONTROLLER = """
    import math, sys, time, rclpy
    from geometry_msgs.msg import PoseArray, Twist
    from std_msgs.msg import Float64
    from mta_sim_ros.node.ros_msgs import QOS
    mode, V0, L1, ANSWERS = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])

    def psi(k):  # float32-exact steering angles (multiples of 2**-8 rad)
        return round(0.3 * math.sin(0.02 * k) * 256) / 256

    rclpy.init()
    node = rclpy.create_node("scripted")
    if mode == "float64":
        pub = node.create_publisher(Float64, "steering_angle", QOS)
        make = lambda p: Float64(data=p)
    elif mode == "cmd_vel":
        pub = node.create_publisher(Twist, "cmd_vel", QOS)
        def make(p):
            m = Twist()
            m.linear.x, m.angular.z = V0 * math.cos(p), V0 * math.sin(p) / L1
            return m
    elif mode == "cmd_vel_stamped":
        from geometry_msgs.msg import TwistStamped
        pub = node.create_publisher(TwistStamped, "cmd_vel", QOS)
        def make(p):
            m = TwistStamped()
            m.header.frame_id = "base_link"
            m.twist.linear.x, m.twist.angular.z = V0 * math.cos(p), V0 * math.sin(p) / L1
            return m
    else:
        from ackermann_msgs.msg import AckermannDriveStamped
        pub = node.create_publisher(AckermannDriveStamped, "ackermann_cmd", QOS)
        def make(p):
            m = AckermannDriveStamped()
            m.drive.steering_angle, m.drive.speed = p, V0 * math.cos(p)
            return m
    answered, seen = set(), []

    def on_poses(msg):
        stamp = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        seen.append(stamp)
        if stamp in answered or len(answered) >= ANSWERS:
            return
        answered.add(stamp)
        pub.publish(make(psi(len(answered))))

    node.create_subscription(PoseArray, "hitch_poses", on_poses, QOS)
    deadline = time.monotonic() + 300
    while len(answered) < ANSWERS and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    # the last answer taken before the publisher goes: the node has run its tick once it publishes
    # outputs of a later time (while it waits it publishes the last ones again, with their stamp)
    last, deadline = max(answered, default=(0, 0)), time.monotonic() + 30
    while max(seen, default=(0, 0)) <= last and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    node.destroy_node()
    rclpy.shutdown()
"""
ANSWERS = 500  # 10 s at 50 Hz: ~30 m along a varying curve


def scripted_run(tmp_path: Path, mode: str, probe: Probe) -> dict[str, list]:
    scene = load_scene(str(SCENE))
    v0, l1 = speed_setpoint(scene, 0.0), scene.train.carts[0].length
    extra = {"cmd_vel_stamped": True} if mode == "cmd_vel_stamped" else {}
    node = start_node(lockstep_params(tmp_path, mode, **extra), tmp_path / f"{mode}.log")
    try:
        code = CONTROLLER.replace("sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])",
                                  f"{mode!r}, {v0!r}, {l1!r}, {ANSWERS}")
        controller = start_python(code, tmp_path / f"{mode}-controller.log")
        assert probe.spin_until(lambda: controller.poll() is not None or node.poll() is not None, 300.0)
        assert controller.returncode == 0, (tmp_path / f"{mode}-controller.log").read_text()
    finally:
        assert stop(node) == 0
    [bag] = bags_in(tmp_path / mode)
    return read_bag(bag)


def poses(bag: dict[str, list]) -> tuple[list[int], np.ndarray]:
    times = [t for t, _ in bag["/hitch_poses"]]
    xy = np.array([[(p.position.x, p.position.y) for p in m.poses] for _, m in bag["/hitch_poses"]])
    return times, xy


def test_cmd_vel_and_ackermann_cmd_steer_the_path_of_the_equivalent_float64_commands(tmp_path, probe):
    """The same schedule of steering angles psi_k, in lockstep (so each command holds over the
    same tick in every run), sent four ways: steering_angle (the speed stays the scene's set
    speed V0), cmd_vel (v = V0 cos psi_k, omega = V0 sin psi_k / l_1: the node's bicycle relation
    gives back psi_k and V0), the same as TwistStamped to a node with cmd_vel_stamped, and
    ackermann_cmd (steering_angle = psi_k, speed = V0 cos psi_k).
    The bags hold the same ticks, and the hitch points agree:

    * cmd_vel to 1e-9 m: atan(l_1 omega / v) and v / cos psi give psi_k and V0 within a few ulps
      (1e-16 relative), which the train's stable forward motion carries to positions of order
      1e-16 x 30 m;
    * ackermann_cmd to 2^-24 x 4 x the distance run (~7e-6 m): psi_k is float32-exact, but the
      speed V0 cos psi_k rounds to float32 (relative 2^-24), so V differs from V0 by that much
      and the position along the path by at most that times the distance, with a factor 4 for
      the governor's transient and the carts behind."""
    base = scripted_run(tmp_path, "float64", probe)
    times, xy = poses(base)
    assert len(times) >= ANSWERS
    distance = float(np.sum(np.hypot(*np.diff(xy[:, 0, :], axis=0).T)))
    assert distance > 20.0
    modes = {"cmd_vel": 1e-9, "cmd_vel_stamped": 1e-9}
    if "ackermann_cmd" in message_commands():
        modes["ackermann"] = 4 * 2.0**-24 * distance
    for mode, tol in modes.items():
        bag = scripted_run(tmp_path, mode, probe)
        t, other = poses(bag)
        assert t == times, mode
        deviation = float(np.max(np.abs(other - xy)))
        print(f"{mode}: largest hitch-point deviation from the Float64 run {deviation:.3g} m (bound {tol:.3g} m)")
        assert deviation < tol, mode
        assert "/steering_angle" not in bag and len(bag["/ackermann_cmd" if mode == "ackermann" else "/cmd_vel"]) == ANSWERS
    if "ackermann" not in modes:
        pytest.fail("ackermann_msgs is not installed: ackermann_cmd not checked")


def test_a_free_running_node_takes_cmd_vel_and_ackermann_cmd_and_records_them_as_received(tmp_path, probe):
    """Taken by the tick timer (raw, as the Float64 commands are taken), counted in /diagnostics,
    and in the bag as the sender's rclpy serialized them."""
    from ackermann_msgs.msg import AckermannDriveStamped
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import Twist
    from rclpy.serialization import deserialize_message

    params = write_params(tmp_path / "p.yaml", scene_file=str(SCENE), bag_dir=str(tmp_path / "bags"),
                          publish_rate=RATE, real_time_factor=1.0, watchdog_timeout=0.0, record=True)
    node = start_node(params, tmp_path / "node.log")
    twist = Twist()
    twist.linear.x, twist.angular.z = 2.0, 0.1
    drive = AckermannDriveStamped()
    drive.header.frame_id = "base_link"
    drive.drive.steering_angle, drive.drive.steering_angle_velocity, drive.drive.speed = 0.25, 0.125, 2.5
    try:
        diagnostics = probe.subscribe("/diagnostics", DiagnosticArray)
        probe.publisher(Twist, "/cmd_vel").publish(twist)
        probe.publisher(AckermannDriveStamped, "/ackermann_cmd").publish(drive)

        def counted() -> bool:
            return bool(diagnostics) and all(value(diagnostics[-1], f"{t}_commands") == "1"
                                             for t in ("cmd_vel", "ackermann_cmd"))

        assert probe.spin_until(counted, 30.0), "the node did not count the commands"
    finally:
        assert stop(node) == 0
    [bag] = bags_in(tmp_path / "bags")
    records = {topic: data for topic, _, data in raw_messages(bag) if topic in ("/cmd_vel", "/ackermann_cmd")}
    # as received: the same message (CDR's padding bytes are whatever the sender's buffer held, so
    # the bytes are compared through rclpy's reader, field by field)
    assert deserialize_message(records["/cmd_vel"], Twist) == twist
    assert deserialize_message(records["/ackermann_cmd"], AckermannDriveStamped) == drive
