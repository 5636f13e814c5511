"""The train's frames and robot model for ROS tools (urdf.py, messages/frames.py): /tf,
/tf_static, joint_states, odom and robot_description.

Every check holds the frames to what cannot drift: the hitch poses the simulator publishes
(hitch_poses: A_k and th_k of every cart), the closed forms of the kinematics (B_k = A_k - l_k e_k;
a rear axle without side slip turns at th' = v_B tan(psi_1) / l_1; the steady circle R_B1 = l_1 /
tan psi_1), the train file's numbers, and an independent reader of the URDF (yourdfpy), whose
forward kinematics at the published joint states must give the published frames. The
transforms are composed here from their fields, not by the code under test. In process (the
encoders, a session, the offline run's bag) and, at the end, from a running node over real DDS
(loopback, own domain) in a namespace, its bag included.
"""
from __future__ import annotations

import dataclasses
import io
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yourdfpy
from bagcheck import assert_never_back
from cdr_refs import rosbags_decode
from rosbags.highlevel import AnyReader
from test_session import FakeClock, Log
from trains import scene as make_scene

from mta_sim_ros import cli
from mta_sim_ros.bag import read_messages, stamp
from mta_sim_ros.messages import FrameEncoder
from mta_sim_ros.messages.topics import FRAME_TOPICS, LATCHED_TOPICS, RUN_METADATA_TOPIC, qualified
from mta_sim_ros.messages.urdf import frame_prefix, robot_model
from mta_sim_ros.physics.outline import BOX_HEIGHT
from mta_sim_ros.node.params import PARAMS, ConfigError
from mta_sim_ros.node.run_session import RunSession
from mta_sim_ros.physics import terrain
from mta_sim_ros.physics.loader import load_scene, load_train
from mta_sim_ros.run.simulation import Simulation
from mta_sim_ros.validate import InputError

REPO = Path(__file__).resolve().parents[1]
TRAIN = REPO / "config" / "trains" / "default.yaml"
TOL = 1e-9  # m and rad


# -- composing transforms by hand ------------------------------------------------------------
def planar(tf) -> tuple[float, float, float]:
    """(x, y, yaw) of a geometry_msgs/TransformStamped that lies in the plane (checked)."""
    t, r = tf.transform.translation, tf.transform.rotation
    assert t.z == 0.0 and r.x == 0.0 and r.y == 0.0, tf.child_frame_id
    assert abs(r.z ** 2 + r.w ** 2 - 1.0) < 1e-15
    return t.x, t.y, 2.0 * math.atan2(r.z, r.w)


def compose(a, b):
    ax, ay, ath = a
    bx, by, bth = b
    c, s = math.cos(ath), math.sin(ath)
    return ax + c * bx - s * by, ay + s * bx + c * by, ath + bth


def tree(transforms, root: str) -> dict[str, tuple[float, float, float]]:
    """Every frame the transforms (parent -> child) reach from ``root``: its (x, y, yaw) in root.
    Each frame has one parent (a tree)."""
    children: dict[str, list] = {}
    parents: dict[str, str] = {}
    for tf in transforms:
        assert parents.setdefault(tf.child_frame_id, tf.header.frame_id) == tf.header.frame_id, tf.child_frame_id
        children.setdefault(tf.header.frame_id, []).append(tf)
    poses, todo = {root: (0.0, 0.0, 0.0)}, [root]
    while todo:
        frame = todo.pop()
        for tf in children.get(frame, []):
            assert tf.child_frame_id not in poses, f"{tf.child_frame_id} twice"
            poses[tf.child_frame_id] = compose(poses[frame], planar(tf))
            todo.append(tf.child_frame_id)
    return poses


def yaw_of(q) -> float:
    return 2.0 * math.atan2(q.z, q.w)


def wrap(angle: float) -> float:
    return math.remainder(angle, 2.0 * math.pi)


def hitch_pose_list(pose_array) -> list[tuple[float, float, float]]:
    return [(p.position.x, p.position.y, yaw_of(p.orientation)) for p in pose_array.poses]


def assert_close(got, want, what: str) -> None:
    x, y, th = got
    wx, wy, wth = want
    assert math.hypot(x - wx, y - wy) <= TOL and abs(wrap(th - wth)) <= TOL, f"{what}: {got} != {want}"


def assert_frames_are_the_hitch_poses(frames: dict, poses: list, train, prefix: str) -> None:
    """Each cart's frame at B_k = A_k - l_k e_k along th_k, its hitch frame (the tractor's front
    wheels: the position only) at A_k, base_link = the tractor's frame; (x, y, yaw) in the
    frame of the hitch poses."""
    for k, cart in enumerate(train.carts):
        ax, ay, th = poses[k]
        assert_close(frames[prefix + cart.name], (ax - cart.length * math.cos(th), ay - cart.length * math.sin(th), th),
                     cart.name)
        if k:
            assert_close(frames[prefix + cart.name + "_hitch"], (ax, ay, th), cart.name + "_hitch")
        else:
            x, y, _ = frames[prefix + cart.name + "_front_wheels"]
            assert math.hypot(x - ax, y - ay) <= TOL
    assert frames[prefix + "base_link"] == frames[prefix + train.carts[0].name]


def urdf_of(text: str) -> yourdfpy.URDF:
    return yourdfpy.URDF.load(io.StringIO(text), load_meshes=False, build_collision_scene_graph=False)


def assert_urdf_kinematics_give_the_frames(model: yourdfpy.URDF, joint_state, frames: dict, base: str) -> None:
    """yourdfpy's forward kinematics at the joint state, from the base frame's pose, give every
    link's frame."""
    model.update_cfg(dict(zip(joint_state.name, [float(p) for p in joint_state.position])))
    bx, by, bth = frames[base]
    for link in model.link_map:
        m = model.get_transform(frame_to=link, frame_from=base)
        assert np.allclose(m[2, :3], [0, 0, 1], atol=1e-15) and abs(m[2, 3]) < 1e-15, link  # in the plane
        want = compose((bx, by, bth), (m[0, 3], m[1, 3], math.atan2(m[1, 0], m[0, 0])))
        assert_close(frames[link], want, link)


# -- the robot model -----------------------------------------------------------------------------
def test_the_robot_model_is_the_same_wherever_the_train_file_lies(tmp_path):
    """The URDF names the train file by its name, never its folder: copied elsewhere, the same model."""
    here = robot_model(load_train(TRAIN)).urdf
    (tmp_path / "deep" / "er").mkdir(parents=True)
    there = robot_model(load_train(shutil.copy(TRAIN, tmp_path / "deep" / "er" / "default.yaml"))).urdf
    assert here == there and "from default.yaml," in here
    assert str(REPO) not in here and str(tmp_path) not in there


def test_the_prefix_comes_from_the_namespace():
    assert [frame_prefix(ns) for ns in ("/", "", "/unit1", "/fleet/unit1/")] == ["", "", "unit1/", "fleet/unit1/"]


def test_the_urdf_read_by_yourdfpy_has_the_train_s_links_joints_limits_and_inertia():
    train = load_train(TRAIN)
    robot = robot_model(train, "unit1/")
    model = urdf_of(robot.urdf)
    assert model.base_link == "unit1/base_link"
    names = [c.name for c in train.carts]  # tractor, air_cart, seeder
    assert set(model.link_map) == {"unit1/base_link", *("unit1/" + n for n in names),
                                   "unit1/air_cart_hitch", "unit1/seeder_hitch", "unit1/tractor_front_wheels"}
    joints = model.joint_map
    steer = joints["unit1/tractor_steering_joint"]
    assert (steer.type, steer.parent, steer.child) == ("revolute", "unit1/tractor", "unit1/tractor_front_wheels")
    assert list(steer.axis) == [0, 0, 1] and steer.origin[0, 3] == train.carts[0].length
    assert (steer.limit.lower, steer.limit.upper) == (-math.radians(40), math.radians(40))
    assert steer.limit.velocity == train.actuator.max_rate
    for k in (1, 2):
        hitch = joints[f"unit1/{names[k]}_hitch_joint"]
        assert (hitch.type, hitch.parent, hitch.child) == ("revolute", f"unit1/{names[k - 1]}", f"unit1/{names[k]}_hitch")
        assert list(hitch.axis) == [0, 0, -1]  # position = th_{k-1} - th_k
        assert hitch.origin[0, 3] == -train.carts[k - 1].hitch_offset
        assert (hitch.limit.lower, hitch.limit.upper) == (-math.radians(80), math.radians(80))  # max_hitch_angle_deg
        fixed = joints[f"unit1/{names[k]}_joint"]
        assert (fixed.type, fixed.origin[0, 3]) == ("fixed", -train.carts[k].length)
    assert joints["unit1/tractor_joint"].type == "fixed" and np.array_equal(joints["unit1/tractor_joint"].origin, np.eye(4))
    assert robot.joint_names == ["unit1/air_cart_hitch_joint", "unit1/seeder_hitch_joint", "unit1/tractor_steering_joint"]
    widths = (2.5, 2.5, 12.0)  # the markers' widths: the seeder's draft width 12 m, else 2.5 m
    for k, cart in enumerate(train.carts):
        link = model.link_map["unit1/" + cart.name]
        length = cart.length + max(cart.hitch_offset, 0.0)  # A_k back to the rearmost of B_k and A_{k+1}
        for part in (link.visuals[0], link.collisions[0]):
            assert list(part.geometry.box.size) == [length, widths[k], BOX_HEIGHT]
        inertial = link.inertial
        assert inertial.mass == cart.mass
        assert list(inertial.origin[:3, 3]) == [cart.com_offset, 0.0, BOX_HEIGHT / 2]
        ixx, iyy, izz = np.diag(inertial.inertia)
        assert izz == cart.yaw_inertia and np.count_nonzero(inertial.inertia - np.diag(np.diag(inertial.inertia))) == 0
        assert ixx > 0 and iyy > 0 and ixx + iyy >= izz and ixx + izz >= iyy and iyy + izz >= ixx  # physical
    assert model.link_map["unit1/base_link"].inertial is None  # KDL wants a root without mass


@pytest.mark.parametrize("name", ["base_link", "odom", "air_cart_hitch", "a b"])
def test_a_cart_name_that_makes_a_frame_twice_or_no_frame_is_refused_in_one_line(name):
    train = load_train(TRAIN)  # tractor, air_cart, seeder: the seeder renamed
    carts = (*train.carts[:2], dataclasses.replace(train.carts[2], name=name))
    with pytest.raises(InputError) as err:
        robot_model(dataclasses.replace(train, carts=carts), "unit1/")
    message = str(err.value)
    assert "\n" not in message and f"name: {name!r}" in message.replace('"', "'") and "carts[2]" in message, message


@pytest.mark.parametrize("namespace", ["/unit 1", "/1unit", "//a"])
def test_mta_urdf_refuses_a_namespace_no_node_could_have_in_one_line(namespace):
    done = subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", "urdf", "--namespace", namespace],
                          capture_output=True, text=True, cwd=REPO, timeout=60)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.startswith(f"mta urdf: --namespace: {namespace!r} must be a ROS namespace")
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr


# -- the encoders, in process ------------------------------------------------------------------
def decoded(msgs: dict[str, bytes]) -> dict:
    """The frames' messages (topic -> CDR bytes) decoded by rosbags."""
    return {topic: rosbags_decode(FRAME_TOPICS[topic], data) for topic, data in msgs.items()}


def samples_of(scene, ticks_at):
    sim = Simulation(scene)
    samples = []
    while sim.ticks < max(ticks_at):
        sim.advance(*sim.scheduled_inputs(sim.t))
        if sim.ticks in ticks_at:
            samples.append(sim.outputs())
    return scene, samples


@pytest.fixture(scope="module")
def turning():
    """The default train in the lane change, mid-manoeuvre (hitch angles of both signs over it)."""
    scene, samples = samples_of(load_scene(REPO / "config" / "scenes" / "lane_change.yaml"), (1, 300, 360, 420, 499))
    assert max(abs(s.hitch_angle).max() for s in samples) > 0.02
    return scene, samples


@pytest.fixture(scope="module", params=["single_tractor", "offset_hitch", "long_train"])
def other_train(request):
    """A train of 1 cart, one hitched ahead of its axle (a < 0), one of 5 carts: steered left then right."""
    train = load_train(REPO / "config" / "trains" / f"{request.param}.yaml")
    return samples_of(make_scene(train, table=((0.0, 2.0, 5.0), (0.0, 0.3, -0.2)), rate=50.0), (1, 150, 300))


def pose_list(out) -> list[tuple[float, float, float]]:
    return [(float(x), float(y), float(th)) for (x, y), th in zip(out.front, out.heading)]


def assert_encoded_frames(scene, samples, frame_id: str, prefix: str = "") -> None:
    """The FrameEncoder's messages of each sample (decoded by rosbags) give the hitch poses, by
    composing /tf_static and /tf and by the URDF's kinematics at joint_states."""
    robot = robot_model(scene.train, prefix)
    enc = FrameEncoder(robot, frame_id)
    static = decoded(enc.latched(12.5))
    assert static["robot_description"].data == robot.urdf
    fixed = static["/tf_static"].transforms
    model = urdf_of(static["robot_description"].data)
    for out in samples:
        msgs = decoded(enc.encode(out))
        frames = tree([*fixed, *msgs["/tf"].transforms], frame_id)
        assert_frames_are_the_hitch_poses(frames, pose_list(out), scene.train, prefix)
        assert_urdf_kinematics_give_the_frames(model, msgs["joint_states"], frames, prefix + "base_link")
        for header in [t.header for t in msgs["/tf"].transforms] + [msgs["joint_states"].header, msgs["odom"].header]:
            assert {"sec": header.stamp.sec, "nanosec": header.stamp.nanosec} == stamp(out.t)


@pytest.mark.parametrize("frame_id", ["map", "odom"])
def test_the_encoded_frames_are_the_hitch_poses_and_the_urdf_s_kinematics(turning, frame_id):
    scene, samples = turning
    assert_encoded_frames(scene, samples, frame_id)
    fixed = decoded(FrameEncoder(robot_model(scene.train), frame_id).latched(12.5))
    fixed = fixed["/tf_static"].transforms
    assert {(t.header.frame_id, t.child_frame_id) for t in fixed} == (
        {("base_link", "tractor"), ("air_cart_hitch", "air_cart"), ("seeder_hitch", "seeder")}
        | ({("map", "odom")} if frame_id == "map" else set()))
    assert all((t.header.stamp.sec, t.header.stamp.nanosec) == (12, 500_000_000) for t in fixed)


def test_the_frames_of_other_trains_are_their_hitch_poses(other_train):
    scene, samples = other_train
    assert_encoded_frames(scene, samples, "map", "fleet/unit7/")


def test_joint_states_are_the_hitch_angles_of_the_poses_their_rates_and_the_steering(turning):
    scene, samples = turning
    robot = robot_model(scene.train)
    enc = FrameEncoder(robot)
    act = scene.train.actuator
    for out in samples:
        js = decoded(enc.encode(out))["joint_states"]
        assert list(js.name) == robot.joint_names and len(js.effort) == 0
        th = [p[2] for p in pose_list(out)]
        for k in (1, 2):  # th_{k-1} - th_k from the headings; its rate from the carts' yaw rates
            assert abs(wrap(js.position[k - 1] - (th[k - 1] - th[k]))) <= TOL
            assert js.velocity[k - 1] == pytest.approx(out.yaw_rate[k - 1] - out.yaw_rate[k], abs=1e-12)
        assert js.position[2] == out.steering
        target = min(max(out.command, -act.max_angle), act.max_angle)  # the actuator law, spec.Actuator
        assert js.velocity[2] == min(max((target - out.steering) / act.time_constant, -act.max_rate), act.max_rate)


def test_the_steering_joint_moves_at_a_rate_limit_held_as_an_input():
    """An ackermann_cmd's steering_angle_velocity is a rate limit held beside the command
    (Simulation.set_rate_limit): the steering joint's velocity is the actuator's under that limit,
    and the angle moves at it over the tick (the train's own max_rate would be 10 times more)."""
    scene = load_scene(REPO / "config" / "scenes" / "straight_pass.yaml")
    sim = Simulation(scene, fidelity="dynamic")
    rate = scene.train.actuator.max_rate / 10
    psi0 = sim.y[sim.model.layout.steering]
    sim.set_rate_limit(rate)
    sim.advance(psi0 + 0.3, 3.0)  # a step the held limit closes in far more than a tick
    out = sim.outputs()
    js = decoded(FrameEncoder(robot_model(scene.train)).encode(out))["joint_states"]
    assert js.velocity[-1] == out.steering_rate == rate
    assert out.steering - psi0 == pytest.approx(rate * sim.tick, rel=1e-12)


def test_odometry_in_a_steady_turn_is_the_rear_axle_on_its_closed_form_circle():
    """steady_turn: psi_1 = 0.15 rad held, settled after 60 s: the odometry is B_1 and th_1, its
    twist in base_link turns at v_B tan(psi_1) / l_1 about the circle R_B1 = l_1 / tan psi_1."""
    scene = load_scene(REPO / "config" / "scenes" / "steady_turn.yaml")
    sim = Simulation(scene)
    while sim.t < 60.0:
        sim.advance(*sim.scheduled_inputs(sim.t))
    out = sim.outputs()
    l1 = scene.train.carts[0].length
    odom = decoded(FrameEncoder(robot_model(scene.train, "u/")).encode(out))["odom"]
    assert (odom.header.frame_id, odom.child_frame_id) == ("u/odom", "u/base_link")
    (ax, ay), th = out.front[0], float(out.heading[0])
    p = odom.pose.pose
    assert_close((p.position.x, p.position.y, yaw_of(p.orientation)),
                 (ax - l1 * math.cos(th), ay - l1 * math.sin(th), th), "odom")
    tw = odom.twist.twist
    assert (tw.linear.y, tw.linear.z, tw.angular.x, tw.angular.y) == (0.0, 0.0, 0.0, 0.0)
    psi = 0.15
    assert tw.linear.x == pytest.approx(out.speed * math.cos(psi), rel=1e-9)  # s'_B1 = V cos psi_1
    assert tw.angular.z == pytest.approx(tw.linear.x * math.tan(psi) / l1, rel=1e-9)
    assert tw.linear.x / tw.angular.z == pytest.approx(l1 / math.tan(psi), rel=1e-9)  # R_B1
    assert not any(odom.pose.covariance) and not any(odom.twist.covariance)


# -- a session, in process -----------------------------------------------------------------------
def session(tmp_path, namespace="/", **overrides) -> tuple[RunSession, list]:
    cfg = {p.name: p.default for p in PARAMS}
    cfg.update(scene_file=str(REPO / "config/scenes/headland_turn.yaml"), bag_dir=str(tmp_path / "bags"),
               publish_rate=50.0, watchdog_timeout=0.0, record=False)
    cfg.update(overrides)
    published: list[dict] = []
    clock = FakeClock()
    return RunSession(cfg, clock=clock, publish=published.append, log=Log(), namespace=namespace, background=False,
                      compute_clock=clock, cpu_clock=clock), published


def test_without_cart_frames_the_session_leaves_the_joints_to_robot_state_publisher(tmp_path):
    s, published = session(tmp_path, "/unit2", publish_cart_frames=False)
    assert set(published[0]) | set(published[1]) == set(LATCHED_TOPICS)  # at start, before any tick
    static = decoded(published[1])["/tf_static"].transforms
    assert [(t.header.frame_id, t.child_frame_id) for t in static] == [("map", "unit2/odom")]
    s.tick()
    tf = decoded({"/tf": published[-1]["/tf"]})["/tf"].transforms
    assert [(t.header.frame_id, t.child_frame_id) for t in tf] == [("unit2/odom", "unit2/base_link")]
    assert {"joint_states", "odom"} <= set(published[-1])  # what robot_state_publisher reads


def test_a_new_frame_id_republishes_tf_static_and_one_of_the_train_s_frames_is_refused(tmp_path):
    s, published = session(tmp_path, "/unit1")
    assert s.set_parameters({"frame_id": "world"}) == ""
    static = decoded({"/tf_static": published[-1]["/tf_static"]})["/tf_static"].transforms
    assert ("world", "unit1/odom") in [(t.header.frame_id, t.child_frame_id) for t in static]
    assert list(published[-1]) == ["/tf_static"]
    reason = s.set_parameters({"frame_id": "unit1/seeder"})
    assert reason.startswith("frame_id: 'unit1/seeder' must be a frame that is none of the train's own"), reason
    with pytest.raises(ConfigError, match="parameter frame_id: 'unit1/base_link' must be"):
        session(tmp_path, "/unit1", frame_id="unit1/base_link")


# -- the offline run's bag -------------------------------------------------------------------------
def read_bag(path: Path) -> tuple[dict[str, list], dict[str, str]]:
    """topic -> [(log time, message)] by rosbags, and topic -> offered_qos_profiles."""
    out: dict[str, list] = {}
    with AnyReader([path]) as r:
        qos = {c.topic: c.ext.offered_qos_profiles for c in r.connections}
        for con, log_time, raw in r.messages():
            out.setdefault(con.topic, []).append((log_time, r.deserialize(raw, con.msgtype)))
    return out, qos


def assert_bag_frames(bag: dict, namespace: str, train) -> None:
    """The frames of every tick of a bag are its hitch poses and the URDF's kinematics."""
    q = lambda topic: qualified(topic, namespace)  # noqa: E731
    prefix = frame_prefix(namespace)
    assert len(bag["/tf_static"]) == 1 and len(bag[q("robot_description")]) == 1
    assert bag["/tf_static"][0][0] == bag[q("robot_description")][0][0] <= bag[q("hitch_poses")][0][0]
    model = urdf_of(bag[q("robot_description")][0][1].data)
    fixed = bag["/tf_static"][0][1].transforms
    ticks = {t: m for t, m in bag[q("hitch_poses")]}
    assert [t for t, _ in bag["/tf"]] == [t for t, _ in bag[q("joint_states")]] == [t for t, _ in bag[q("odom")]] == list(ticks)
    for (t, tf), (_, js) in zip(bag["/tf"], bag[q("joint_states")]):
        frames = tree([*fixed, *tf.transforms], "map")
        assert_frames_are_the_hitch_poses(frames, hitch_pose_list(ticks[t]), train, prefix)
        assert_urdf_kinematics_give_the_frames(model, js, frames, prefix + "base_link")


def test_the_offline_bag_holds_the_frames_of_every_tick_latched_topics_first(tmp_path):
    scene = tmp_path / "scene.yaml"
    scene.write_text(f"name: short\ntrain: {TRAIN}\nduration: 4\ninitial: {{speed: 3.0}}\n"
                     "steering: {table: {time: [0, 1, 2], angle: [0, 0.3, -0.2]}}\npublish_rate: 25\n")
    path = tmp_path / "run.mcap"
    assert cli.main(["run", "--scene", str(scene), "--bag", str(path), "--quiet"]) == 0
    assert_never_back(path)
    bag, qos = read_bag(path)
    assert {qualified(t) for t in FRAME_TOPICS} <= set(bag)
    for topic in sorted(set(LATCHED_TOPICS) - {RUN_METADATA_TOPIC}):  # as rosbags reads offered_qos_profiles
        # (run_metadata is the node's: mta run's bag holds its record as MCAP metadata)
        [offered] = qos[qualified(topic)]
        assert (offered.durability.name, offered.depth, offered.reliability.name) == ("TRANSIENT_LOCAL", 1, "RELIABLE")
    assert [q.durability.name for q in qos["/tf"]] == ["VOLATILE"]
    assert_bag_frames(bag, "/", load_train(TRAIN))
    assert max(abs(m.position[0]) for _, m in bag["/joint_states"]) > 0.05  # it turned
    # mcap_ros2's decoder (mta analyze's reader) reads the new topics too
    assert {topic for topic, _, _ in read_messages(str(path))} >= {qualified(t) for t in FRAME_TOPICS}


# -- the node, over real DDS ---------------------------------------------------------------------
@pytest.mark.dds
def test_a_running_node_in_a_namespace_publishes_frames_that_are_its_hitch_poses(tmp_path, probe):
    """The node in /unit1, steered over DDS: every /tf it sends, with /tf_static, gives each
    cart's frame at its hitch pose; joint_states are the hitch angles; the robot_description a
    late subscriber gets parses with yourdfpy and its kinematics give the same frames; the odometry
    is base_link's frame and turns as its rear axle must; its bag holds all of it."""
    from dds import start_node, stop, write_params
    from geometry_msgs.msg import PoseArray
    from nav_msgs.msg import Odometry
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64, String
    from tf2_msgs.msg import TFMessage

    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    params = write_params(tmp_path / "params.yaml", scene_file=str(REPO / "config/scenes/headland_turn.yaml"),
                          bag_dir=str(tmp_path / "bags"), publish_rate=50.0, real_time_factor=4.0,
                          watchdog_timeout=0.0, record=True)
    node = start_node(params, tmp_path / "node.log", ros_args=["-r", "__ns:=/unit1"])
    try:
        poses = probe.subscribe("/unit1/hitch_poses", PoseArray)
        tf = probe.subscribe("/tf", TFMessage, 100)
        joints = probe.subscribe("/unit1/joint_states", JointState, 100)
        odom = probe.subscribe("/unit1/odom", Odometry, 100)
        assert probe.spin_until(lambda: len(poses) > 3 or node.poll() is not None, 30.0), "no output"
        static = probe.subscribe("/tf_static", TFMessage, latched)  # late: latched ones arrive all the same
        description = probe.subscribe("/unit1/robot_description", String, latched)
        probe.publisher(Float64, "/unit1/steering_angle").publish(Float64(data=0.2))
        assert probe.spin_until(lambda: static and description and joints and abs(joints[-1].position[1]) > 0.05, 60.0)
    finally:
        assert stop(node) == 0, (tmp_path / "node.log").read_text()[-3000:]
    train = load_train(TRAIN)
    [fixed] = [m.transforms for m in static]
    by_stamp = lambda box: {(m.header.stamp.sec, m.header.stamp.nanosec): m for m in box}  # noqa: E731
    pose_at, joints_at, odom_at = by_stamp(poses), by_stamp(joints), by_stamp(odom)
    model = urdf_of(description[0].data)
    assert model.base_link == "unit1/base_link"
    # what robot_state_publisher would be given: mta urdf prints the same URDF
    printed = subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", "urdf", "--scene", "scenes/headland_turn.yaml",
                              "--namespace", "/unit1"], capture_output=True, text=True, cwd=REPO, timeout=60)
    assert printed.returncode == 0 and printed.stdout == description[0].data, printed.stderr
    checked = 0
    for msg in tf:
        stamp = (msg.transforms[0].header.stamp.sec, msg.transforms[0].header.stamp.nanosec)
        if stamp not in pose_at or stamp not in joints_at or stamp not in odom_at:
            continue  # a message of that tick lost on the way (keep last 10): nothing to compare with
        frames = tree([*fixed, *msg.transforms], "map")
        assert_frames_are_the_hitch_poses(frames, hitch_pose_list(pose_at[stamp]), train, "unit1/")
        js = joints_at[stamp]
        th = [p[2] for p in hitch_pose_list(pose_at[stamp])]
        assert all(abs(wrap(js.position[k - 1] - (th[k - 1] - th[k]))) <= TOL for k in (1, 2))
        assert_urdf_kinematics_give_the_frames(model, js, frames, "unit1/base_link")
        o = odom_at[stamp]
        assert (o.header.frame_id, o.child_frame_id) == ("unit1/odom", "unit1/base_link")
        p = o.pose.pose
        assert_close((p.position.x, p.position.y, yaw_of(p.orientation)), frames["unit1/base_link"], "odom")
        tw, psi = o.twist.twist, js.position[2]
        assert tw.angular.z == pytest.approx(tw.linear.x * math.tan(psi) / train.carts[0].length, rel=1e-9, abs=1e-12)
        checked += 1
    assert checked > 50
    [bag_path] = sorted((tmp_path / "bags").glob("*.mcap"))
    assert_never_back(bag_path)
    bag, qos = read_bag(bag_path)
    assert {t for t in bag if t.endswith(tuple(FRAME_TOPICS))} == {qualified(t, "/unit1") for t in FRAME_TOPICS}
    assert [q.durability.name for q in qos["/unit1/robot_description"]] == ["TRANSIENT_LOCAL"]
    assert bag["/unit1/robot_description"][0][1].data == description[0].data
    assert_bag_frames(bag, "/unit1", train)



def test_on_a_slope_the_session_tilts_odom_and_stamps_the_poses_in_it(tmp_path):
    """The node's session on the side-slope scene, in a namespace: /tf_static map -> unit3/odom is
    the plane's tilt (its z axis the plane's normal), hitch_poses and the markers are in unit3/odom."""
    from scipy.spatial.transform import Rotation

    s, published = session(tmp_path, "/unit3", scene_file=str(REPO / "config/scenes/side_slope_pass.yaml"))
    static = decoded(published[1])["/tf_static"].transforms
    tilt = [t for t in static if t.child_frame_id == "unit3/odom"]
    assert [t.header.frame_id for t in tilt] == ["map"]
    r = tilt[0].transform.rotation
    normal = np.array([-0.04, -0.12, 1.0]) / math.sqrt(1 + 0.04 ** 2 + 0.12 ** 2)
    assert np.allclose(Rotation.from_quat([r.x, r.y, r.z, r.w]).apply([0, 0, 1]), normal, atol=1e-12)
    for _ in range(60):  # the markers come every few ticks
        s.tick()
    msgs = {}
    for p in published[2:]:
        msgs.update(p)
    assert rosbags_decode("geometry_msgs/msg/PoseArray", msgs["hitch_poses"]).header.frame_id == "unit3/odom"
    markers = rosbags_decode("visualization_msgs/msg/MarkerArray", msgs["markers"]).markers
    assert markers and {m.header.frame_id for m in markers} == {"unit3/odom"}
    # the ground, drawn in the plane's frame (unit3/odom): its top at z = 0, centred under A_1
    [ground] = [m for m in markers if m.ns == "terrain"]
    [tick] = [p for p in published[2:] if "markers" in p][-1:]  # the markers' tick: its own hitch poses
    a1 = rosbags_decode("geometry_msgs/msg/PoseArray", tick["hitch_poses"]).poses[0].position
    assert ground.type == 1 and ground.pose.position.z + ground.scale.z / 2 == 0.0
    assert (ground.pose.position.x, ground.pose.position.y) == pytest.approx((a1.x, a1.y), abs=1e-9)


# -- on a height grid: 3D poses ----------------------------------------------------------------------
GRADE = (0.1, 0.05)  # the plane z = 0.1 x + 0.05 y, sampled on the grid


def plane_grid():
    xs, ys = np.arange(-60.0, 200.0, 4.0), np.arange(-60.0, 60.0, 4.0)
    return terrain.grid_from(GRADE[0] * xs[None, :] + GRADE[1] * ys[:, None], (-60.0, -60.0), 4.0)


def plane_rotation(th: float):
    """The rotation of a cart of heading th on the plane: roll = asin(across / w), pitch = -atan(along)."""
    from scipy.spatial.transform import Rotation

    gx, gy = GRADE
    along, across = gx * math.cos(th) + gy * math.sin(th), gy * math.cos(th) - gx * math.sin(th)
    roll, pitch = math.asin(across / math.sqrt(1 + gx * gx + gy * gy)), -math.atan(along)
    return Rotation.from_euler("ZYX", [th, pitch, roll])


def rotation_of(q):
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat([q.x, q.y, q.z, q.w])


def test_on_a_height_grid_odom_and_tf_are_the_surface_poses_of_the_axles(turning):
    """odom and /tf odom -> base_link: B_1 at the surface's height, the tractor's rotation on it;
    the hitch joints turn each cart into its own rotation on the surface; odom is world-aligned."""
    scene, samples = turning
    train = dataclasses.replace(scene.train, relief=plane_grid(), terrain=None)
    robot = robot_model(train)
    for cart_frames in (True, False):
        enc = FrameEncoder(robot, "map", cart_frames, train.terrain, train.relief)
        [static] = [t for t in decoded(enc.latched(0.0))["/tf_static"].transforms if t.child_frame_id == "odom"]
        assert planar(static) == (0.0, 0.0, 0.0) and static.header.frame_id == "map"
        for out in samples:
            msgs = decoded(enc.encode(out))
            bx, by = out.axle[0]
            pose = msgs["odom"].pose.pose
            assert (pose.position.x, pose.position.y) == (bx, by)
            assert abs(pose.position.z - (GRADE[0] * bx + GRADE[1] * by)) < TOL
            want = plane_rotation(float(out.heading[0]))
            assert (rotation_of(pose.orientation) * want.inv()).magnitude() < TOL
            base, *joints = msgs["/tf"].transforms
            assert (base.transform.translation.z, base.transform.rotation) == (pose.position.z, pose.orientation)
            assert len(joints) == (len(train.carts) if cart_frames else 0)
            for k, tf in enumerate(joints[1:], start=1):  # cart k-1 -> cart k's hitch: R_{k-1}^T R_k
                turned = plane_rotation(float(out.heading[k - 1])) * rotation_of(tf.transform.rotation)
                assert (turned * plane_rotation(float(out.heading[k])).inv()).magnitude() < TOL
                assert tf.transform.translation.x == robot.hitch_joints[k - 1].x and tf.transform.translation.z == 0.0


def test_level_and_plane_frame_templates_have_no_height_grid_slots(turning):
    """The level's and a plane's /tf and odom templates: z, w per transform and six odometry
    numbers, as before height grids; a grid adds base_link's height and the quaternions' x, y."""
    scene, samples = turning
    robot, n = robot_model(scene.train), len(scene.train.carts)
    for plane, relief in ((None, None), (terrain.Plane(0.1, 0.05), None), (None, plane_grid())):
        enc = FrameEncoder(robot, "map", True, plane, relief)
        groups = {name: g.count for name, g in enc.tf.groups.items()}
        grid = relief is not None
        assert groups == {"xy": 2, "q": (4 if grid else 2) * (n + 1), "sec": n + 1, "nanosec": n + 1,
                          **({"z": 1} if grid else {})}
        assert enc.odom.groups["odom"].count == (9 if grid else 6)
        if not grid:  # every transform a turn in the plane
            assert all(planar(tf) for tf in decoded(enc.encode(samples[-1]))["/tf"].transforms)


def test_on_the_hilly_field_the_session_publishes_3d_poses_in_frame_id(tmp_path):
    """The node's session on a height grid: hitch_poses in frame_id, odom at the surface's height."""
    s, published = session(tmp_path, scene_file=str(REPO / "config/scenes/hilly_field.yaml"))
    for _ in range(5):
        s.tick()
    relief = s.scene.train.relief
    odom = decoded({"odom": published[-1]["odom"]})["odom"].pose.pose.position
    assert abs(odom.z - relief.at(odom.x, odom.y).z) < TOL and odom.z != 0.0
    poses = rosbags_decode("geometry_msgs/msg/PoseArray", published[-1]["hitch_poses"])
    assert poses.header.frame_id == "map"
    assert all(abs(p.position.z - relief.at(p.position.x, p.position.y).z) < TOL for p in poses.poses)
