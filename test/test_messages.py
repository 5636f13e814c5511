"""The simulator's messages as CDR bytes (mta_sim_ros.messages), as the node and the offline run
write them.

Each encoder's bytes must be byte for byte the plain dicts of ``topics.output_messages`` (etc.)
encoded by ``bag.cdr`` (what bags hold), and must decode, with rclpy and with rosbags, to the
messages built field by field from the same Outputs. No node is started.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from cdr_refs import assert_fields, rclpy_message, rosbags_decode
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Point, Pose, PoseArray, Quaternion
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Header
from trains import scene as make_scene
from visualization_msgs.msg import Marker, MarkerArray

from mta_sim_ros import messages
from mta_sim_ros.bag import cdr, stamp
from mta_sim_ros.messages import markers as drawing
from mta_sim_ros.messages import topics
from mta_sim_ros.physics.loader import load_scene, load_train
from mta_sim_ros.physics import terrain
from mta_sim_ros.physics.terrain import Plane
from mta_sim_ros.run.simulation import Simulation

REPO = Path(__file__).resolve().parents[1]
CLASSES = {"hitch_poses": PoseArray, "cart_velocities": JointState, "traction_power": Float64,
           "applied_steering": Float64, "steering_angle": Float64, "speed_setpoint": Float64, "/clock": Clock}


def run_samples(scene, ticks_at):
    """Outputs of a run of ``scene`` on its own inputs after each tick count in ``ticks_at``."""
    sim = Simulation(scene)
    samples = []
    for ticks in ticks_at:
        while sim.ticks < ticks:
            sim.advance(*sim.scheduled_inputs(sim.t))
        samples.append(sim.outputs())
    return sim, samples


@pytest.fixture(scope="module")
def lane_change():
    """The default train in the lane change: at rest on the straight, then mid-manoeuvre (the
    lane change steers from t = 5 s), at a time that is no whole number of seconds."""
    return run_samples(load_scene(REPO / "config/scenes/lane_change.yaml"), (0, 3, 330, 401))


@pytest.fixture(scope="module")
def offset_hitch():
    """A tractor hitched 0.4 m ahead of its rear axle, turning."""
    tr = load_train(REPO / "config/trains/offset_hitch.yaml")
    return run_samples(make_scene(tr, table=((0.0, 1.0), (0.0, 0.3)), rate=50.0), (250,))


def time_msg(t: float) -> Time:
    return Time(**stamp(t))


def rclpy_outputs(out, names, frame_id):
    """The five output messages as rclpy objects, built field by field from the Outputs."""
    poses = [Pose(position=Point(x=float(p[0]), y=float(p[1]), z=0.0),
                  orientation=Quaternion(x=0.0, y=0.0, z=math.sin(th / 2.0), w=math.cos(th / 2.0)))
             for p, th in zip(out.front, out.heading.tolist())]
    return {
        "hitch_poses": PoseArray(header=Header(stamp=time_msg(out.t), frame_id=frame_id), poses=poses),
        "cart_velocities": JointState(header=Header(stamp=time_msg(out.t), frame_id=""), name=list(names),
                                      position=out.heading.tolist(), velocity=out.com_speed.tolist(),
                                      effort=out.resistance.tolist()),
        "traction_power": Float64(data=float(out.power)),
        "applied_steering": Float64(data=float(out.steering)),
        "/clock": Clock(clock=time_msg(out.t)),
    }


def check_outputs(encoder, out, names, frame_id):
    """The encoder's bytes: those of the offline dicts, and, decoded by rclpy and by rosbags, the
    messages built field by field."""
    data = encoder.encode(out)
    dicts = topics.output_messages(out, names, frame_id)
    assert list(data) == list(dicts)
    for topic, msg in rclpy_outputs(out, names, frame_id).items():
        assert data[topic] == cdr.encode(topics.TOPICS[topic], dicts[topic]), topic
        assert deserialize_message(data[topic], CLASSES[topic]) == msg, topic
        assert_fields(rosbags_decode(topics.TOPICS[topic], data[topic]), dicts[topic], topic)


@pytest.mark.parametrize("frame_id", ["map", "odom", ""])
def test_encoded_outputs_are_the_offline_bytes_and_decode_to_the_messages_built_field_by_field(
        lane_change, offset_hitch, frame_id):
    """Several samples through one encoder: nothing of an earlier tick leaks into a later."""
    for sim, samples in (lane_change, offset_hitch):
        names = [c.name for c in sim.scene.train.carts]
        encoder = messages.OutputEncoder(names, frame_id)
        for out in samples + samples[::-1]:
            check_outputs(encoder, out, names, frame_id)


def test_output_content(lane_change):
    sim, samples = lane_change
    out = samples[-1]
    names = [cart.name for cart in sim.scene.train.carts]
    data = messages.OutputEncoder(names, "odom").encode(out)
    msgs = {topic: deserialize_message(b, CLASSES[topic]) for topic, b in data.items()}
    assert out.t == pytest.approx(8.02) and out.steering != 0.0
    stamp_ = msgs["hitch_poses"].header.stamp
    assert (stamp_.sec, stamp_.nanosec) == (8, 20_000_000)
    assert msgs["/clock"].clock == stamp_ == msgs["cart_velocities"].header.stamp
    assert msgs["hitch_poses"].header.frame_id == "odom"
    for pose, a, th in zip(msgs["hitch_poses"].poses, out.front, out.heading):
        assert (pose.position.x, pose.position.y) == (a[0], a[1])
        assert 2.0 * math.atan2(pose.orientation.z, pose.orientation.w) == pytest.approx(th)
    joints = msgs["cart_velocities"]
    assert list(joints.name) == names
    assert list(joints.velocity) == list(out.com_speed)
    assert list(joints.position) == list(out.heading)
    assert list(joints.effort) == list(out.resistance)
    assert msgs["traction_power"].data == out.power
    assert msgs["applied_steering"].data == out.steering
    with pytest.raises(ValueError, match="2 cart names for 3 carts"):
        messages.OutputEncoder(names[:2]).encode(out)


def test_encoded_stamps_round_like_the_bag_stamp(lane_change):
    """Stamps written into the templates carry sec and nanosec as ``bag.stamp`` rounds them,
    including the second boundary, sub-nanosecond times and large times."""
    sim, samples = lane_change
    encoder = messages.OutputEncoder([c.name for c in sim.scene.train.carts])
    for t in (0.0, 0.02, 8.02, 0.5e-9, 1.5e-9, 0.999999999, 1.0, 1.9999999999, 12.3456789, 123456.789,
              3599.9999999996, 2.0 ** 31 - 1.5):
        out = dataclasses.replace(samples[1], t=t)  # not the shared fixture's sample itself
        clock = deserialize_message(encoder.encode(out)["/clock"], Clock)
        assert (clock.clock.sec, clock.clock.nanosec) == tuple(stamp(t).values()), t
    clock = deserialize_message(encoder.encode(dataclasses.replace(samples[1], t=1.9999999999))["/clock"], Clock)
    assert (clock.clock.sec, clock.clock.nanosec) == (2, 0)


def test_commands(lane_change):
    _, samples = lane_change
    encoder = messages.CommandEncoder()
    for out in samples + [dataclasses.replace(samples[0], command=-2.5, speed_setpoint=3)]:
        data = encoder.encode(out)
        dicts = topics.command_messages(out)
        assert list(data) == list(dicts) == ["steering_angle", "speed_setpoint"]
        for topic, value in (("steering_angle", out.command), ("speed_setpoint", out.speed_setpoint)):
            assert data[topic] == cdr.encode(topics.TOPICS[topic], dicts[topic])
            assert deserialize_message(data[topic], Float64) == Float64(data=float(value))
            assert rosbags_decode(topics.TOPICS[topic], data[topic]).data == value


# -- any number of carts ------------------------------------------------------------------------

def fake_train(n: int, terrain=None):
    return SimpleNamespace(name=f"train_{n}", carts=[SimpleNamespace(name=f"cart_{k}" + "x" * (k % 4)) for k in range(n)],
                           draft=[SimpleNamespace(cart=f"cart_{k}" + "x" * (k % 4), width=1.0 + k) for k in range(1, n, 3)],
                           terrain=terrain)


def fake_outputs(n: int, seed: int):
    rng = np.random.default_rng(seed)
    front = rng.normal(size=(n, 2)) * 50.0
    heading = rng.uniform(-math.pi, math.pi, n)
    axle = front - 3.0 * np.c_[np.cos(heading), np.sin(heading)]
    return SimpleNamespace(t=rng.uniform(0, 1e4), front=front, axle=axle, heading=heading,
                           rear_hitch=axle[-1] - 1.0, com_speed=rng.normal(size=n), resistance=rng.normal(size=n) * 1e3,
                           power=float(rng.normal()) * 1e4, steering=float(rng.normal()),
                           command=float(rng.normal()), speed_setpoint=3.0)


@pytest.mark.parametrize("n", range(1, 121))
def test_templates_for_any_number_of_carts_build_and_decode(n):
    """1..120 carts (the old sentinel search refused some counts): outputs and markers build,
    equal the dicts encoded from scratch, and decode with rclpy to the messages built field by
    field."""
    train, out = fake_train(n), fake_outputs(n, n)
    names = [c.name for c in train.carts]
    check_outputs(messages.OutputEncoder(names, "map"), out, names, "map")
    for terrain in (None, Plane(0.1, -0.2)):  # on a tilted plane the ground is drawn too
        train = fake_train(n, terrain)
        data = messages.TrainMarkers(train, "odom").encode(out)
        drawn = messages.train_markers(out, train, "odom")
        assert data == cdr.encode(messages.MARKERS_TYPE, drawn)
        assert deserialize_message(data, MarkerArray) == rclpy_message(messages.MARKERS_TYPE, drawn)
        assert len(drawn["markers"]) == 3 * n + 1 + (terrain is not None)


@pytest.mark.slow
def test_templates_are_the_same_bytes_each_time_they_are_built():
    for n in range(1, 201):
        train, names = fake_train(n), [f"cart_{k}" for k in range(n)]
        first, second = messages.OutputEncoder(names), messages.OutputEncoder(names)
        assert (first.poses.buf, first.joints.buf) == (second.poses.buf, second.joints.buf), n
        assert messages.TrainMarkers(train).template.buf == messages.TrainMarkers(train).template.buf, n


# -- markers -------------------------------------------------------------------


def drawn(out, train, frame_id="map") -> MarkerArray:
    """The node's markers (TrainMarkers.encode) as rclpy decodes them."""
    return deserialize_message(messages.TrainMarkers(train, frame_id).encode(out), MarkerArray)


def on_segment(p, a, b, tol=1e-9):
    cross = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
    inside_box = (min(a[0], b[0]) - tol <= p[0] <= max(a[0], b[0]) + tol
                  and min(a[1], b[1]) - tol <= p[1] <= max(a[1], b[1]) + tol)
    return abs(cross) <= tol * max(1.0, math.dist(a, b)) and inside_box


def encloses(polygon, p):
    """True if p is inside the closed polygon (vertices, last = first) or on its boundary."""
    edges = list(zip(polygon, polygon[1:]))
    if any(on_segment(p, a, b) for a, b in edges):
        return True
    crossings = 0
    for (x1, y1), (x2, y2) in edges:
        if (y1 > p[1]) != (y2 > p[1]) and p[0] < x1 + (p[1] - y1) * (x2 - x1) / (y2 - y1):
            crossings += 1
    return crossings % 2 == 1


def xy(points):
    return [(pt.x, pt.y) for pt in points]


def by_ns(array):
    kinds = {}
    for marker in array.markers:
        kinds.setdefault(marker.ns, []).append(marker)
    return kinds


@pytest.mark.parametrize("case", ["lane_change", "offset_hitch"])
def test_outlines_enclose_hitch_and_axle(case, request):
    sim, samples = request.getfixturevalue(case)
    train = sim.scene.train
    for out in samples:
        outlines = by_ns(drawn(out, train))[drawing.NS_OUTLINE]
        assert [m.id for m in outlines] == list(range(train.n))
        for k, marker in enumerate(outlines):
            assert marker.type == Marker.LINE_STRIP
            corners = xy(marker.points)
            assert len(corners) == 5 and corners[0] == corners[-1]
            a, b = out.front[k], out.axle[k]
            assert encloses(corners, a) and encloses(corners, b), (case, out.t, k)
            ahead = a + 0.5 * (a - b) / math.dist(a, b)
            assert not encloses(corners, ahead)
            # as long as from A_k to the rearmost of B_k and the rear hitch
            cart = train.carts[k]
            assert math.dist(corners[1], corners[2]) == pytest.approx(
                max(cart.length, cart.length + cart.hitch_offset))


def test_outline_widths(lane_change):
    sim, samples = lane_change
    markers = by_ns(drawn(samples[-1], sim.scene.train))
    widths = {}
    for outline, label in zip(markers[drawing.NS_OUTLINE], markers[drawing.NS_LABEL]):
        corners = xy(outline.points)
        widths[label.text] = math.dist(corners[0], corners[1])
        assert math.dist(corners[2], corners[3]) == pytest.approx(widths[label.text])
    assert widths == pytest.approx({"tractor": 2.5, "air_cart": 2.5, "seeder": 12.0})
    axles = markers[drawing.NS_AXLE]
    assert [math.dist(*xy(m.points)) for m in axles] == pytest.approx([2.5, 2.5, 12.0])


def test_markers_are_stable_and_complete(lane_change):
    sim, samples = lane_change
    train = sim.scene.train
    first, last = (drawn(out, train, "odom") for out in (samples[0], samples[-1]))
    keys = [(m.ns, m.id) for m in first.markers]
    assert keys == [(m.ns, m.id) for m in last.markers]  # every message updates the same markers
    assert len(set(keys)) == len(keys)  # ids unique within each namespace
    kinds = by_ns(last)
    assert {ns: [m.id for m in ms] for ns, ms in kinds.items()} == {
        drawing.NS_OUTLINE: [0, 1, 2], drawing.NS_AXLE: [0, 1, 2], drawing.NS_LABEL: [0, 1, 2],
        drawing.NS_HITCHES: [0]}
    out = samples[-1]
    for m in last.markers:
        assert m.header.frame_id == "odom"
        assert m.header.stamp == time_msg(out.t)
        assert m.action == Marker.ADD
        assert (m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z,
                m.pose.orientation.w) == (0.0, 0.0, 0.0, 1.0)
        assert m.color.a == 1.0
        assert all(p.z == 0.0 for p in m.points) and m.pose.position.z == 0.0
    for m in kinds[drawing.NS_OUTLINE] + kinds[drawing.NS_AXLE]:
        assert m.scale.x == pytest.approx(0.1)
    axles = kinds[drawing.NS_AXLE]
    for k, m in enumerate(axles):
        assert m.type == Marker.LINE_LIST and len(m.points) == 2
        p, q = xy(m.points)
        assert ((p[0] + q[0]) / 2, (p[1] + q[1]) / 2) == pytest.approx(tuple(out.axle[k]))
        across = (q[0] - p[0], q[1] - p[1])
        assert across[0] * math.cos(out.heading[k]) + across[1] * math.sin(out.heading[k]) \
            == pytest.approx(0.0, abs=1e-9)
    (hitches,) = kinds[drawing.NS_HITCHES]
    assert hitches.type == Marker.SPHERE_LIST and hitches.scale.x > 0.0
    assert xy(hitches.points) == [tuple(a) for a in out.front]
    assert [m.text for m in kinds[drawing.NS_LABEL]] == ["tractor", "air_cart", "seeder"]
    assert all(m.type == Marker.TEXT_VIEW_FACING and m.scale.z > 0.0
               for m in kinds[drawing.NS_LABEL])
    colours = [(m.color.r, m.color.g, m.color.b) for m in kinds[drawing.NS_OUTLINE]]
    assert len(set(colours)) == 3
    assert [(c.r, c.g, c.b) for c in hitches.colors] == colours


def test_marker_constants_are_the_messages():
    assert (drawing.LINE_STRIP, drawing.LINE_LIST, drawing.SPHERE_LIST, drawing.TEXT_VIEW_FACING, drawing.ADD) == (
        Marker.LINE_STRIP, Marker.LINE_LIST, Marker.SPHERE_LIST, Marker.TEXT_VIEW_FACING, Marker.ADD)


def test_encoded_markers_are_the_drawing_encoded_from_scratch(lane_change, offset_hitch):
    """TrainMarkers.encode (the node's marker tick) along a run and back: the bytes of
    train_markers' dicts, decoding with rclpy and rosbags to them."""
    for sim, samples in (lane_change, offset_hitch):
        markers = messages.TrainMarkers(sim.scene.train, "odom")
        for out in samples + [samples[0]]:
            fresh = messages.train_markers(out, sim.scene.train, "odom")
            data = markers.encode(out)
            assert data == cdr.encode(messages.MARKERS_TYPE, fresh)
            assert deserialize_message(data, MarkerArray) == rclpy_message(messages.MARKERS_TYPE, fresh)
            assert_fields(rosbags_decode(messages.MARKERS_TYPE, data), fresh)


def test_markers_refuse_another_train(lane_change):
    _, samples = lane_change
    tr = load_train(REPO / "config/trains/single_tractor.yaml")
    with pytest.raises(ValueError, match="3 carts in the outputs, 1 in train"):
        messages.train_markers(samples[0], tr)
    with pytest.raises(ValueError, match="3 carts in the outputs, 1 in train"):
        messages.TrainMarkers(tr).encode(samples[0])


# -- diagnostics ---------------------------------------------------------------


def diagnostics(*args) -> DiagnosticArray:
    data = messages.encode_diagnostics(*args)
    assert_fields(rosbags_decode(messages.DIAGNOSTICS_TYPE, data), messages.diagnostic_array(*args))
    return deserialize_message(data, DiagnosticArray)


@pytest.mark.parametrize("level, number", [(0, 0), (1, 1), (2, 2), (3, 3),
                                           (DiagnosticStatus.WARN, 1),
                                           (DiagnosticStatus.STALE, 3)])
def test_diagnostics_level_round_trips(level, number):
    array = diagnostics(12.5, "mta_sim: tick", level, "late", {"misses": 3})
    (status,) = array.status
    assert status.level == bytes([number])
    assert array == rclpy_message(messages.DIAGNOSTICS_TYPE,
                                  messages.diagnostic_array(12.5, "mta_sim: tick", level, "late", {"misses": 3}))


def test_diagnostics_content():
    values = {"p99": 0.0123456789, "count": 1200, "rtf": 1.0, "ok": True, "scene": "lane_change",
              "big": 1.5e12, "numpy": np.float64(0.5)}
    array = diagnostics(3.25, "mta_sim: timing", DiagnosticStatus.OK, "ok", values)
    assert (array.header.stamp.sec, array.header.stamp.nanosec) == (3, 250_000_000)
    assert array.header.frame_id == ""
    (status,) = array.status
    assert status.name == "mta_sim: timing" and status.message == "ok"
    assert status.hardware_id == "mta_sim_ros"
    kv = {item.key: item.value for item in status.values}
    assert kv == {"p99": "0.0123457", "count": "1200", "rtf": "1", "ok": "True",
                  "scene": "lane_change", "big": "1.5e+12", "numpy": "0.5"}


@pytest.mark.parametrize("level", [4, -1, b"\x05", b"", b"\x00\x01"])
def test_diagnostics_refuse_unknown_levels(level):
    with pytest.raises(ValueError, match="diagnostic level"):
        messages.encode_diagnostics(0.0, "x", level, "", {})


@pytest.mark.slow
def test_the_encoders_and_the_offline_run_need_no_ros(tmp_path):
    """With rclpy and every ROS message package made unimportable, the offline run's module
    loads and the encoders encode (the definitions are .msg files, read as text)."""
    import subprocess
    import sys

    script = f"""
import importlib.abc, sys
class NoRos(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        top = name.split(".")[0]
        if top in ("rclpy", "rosidl_runtime_py") or top.endswith(("_msgs", "_srvs", "_interfaces")):
            raise ImportError("no ROS here: " + name)
sys.meta_path.insert(0, NoRos())
import mta_sim_ros.tools.run
from mta_sim_ros import messages
from mta_sim_ros.physics.loader import load_scene
from mta_sim_ros.run.simulation import Simulation
scene = load_scene({str(REPO / "config/scenes/lane_change.yaml")!r})
out = Simulation(scene).outputs()
names = [c.name for c in scene.train.carts]
data = {{**messages.OutputEncoder(names).encode(out), **messages.CommandEncoder().encode(out),
        "markers": messages.TrainMarkers(scene.train).encode(out),
        "diagnostics": messages.encode_diagnostics(0.0, "x", 0, "ok", {{"a": 1.5}})}}
assert "rclpy" not in sys.modules
print(len(data))
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "9"


# -- on a height grid -----------------------------------------------------------------------------
GRADE = (0.1, 0.05)  # the plane z = 0.1 x + 0.05 y, sampled on the grids


def plane_grid(nx: int = 65, ny: int = 30, spacing: float = 4.0):
    xs, ys = -60.0 + spacing * np.arange(nx), -60.0 + spacing * np.arange(ny)
    return terrain.grid_from(GRADE[0] * xs[None, :] + GRADE[1] * ys[:, None], (-60.0, -60.0), spacing)


def plane_height(x: float, y: float) -> float:
    return GRADE[0] * x + GRADE[1] * y


def plane_quaternion(th: float) -> np.ndarray:
    """(x, y, z, w) of a cart of heading th on the plane: roll = asin(across / w), pitch = -atan(along)."""
    from scipy.spatial.transform import Rotation

    gx, gy = GRADE
    along, across = gx * math.cos(th) + gy * math.sin(th), gy * math.cos(th) - gx * math.sin(th)
    roll, pitch = math.asin(across / math.sqrt(1 + gx * gx + gy * gy)), -math.atan(along)
    return Rotation.from_euler("ZYX", [th, pitch, roll]).as_quat()


def test_on_a_height_grid_hitch_poses_are_3d_the_dicts_bytes_and_the_plane_s_closed_form(lane_change, offset_hitch):
    """Each pose: A_k at the surface's height, the cart's rotation on the surface (its heading,
    roll and pitch of the plane's closed form); the template's bytes are the plain dicts'."""
    grid = plane_grid()
    for sim, samples in (lane_change, offset_hitch):
        names = [c.name for c in sim.scene.train.carts]
        enc = messages.OutputEncoder(names, "map", grid)
        assert enc.poses.groups["pose"].count == 7 * len(names)
        for out in samples:
            data = enc.encode(out)["hitch_poses"]
            assert data == cdr.encode(topics.TOPICS["hitch_poses"], topics.output_messages(out, names, "map", grid)
                                      ["hitch_poses"])
            poses = rosbags_decode(topics.TOPICS["hitch_poses"], data).poses
            for (ax, ay), th, pose in zip(out.front.tolist(), out.heading.tolist(), poses):
                p, q = pose.position, pose.orientation
                assert (p.x, p.y) == (ax, ay) and abs(p.z - plane_height(ax, ay)) < 1e-9
                assert abs(abs(np.dot([q.x, q.y, q.z, q.w], plane_quaternion(th))) - 1.0) < 1e-12


def test_a_level_train_s_hitch_poses_template_has_no_height_grid_slots(lane_change):
    """Level: x, y and the yaw's z, w per pose, and z = 0, x = y = 0 written in the template."""
    sim, samples = lane_change
    names = [c.name for c in sim.scene.train.carts]
    enc = messages.OutputEncoder(names, "map")
    assert enc.poses.groups["pose"].count == 4 * len(names)
    assert enc.encode(samples[-1])["hitch_poses"] == cdr.encode(
        topics.TOPICS["hitch_poses"], topics.output_messages(samples[-1], names, "map")["hitch_poses"])


def test_on_a_height_grid_the_markers_lie_on_the_surface_over_its_mesh(lane_change):
    """The drawing on a grid: every point at the surface's height, the ground one TRIANGLE_LIST
    (ns terrain, id 0) through every node (a small grid), TERRAIN_DROP below them."""
    sim, samples = lane_change
    grid = plane_grid()
    train = dataclasses.replace(sim.scene.train, relief=grid, terrain=None)
    enc = messages.TrainMarkers(train, "map")
    for out in samples:
        data = enc.encode(out)
        assert data == cdr.encode(messages.MARKERS_TYPE, messages.train_markers(out, train, "map"))
        array = deserialize_message(data, MarkerArray)
        [ground] = [m for m in array.markers if m.ns == drawing.NS_TERRAIN]
        assert (ground.id, ground.type, ground.header.frame_id) == (0, drawing.TRIANGLE_LIST, "map")
        assert len(ground.points) == 6 * 64 * 29
        assert max(abs(p.z + drawing.TERRAIN_DROP - plane_height(p.x, p.y)) for p in ground.points) < 1e-9
        drawn_points = [p for m in array.markers if m.ns != drawing.NS_TERRAIN for p in m.points]
        drawn_points += [m.pose.position for m in array.markers if m.ns == drawing.NS_LABEL]
        assert max(abs(p.z - plane_height(p.x, p.y)) for p in drawn_points) < 1e-9


def test_a_large_grid_s_mesh_is_decimated_to_its_corners():
    grid = plane_grid(nx=401, ny=257, spacing=1.0)
    points = drawing.terrain_mesh(grid)
    assert len(points) % 3 == 0 and len(points) // 3 <= drawing.MAX_TERRAIN_TRIANGLES
    assert len(points) // 3 > drawing.MAX_TERRAIN_TRIANGLES / 4  # no coarser than needed
    xs, ys = {p["x"] for p in points}, {p["y"] for p in points}
    assert (min(xs), max(xs), min(ys), max(ys)) == (-60.0, 340.0, -60.0, 196.0)
