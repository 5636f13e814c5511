"""`mta run` as a user runs it: a separate process writing a bag, read back by two independent
readers (rosbags, and mcap + mcap_ros2), whose content must obey the train's geometry."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader

from mta_sim_ros.bag import read_messages, read_metadata
from mta_sim_ros.physics.loader import load_train

pytestmark = pytest.mark.slow  # `mta run` as processes

REPO = Path(__file__).resolve().parents[1]
DEFAULT_TRAIN = REPO / "config" / "trains" / "default.yaml"


def mta(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd or REPO, timeout=300)


def write_scene(tmp_path: Path, steering: str, duration: float, rate: float = 20.0) -> Path:
    path = tmp_path / "scene.yaml"
    path.write_text(
        f"name: test_scene\ntrain: {DEFAULT_TRAIN}\nduration: {duration}\n"
        f"initial: {{speed: 3.0}}\nsteering:\n{steering}\n"
        f"integrator: {{method: rk4, step: 0.01}}\npublish_rate: {rate}\n"
    )
    return path


LANE_CHANGE = "  maneuver: lane_change\n  params: {t0: 1.0, amplitude: 0.1, duration: 6.0}"


@pytest.fixture(scope="module")
def lane_change_bag(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("run")
    scene = write_scene(tmp, LANE_CHANGE, duration=10.0)
    bag = tmp / "lane.mcap"
    done = mta("run", "--scene", scene, "--bag", bag, "--quiet")
    assert done.returncode == 0, done.stderr
    return scene, bag


def test_bag_is_ros2_mcap_that_rosbags_and_mcap_both_decode(lane_change_bag):
    scene, bag = lane_change_bag
    ticks = 10.0 * 20.0
    expected_counts = {"/hitch_poses": ticks + 1, "/cart_velocities": ticks + 1, "/traction_power": ticks + 1,
                       "/applied_steering": ticks + 1, "/clock": ticks + 1,
                       "/steering_angle": ticks, "/speed_setpoint": ticks,
                       "/tf": ticks + 1, "/joint_states": ticks + 1, "/odom": ticks + 1,  # the frames (test_frames.py)
                       "/tf_static": 1, "/robot_description": 1}  # latched: once, at the start
    with open(bag, "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        summary = reader.get_summary()
    assert header.profile == "ros2"
    assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
    assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
    assert "MSG: geometry_msgs/Pose" in next(s.data.decode() for s in summary.schemas.values()
                                             if s.name == "geometry_msgs/msg/PoseArray")

    # reader 1: rosbags, independent of the writing library
    by_rosbags: dict[str, list] = {}
    with AnyReader([bag]) as r:
        for con, log_time, raw in r.messages():
            by_rosbags.setdefault(con.topic, []).append((log_time, r.deserialize(raw, con.msgtype)))
    assert {t: len(v) for t, v in by_rosbags.items()} == expected_counts

    # reader 2: mcap + mcap_ros2's decoder, through the package's reader
    by_mcap: dict[str, list] = {}
    for topic, log_time, msg in read_messages(str(bag)):
        by_mcap.setdefault(topic, []).append((log_time, msg))
    assert {t: len(v) for t, v in by_mcap.items()} == expected_counts
    for (t1, m1), (t2, m2) in zip(by_rosbags["/traction_power"], by_mcap["/traction_power"]):
        assert t1 == t2 and m1.data == m2.data

    # log_time is simulation time, the same as the stamps
    for log_time, msg in by_rosbags["/hitch_poses"]:
        assert log_time == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
    assert by_rosbags["/clock"][-1][1].clock.sec == 10

    # the content obeys the train: A_{k+1} = A_k - (l_k + a_k) e_k, e_k from the pose's quaternion
    train = load_train(DEFAULT_TRAIN)
    for _, msg in by_rosbags["/hitch_poses"][::20]:
        poses = msg.poses
        assert len(poses) == train.n
        for k in range(train.n - 1):
            q = poses[k].orientation
            heading = 2 * math.atan2(q.z, q.w)
            step = np.array([poses[k + 1].position.x - poses[k].position.x,
                             poses[k + 1].position.y - poses[k].position.y])
            span = train.carts[k].length + train.carts[k].hitch_offset
            np.testing.assert_allclose(step, -span * np.array([math.cos(heading), math.sin(heading)]), atol=1e-9)
    names = [c.name for c in train.carts]
    for _, msg in by_rosbags["/cart_velocities"]:
        assert list(msg.name) == names and len(msg.velocity) == train.n

    meta = read_metadata(str(bag))["mta_sim_ros"]
    assert meta["scene_yaml"] == scene.read_text()
    assert meta["train_yaml"] == DEFAULT_TRAIN.read_text()
    assert meta["method"] == "rk4"


def test_run_stopped_by_a_jackknife_keeps_a_complete_bag_and_says_where(tmp_path):
    # 0.45 rad held: R_A3 = 4.25 m < l_3 = 6 m, the seeder cannot follow (steady.py)
    scene = write_scene(tmp_path, "  table: {time: [0, 1], angle: [0, 0.45]}", duration=120.0)
    bag = tmp_path / "jk.mcap"
    done = mta("run", "--scene", scene, "--bag", bag, "--quiet")
    assert done.returncode == 3
    assert "jackknife" in done.stderr and "seeder" in done.stderr and "Traceback" not in done.stderr
    times = []
    with AnyReader([bag]) as r:
        for con, log_time, raw in r.messages(connections=[c for c in r.connections if c.topic == "/clock"]):
            times.append(log_time)
    assert len(times) > 20 and times[-1] < 120 * 10**9
    assert "stopped early" in bag.with_suffix(".md").read_text()


@pytest.mark.parametrize("content,expected", [
    ("name: x\ntrain: nowhere.yaml\nduration: 5\nsteering: {table: {time: [0], angle: [0]}}\n", "nowhere.yaml"),
    (f"name: x\ntrain: {DEFAULT_TRAIN}\nduration: -5\nsteering: {{table: {{time: [0], angle: [0]}}}}\n",
     "duration: -5"),
])
def test_bad_scene_exits_2_with_one_clear_line(tmp_path, content, expected):
    path = tmp_path / "bad.yaml"
    path.write_text(content)
    done = mta("run", "--scene", path, "--bag", tmp_path / "x.mcap")
    assert done.returncode == 2
    assert expected in done.stderr and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x.mcap").exists()


def test_help_lists_the_subcommands():
    done = mta("--help")
    assert done.returncode == 0 and "run" in done.stdout and "check" in done.stdout
    assert mta("run", "--help").returncode == 0


@pytest.mark.parametrize("command", [["run", "--bag", "x.mcap", "--scene"], ["check"]])
def test_a_scene_name_resolves_from_any_folder_as_in_every_command(tmp_path, command):
    """'scenes/reversing.yaml' names the package's scene from anywhere, as for maneuver, follow,
    session, bench and the node's scene_file."""
    done = mta(*command, "scenes/reversing.yaml", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
