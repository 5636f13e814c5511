"""The node as users meet it: a separate process on real DDS (loopback, own domain), steered by
another process, observed by the test's own node, its bag read by rosbags.

Only what DDS or the process shows is here: topics, services and parameters end to end, exit
codes, signals, the bag on SIGTERM/SIGKILL and a full disk, namespaces. The policy behind them
(watchdog, pause and reset, pacing, diagnostics, parameter checks, bad commands, a halt) is
tested in process with a set clock in test_session.py."""
from __future__ import annotations

import math
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from bagcheck import assert_never_back
from dds import REPO, Probe, bags_in, read_bag, start_node, start_python, stop, value, write_params
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger

from mta_sim_ros.bag import DEFAULT_CHUNK_SIZE, read_metadata
from mta_sim_ros.bag import summary as bag_summary
from mta_sim_ros.node.timing import TickStats
from mta_sim_ros.physics.loader import load_scene
from mta_sim_ros.run.simulation import Simulation

SCENE = REPO / "config" / "scenes" / "headland_turn.yaml"
RATE = 50.0

pytestmark = pytest.mark.dds

STEERER = """
    import math, sys, time, rclpy
    from std_msgs.msg import Float64
    rclpy.init()
    node = rclpy.create_node("steerer")
    pub = node.create_publisher(Float64, "steering_angle", 10)
    deadline = time.monotonic() + 30
    while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    start = time.monotonic()
    while (t := time.monotonic() - start) < 3.0:
        pub.publish(Float64(data=0.2 * math.sin(1.5 * t)))
        time.sleep(0.05)
    node.destroy_node()
    rclpy.shutdown()
"""


def params(tmp_path: Path, **overrides) -> Path:
    values = dict(scene_file=str(SCENE), bag_dir=str(tmp_path / "bags"), publish_rate=RATE, real_time_factor=1.0,
                  watchdog_timeout=0.0, record=True)
    values.update(overrides)
    return write_params(tmp_path / "params.yaml", **values)


def stamp_ns(stamp) -> int:
    return stamp.sec * 10**9 + stamp.nanosec


def wait_for_output(probe: Probe, node, count=3, timeout=30.0) -> list:
    box = probe.received.get("/hitch_poses") or probe.subscribe("/hitch_poses", PoseArray)
    ok = probe.spin_until(lambda: len(box) >= count or node.poll() is not None, timeout)
    assert ok and node.poll() is None, "the node did not start publishing"
    return box


def resimulate(bag: dict[str, list]) -> dict[int, object]:
    """Offline run of the same command sequence: each tick holds the last steering command the
    node had received at the tick's start (the bag stamps commands with the sim time they arrived)."""
    sim = Simulation(load_scene(str(SCENE)), rate=RATE)
    commands = [(t, m.data) for t, m in bag.get("/steering_angle", [])]
    ends = [t for t, _ in bag["/hitch_poses"]]
    outputs, i, command = {}, 0, sim.command
    while round(sim.t * 1e9) < ends[-1]:
        t_ns = round(sim.t * 1e9)
        while i < len(commands) and commands[i][0] <= t_ns:
            command = commands[i][1]
            i += 1
        sim.advance(command, sim.v_set)
        outputs[round(sim.t * 1e9)] = sim.outputs()
    return outputs


def test_steered_over_dds_the_node_matches_the_offline_simulation(tmp_path, probe):
    node = start_node(params(tmp_path), tmp_path / "node.log")
    try:
        poses = wait_for_output(probe, node)
        power = probe.subscribe("/traction_power", Float64)
        steerer = start_python(STEERER, tmp_path / "steerer.log")
        probe.spin_until(lambda: steerer.poll() is not None, 60.0)  # receive while it steers
        assert steerer.wait(timeout=5) == 0, (tmp_path / "steerer.log").read_text()
    finally:
        assert stop(node) == 0, (tmp_path / "node.log").read_text()
    [bag_path] = bags_in(tmp_path / "bags")
    assert_never_back(bag_path)  # in file order: log times never go back
    bag = read_bag(bag_path)
    assert len(bag["/steering_angle"]) >= 40  # 20 Hz for 3 s
    # the second reader (mcap + mcap_ros2) sees the same topics and counts; one output per tick
    counts = {topic: len(v) for topic, v in bag.items()}
    assert {t: s["count"] for t, s in bag_summary(str(bag_path)).items() if s["count"]} == counts
    ticks = counts["/hitch_poses"]
    for topic in ("/cart_velocities", "/traction_power", "/applied_steering", "/clock"):
        assert counts[topic] == ticks
    assert counts["/markers"] == ticks // round(RATE / 10.0)  # marker_rate 10 Hz
    assert counts["/diagnostics"] >= 3
    expected = resimulate(bag)
    for log_time, msg in bag["/hitch_poses"]:
        out = expected[log_time]
        got = np.array([[p.position.x, p.position.y] for p in msg.poses])
        np.testing.assert_allclose(got, out.front, rtol=0, atol=1e-9)
    power_by_time = {t: m.data for t, m in bag["/traction_power"]}
    for t, out in expected.items():
        assert power_by_time[t] == pytest.approx(out.power, rel=1e-12)
    # what the test received over DDS is what the bag holds
    by_stamp = {t: m for t, m in bag["/hitch_poses"]}
    assert len(poses) > 50 and len(power) > 50
    for msg in poses:
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        assert [p.position.x for p in msg.poses] == [p.position.x for p in by_stamp[stamp].poses]
    clock = [m.clock.sec * 10**9 + m.clock.nanosec for _, m in bag["/clock"]]
    assert clock[0] > 0 and all(b > a for a, b in zip(clock, clock[1:]))
    turned = max(abs(m.data) for _, m in bag["/applied_steering"])
    assert turned > 0.1  # the commands reached the model


def test_pause_and_reset_services_reach_the_session(tmp_path, probe):
    """pause answers with the state it set, and /diagnostics shows it; reset answers with the new
    bag: two bags, and /clock goes on over the reset."""
    node = start_node(params(tmp_path, real_time_factor=2.0), tmp_path / "node.log")
    try:
        poses = wait_for_output(probe, node)
        clock = probe.subscribe("/clock", Clock)
        diags = probe.subscribe("/diagnostics", DiagnosticArray)
        reply = probe.call(SetBool, "/pause", SetBool.Request(data=True))
        assert reply.success and reply.message == "paused"
        assert probe.spin_until(lambda: any(value(d, "paused") == "True" for d in diags), 10.0)
        reply = probe.call(SetBool, "/pause", SetBool.Request(data=False))
        assert reply.success and reply.message == "running"
        assert probe.spin_until(lambda: len(clock) > 3, 10.0)
        before = stamp_ns(clock[-1].clock)
        reply = probe.call(Trigger, "/reset", Trigger.Request())
        assert reply.success and "recording" in reply.message
        n = len(poses)
        assert probe.spin_until(lambda: len(poses) > n + 3, 10.0)
        assert stamp_ns(clock[-1].clock) > before
    finally:
        assert stop(node) == 0
    bags = bags_in(tmp_path / "bags")
    assert len(bags) == 2  # a new bag for the new run
    for b in bags:
        assert len(read_bag(b)["/hitch_poses"]) > 0


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_stop_signal_leaves_a_complete_bag(tmp_path, probe, sig):
    node = start_node(params(tmp_path), tmp_path / "node.log")
    wait_for_output(probe, node, count=20)
    assert stop(node, sig) == 0
    [bag] = bags_in(tmp_path / "bags")
    data = read_bag(bag)  # needs the summary and footer: a finished file
    assert len(data["/hitch_poses"]) >= 20
    # the closing record: one tick per published pose; a thread's CPU time within a tick cannot
    # exceed the tick's wall time, so neither can any percentile of it (each estimate is within
    # TickStats.relative_error of the exact one: the two may differ by twice that)
    run = {k: float(v) for k, v in read_metadata(bag)["mta_sim_ros.run"].items()}
    assert run["tick_count"] == len(data["/hitch_poses"])
    err = TickStats().relative_error
    for q in ("p50", "p99", "max"):
        assert 0 < run[f"tick_cpu_{q}"] <= run[f"tick_{q}"] * (1 + err) / (1 - err) + 1e-6


def test_sigkill_then_recover_keeps_all_but_the_last_chunk(tmp_path, probe):
    node = start_node(params(tmp_path, real_time_factor=4.0), tmp_path / "node.log")
    poses = wait_for_output(probe, node, count=600, timeout=60)
    last_seen = max(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in poses)
    stop(node, signal.SIGKILL)
    [bag] = bags_in(tmp_path / "bags")
    with pytest.raises(Exception):
        read_bag(bag)  # no footer: not readable as it is
    fixed = tmp_path / "fixed.mcap"
    done = subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", "recover", str(bag), "-o", str(fixed)],
                          capture_output=True, text=True, cwd=REPO, timeout=60)
    assert done.returncode == 0, done.stderr
    data = read_bag(fixed)
    times = [t for t, _ in data["/hitch_poses"]]
    assert times == sorted(times) and len(times) > 100
    # what is lost is the chunk that was still in memory: bounded by the chunk size
    size_per_second = fixed.stat().st_size / ((times[-1] - times[0]) * 1e-9)
    lost_seconds = (last_seen - times[-1]) * 1e-9
    assert lost_seconds * size_per_second < 2 * DEFAULT_CHUNK_SIZE


def test_commands_reach_the_session_and_a_burst_does_not_stop_the_node(tmp_path, probe):
    """Commands go from the subscription to the session (counted in /diagnostics, recorded as
    received); a burst as fast as a process can publish leaves the node publishing."""
    node = start_node(params(tmp_path, real_time_factor=2.0), tmp_path / "node.log")
    try:
        poses = wait_for_output(probe, node)
        diags = probe.subscribe("/diagnostics", DiagnosticArray)
        pub = probe.publisher(Float64, "/steering_angle")
        pub.publish(Float64(data=math.nan))
        pub.publish(Float64(data=10.0))
        assert probe.spin_until(lambda: any(value(d, "steering_rejected") == "1" and value(d, "steering_clamped") == "1"
                                            for d in diags), 10.0)
        assert any("steering_angle" in d.status[0].message for d in diags)  # said what was wrong
        for i in range(5000):  # a burst, as fast as this process can publish
            pub.publish(Float64(data=0.05 * math.sin(i)))
        n = len(poses)
        assert probe.spin_until(lambda: len(poses) > n + 20, 20.0), "the node stopped publishing"
        assert node.poll() is None
        # keep-last-10 QoS on both ends: a burst arrives in part; only the latest command matters
        assert probe.spin_until(lambda: any(int(value(d, "steering_commands")) >= 2 + 10 for d in diags), 10.0)
    finally:
        assert stop(node) == 0
    data = read_bag(bags_in(tmp_path / "bags")[0])
    steering = [m.data for _, m in data["/steering_angle"]]
    assert math.isnan(steering[0]) and steering[1] == 10.0  # logged as received


def test_commands_taken_by_the_tick_still_say_an_incompatible_publisher(tmp_path, probe):
    """The command subscriptions are out of the executor's reach (node.TakenByTheTick) and have no
    QoS event handlers (they would wake the executor at every message): a best-effort publisher,
    which a reliable subscription cannot hear, is said by the node's 1 Hz look at the graph."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    log = tmp_path / "node.log"
    node = start_node(params(tmp_path, record=False), log)
    try:
        wait_for_output(probe, node)
        probe.node.create_publisher(Float64, "/steering_angle", QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
        assert probe.spin_until(lambda: "incompatible QoS" in log.read_text(), 20.0), log.read_text()[-2000:]
        assert node.poll() is None
    finally:
        assert stop(node) == 0


@pytest.mark.parametrize("bad,expected", [
    (dict(publish_rate=-5.0), "publish_rate"),  # refused by rclpy (the declared range)
    (dict(scene_file="/nowhere/scene.yaml"), "scene_file"),  # refused by the session
    (dict(tick_cpu=4000), "tick_cpu"),  # past this machine's last CPU (the declared range)
])
def test_invalid_parameters_stop_the_start_with_one_message(tmp_path, bad, expected):
    """Exit code 2 and one line naming the parameter (the session's checks: test_session.py)."""
    node = start_node(params(tmp_path, **bad), tmp_path / "node.log")
    assert node.wait(timeout=60) == 2
    log = (tmp_path / "node.log").read_text()
    assert expected in log and "Traceback" not in log


def _limit_file_size():
    """In the node's process: files may not grow past 300 kB (a disk that fills up mid-run);
    SIGXFSZ ignored so the write fails with EFBIG instead of killing the process."""
    import resource

    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (300_000, 300_000))


def test_a_disk_filling_up_mid_run_stops_recording_not_the_simulation(tmp_path, probe):
    node = start_node(params(tmp_path, real_time_factor=0.0), tmp_path / "node.log", preexec_fn=_limit_file_size)
    try:
        poses = wait_for_output(probe, node)
        diags = probe.subscribe("/diagnostics", DiagnosticArray)
        assert probe.spin_until(lambda: any("recording stopped" in d.status[0].message for d in diags), 60.0)
        n = len(poses)
        assert probe.spin_until(lambda: len(poses) > n + 20, 10.0), "the simulation stopped with the recording"
    finally:
        assert stop(node) == 0
    assert (tmp_path / "node.log").read_text().count("recording stopped") == 1  # logged once
    [bag] = bags_in(tmp_path / "bags")
    fixed = tmp_path / "fixed.mcap"
    done = subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", "recover", str(bag), "-o", str(fixed)],
                          capture_output=True, text=True, cwd=REPO, timeout=60)
    assert done.returncode == 0, done.stderr
    assert len(read_bag(fixed)["/hitch_poses"]) > 100  # what was logged before the disk filled


def holds_a_chunk(path) -> bool:
    """Whether the MCAP file being written at ``path`` holds a chunk of messages yet (its records
    read in order up to the tail being written)."""
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader

    try:
        with open(path, "rb") as stream:
            return any(isinstance(r, Chunk) for r in StreamReader(stream, emit_chunks=True).records)
    except Exception:  # noqa: BLE001 - the tail is mid-write: what came before it decides
        return False


def test_a_reset_on_a_full_disk_leaves_no_empty_bag_and_says_so(tmp_path, probe):
    """The disk fills mid-run (the node's file-size limit drops below its bag's size: every
    write past it fails, EFBIG, as ENOSPC would); a reset then cannot write the new bag's
    metadata. The new bag, which no message reached, is removed; the reset's answer, the log
    and /diagnostics say so; the simulation goes on; the first bag is recoverable."""
    import resource

    node = start_node(params(tmp_path, real_time_factor=4.0), None)
    try:
        poses = wait_for_output(probe, node)
        diags = probe.subscribe("/diagnostics", DiagnosticArray)
        [first] = bags_in(tmp_path / "bags")
        # a chunk of messages in the file (the bag is a run's, to be kept), then the disk is full:
        # read from the file itself (its size alone is not enough: the schemas and channels of
        # the topics written as they first appear make it grow before any chunk does)
        assert probe.spin_until(lambda: holds_a_chunk(first), 30.0)
        resource.prlimit(node.pid, resource.RLIMIT_FSIZE, (4096, 4096))  # the disk is full from now on
        assert probe.spin_until(lambda: any("recording stopped" in d.status[0].message for d in diags), 30.0)
        reply = probe.call(Trigger, "/reset", Trigger.Request())
        assert reply.success and "not recording: recording stopped" in reply.message, reply.message
        assert "held no message of this run: removed" in reply.message
        assert probe.spin_until(lambda: any("held no message of this run: removed" in d.status[0].message
                                            for d in diags), 10.0)
        n = len(poses)
        assert probe.spin_until(lambda: len(poses) > n + 20, 10.0), "the simulation stopped with the recording"
    finally:
        code = stop(node)
        log = node.stdout.read()
    assert code == 0, log
    assert bags_in(tmp_path / "bags") == [first] and list((tmp_path / "bags").iterdir()) == [first]
    errors = [line for line in log.splitlines() if "[ERROR]" in line]
    assert len(errors) == 2 and all("recording stopped" in line for line in errors), log  # each failure once
    assert "held no message of this run: removed" in errors[1], log
    fixed = tmp_path / "fixed.mcap"
    done = subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", "recover", str(first), "-o", str(fixed)],
                          capture_output=True, text=True, cwd=REPO, timeout=60)
    assert done.returncode == 0, done.stderr
    recovered = read_bag(fixed)  # the chunks that reached the disk: the run's record and its first poses
    assert len(recovered["/hitch_poses"]) > 0 and len(recovered["/run_metadata"]) == 1


def test_a_namespace_moves_every_relative_name(tmp_path, probe):
    node = start_node(params(tmp_path), tmp_path / "node.log", ros_args=["-r", "__ns:=/unit1"])
    try:
        poses = probe.subscribe("/unit1/hitch_poses", PoseArray)
        clock = probe.subscribe("/clock", Clock)
        diags = probe.subscribe("/diagnostics", DiagnosticArray)  # global by convention, published at 1 Hz
        assert probe.spin_until(lambda: len(poses) > 3 and len(clock) > 3 and diags, 30.0)
        assert probe.call(SetBool, "/unit1/pause", SetBool.Request(data=False)).success
    finally:
        assert stop(node) == 0
    topics = set(read_bag(bags_in(tmp_path / "bags")[0]))
    assert {"/unit1/hitch_poses", "/unit1/traction_power", "/clock", "/diagnostics"} <= topics


def test_a_tiny_real_time_factor_at_start_runs_the_node_standing_still(tmp_path, probe):
    node = start_node(params(tmp_path, real_time_factor=1e-12, record=False), tmp_path / "node.log")
    try:
        diags = probe.subscribe("/diagnostics", DiagnosticArray)
        assert probe.spin_until(lambda: len(diags) >= 2 or node.poll() is not None, 30.0)
        assert node.poll() is None
        assert float(value(diags[-1], "sim_time_s")) == 0.0 and float(value(diags[-1], "tick_period_ms")) > 1e12
    finally:
        assert stop(node) == 0


def test_parameters_end_to_end(tmp_path, probe):
    """The table's ranges and notes reach ROS (describe); a fixed parameter and an out-of-range
    value are refused with a reason; real_time_factor and frame_id change live (the tick timer
    follows; hitch_poses and markers carry the new frame)."""
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import DescribeParameters, SetParameters
    from visualization_msgs.msg import MarkerArray

    node = start_node(params(tmp_path), tmp_path / "node.log")
    try:
        poses = wait_for_output(probe, node)
        markers = probe.subscribe("/markers", MarkerArray)
        described = probe.call(DescribeParameters, "/mta_sim/describe_parameters",
                               DescribeParameters.Request(names=["real_time_factor", "publish_rate"])).descriptors
        assert [(r.from_value, r.to_value) for r in described[0].floating_point_range] == [(0.0, 1000.0)]
        assert described[1].description.endswith("(fixed while running)")

        def set_param(name, value):
            v = (ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value) if isinstance(value, float)
                 else ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value))
            request = SetParameters.Request(parameters=[Parameter(name=name, value=v)])
            return probe.call(SetParameters, "/mta_sim/set_parameters", request).results[0]

        refused = set_param("publish_rate", 20.0)
        assert not refused.successful and "cannot change while running" in refused.reason
        assert not set_param("real_time_factor", -1.0).successful
        clock = probe.subscribe("/clock", Clock)
        for tiny in (1e-12, 5e-324):  # inside the range: once a timer period rclpy could not hold
            assert set_param("real_time_factor", tiny).successful
            n = len(clock)
            probe.spin_until(lambda: False, 0.3)
            assert node.poll() is None and len(clock) <= n + 1  # alive, (nearly) standing still
        assert set_param("real_time_factor", 3.0).successful
        assert probe.spin_until(lambda: len(clock) > 100, 10.0)  # still ticking, now faster

        assert probe.spin_until(lambda: markers, 10.0)
        assert poses[-1].header.frame_id == "map" and markers[-1].markers[0].header.frame_id == "map"
        assert set_param("frame_id", "odom").successful
        n, m = len(poses), len(markers)
        assert probe.spin_until(lambda: len(poses) > n + 5 and len(markers) > m + 2, 10.0)
        assert poses[-1].header.frame_id == "odom"
        assert {mk.header.frame_id for mk in markers[-1].markers} == {"odom"}
        assert stamp_ns(poses[-1].header.stamp) > stamp_ns(poses[n - 1].header.stamp)
    finally:
        assert stop(node) == 0
