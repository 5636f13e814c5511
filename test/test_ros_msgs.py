"""The node's rclpy messages (mta_sim_ros.ros_msgs) against the offline run's plain dicts.

The node records ``rclpy.serialization.serialize_message(msg)``; the offline run records the
dicts of ``topics.output_messages`` encoded by mcap_ros2. Both byte strings are decoded with
mcap_ros2's decoder for the schema rosbag2 stores, and must give the same values, field by field
(the CDR bytes themselves may differ in padding). No node is started.
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from mcap_ros2._dynamic import generate_dynamic, serialize_dynamic
from rclpy.serialization import deserialize_message, serialize_message
from visualization_msgs.msg import Marker

from mta_sim_ros import ros_msgs, topics
from mta_sim_ros.bag import message_definition, schema_name, stamp
from mta_sim_ros.model.loader import load_scene, load_train
from mta_sim_ros.sim import Simulation

from trains import scene as make_scene

REPO = Path(__file__).resolve().parents[1]


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


def codec(type_name):
    """(decoder, encoder) of mcap_ros2 for the schema of ``type_name`` as rosbag2 stores it."""
    name, text = schema_name(type_name), message_definition(type_name)
    return generate_dynamic(name, text)[name], serialize_dynamic(name, text)[name]


def plain(value):
    """A decoded mcap_ros2 message as nested dicts and lists."""
    if hasattr(value, "__slots__"):
        return {field: plain(getattr(value, field)) for field in value.__slots__}
    if isinstance(value, (list, tuple)):
        return [plain(item) for item in value]
    return value


def decoded(msg):
    """An rclpy message serialized by rclpy, then decoded by mcap_ros2, as plain dicts."""
    type_name = type(msg).__module__.split(".")[0] + "/msg/" + type(msg).__name__
    decode, _ = codec(type_name)
    return plain(decode(serialize_message(msg)))


def test_output_messages_match_the_offline_dicts(lane_change):
    sim, samples = lane_change
    names = [cart.name for cart in sim.scene.train.carts]
    for out in samples:
        dicts = topics.output_messages(out, names, "odom")
        msgs = ros_msgs.output_messages(out, names, "odom")
        assert list(msgs) == list(dicts)
        for topic, msg in msgs.items():
            type_name = topics.TOPICS[topic]
            assert type(msg) is ros_msgs.message_class(type_name), topic
            decode, encode = codec(type_name)
            offline = encode(dicts[topic])
            assert plain(decode(serialize_message(msg))) == plain(decode(offline)), (topic, out.t)
            assert deserialize_message(offline, type(msg)) == msg, (topic, out.t)


def test_output_messages_content(lane_change):
    sim, samples = lane_change
    out = samples[-1]
    names = [cart.name for cart in sim.scene.train.carts]
    msgs = ros_msgs.output_messages(out, names, "odom")
    assert out.t == pytest.approx(8.02) and out.steering != 0.0
    stamp = msgs["hitch_poses"].header.stamp
    assert (stamp.sec, stamp.nanosec) == (8, 20_000_000)
    assert msgs["/clock"].clock == stamp
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
        ros_msgs.output_messages(out, names[:2])


def test_time_msg_rounds_like_the_bag_stamp():
    for t in (0.0, 0.02, 8.02, 1.9999999999, 123456.789, 0.5e-9, 1.5e-9):
        msg = ros_msgs.time_msg(t)
        assert {"sec": msg.sec, "nanosec": msg.nanosec} == stamp(t)
    msg = ros_msgs.time_msg(1.9999999999)
    assert (msg.sec, msg.nanosec) == (2, 0)


def test_float64():
    assert ros_msgs.float64(3).data == 3.0
    assert decoded(ros_msgs.float64(-2.5)) == {"data": -2.5}


# -- markers -------------------------------------------------------------------


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
        outlines = by_ns(ros_msgs.train_markers(out, train))[ros_msgs.NS_OUTLINE]
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
    markers = by_ns(ros_msgs.train_markers(samples[-1], sim.scene.train))
    widths = {}
    for outline, label in zip(markers[ros_msgs.NS_OUTLINE], markers[ros_msgs.NS_LABEL]):
        corners = xy(outline.points)
        widths[label.text] = math.dist(corners[0], corners[1])
        assert math.dist(corners[2], corners[3]) == pytest.approx(widths[label.text])
    assert widths == pytest.approx({"tractor": 2.5, "air_cart": 2.5, "seeder": 12.0})
    axles = markers[ros_msgs.NS_AXLE]
    assert [math.dist(*xy(m.points)) for m in axles] == pytest.approx([2.5, 2.5, 12.0])


def test_markers_are_stable_and_complete(lane_change):
    sim, samples = lane_change
    train = sim.scene.train
    first, last = (ros_msgs.train_markers(out, train, "odom") for out in (samples[0], samples[-1]))
    keys = [(m.ns, m.id) for m in first.markers]
    assert keys == [(m.ns, m.id) for m in last.markers]  # every message updates the same markers
    assert len(set(keys)) == len(keys)  # ids unique within each namespace
    kinds = by_ns(last)
    assert {ns: [m.id for m in ms] for ns, ms in kinds.items()} == {
        ros_msgs.NS_OUTLINE: [0, 1, 2], ros_msgs.NS_AXLE: [0, 1, 2], ros_msgs.NS_LABEL: [0, 1, 2],
        ros_msgs.NS_HITCHES: [0]}
    out = samples[-1]
    for m in last.markers:
        assert m.header.frame_id == "odom"
        assert m.header.stamp == ros_msgs.time_msg(out.t)
        assert m.action == Marker.ADD
        assert (m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z,
                m.pose.orientation.w) == (0.0, 0.0, 0.0, 1.0)
        assert m.color.a == 1.0
        assert all(p.z == 0.0 for p in m.points) and m.pose.position.z == 0.0
    for m in kinds[ros_msgs.NS_OUTLINE] + kinds[ros_msgs.NS_AXLE]:
        assert m.scale.x == pytest.approx(0.1)
    axles = kinds[ros_msgs.NS_AXLE]
    for k, m in enumerate(axles):
        assert m.type == Marker.LINE_LIST and len(m.points) == 2
        p, q = xy(m.points)
        assert ((p[0] + q[0]) / 2, (p[1] + q[1]) / 2) == pytest.approx(tuple(out.axle[k]))
        across = (q[0] - p[0], q[1] - p[1])
        assert across[0] * math.cos(out.heading[k]) + across[1] * math.sin(out.heading[k]) \
            == pytest.approx(0.0, abs=1e-9)
    (hitches,) = kinds[ros_msgs.NS_HITCHES]
    assert hitches.type == Marker.SPHERE_LIST and hitches.scale.x > 0.0
    assert xy(hitches.points) == [tuple(a) for a in out.front]
    assert [m.text for m in kinds[ros_msgs.NS_LABEL]] == ["tractor", "air_cart", "seeder"]
    assert all(m.type == Marker.TEXT_VIEW_FACING and m.scale.z > 0.0
               for m in kinds[ros_msgs.NS_LABEL])
    colours = [(m.color.r, m.color.g, m.color.b) for m in kinds[ros_msgs.NS_OUTLINE]]
    assert len(set(colours)) == 3
    assert [(c.r, c.g, c.b) for c in hitches.colors] == colours


def test_marker_array_serializes(lane_change):
    sim, samples = lane_change
    array = ros_msgs.train_markers(samples[-1], sim.scene.train)
    assert deserialize_message(serialize_message(array), type(array)) == array
    stored = decoded(array)
    assert [(m["ns"], m["id"], m["text"]) for m in stored["markers"]] == [
        (m.ns, m.id, m.text) for m in array.markers]


def test_markers_refuse_another_train(lane_change):
    _, samples = lane_change
    tr = load_train(REPO / "config/trains/single_tractor.yaml")
    with pytest.raises(ValueError, match="3 carts in the outputs, 1 in train"):
        ros_msgs.train_markers(samples[0], tr)


# -- diagnostics ---------------------------------------------------------------


@pytest.mark.parametrize("level, number", [(0, 0), (1, 1), (2, 2), (3, 3),
                                           (DiagnosticStatus.WARN, 1),
                                           (DiagnosticStatus.STALE, 3)])
def test_diagnostics_level_round_trips(level, number):
    array = ros_msgs.diagnostic_array(12.5, "mta_sim: tick", level, "late", {"misses": 3})
    (status,) = array.status
    assert status.level == bytes([number])
    assert deserialize_message(serialize_message(array), type(array)) == array
    (stored,) = decoded(array)["status"]
    assert stored["level"] == number


def test_diagnostics_content():
    values = {"p99": 0.0123456789, "count": 1200, "rtf": 1.0, "ok": True, "scene": "lane_change",
              "big": 1.5e12}
    array = ros_msgs.diagnostic_array(3.25, "mta_sim: timing", DiagnosticStatus.OK, "ok", values)
    assert (array.header.stamp.sec, array.header.stamp.nanosec) == (3, 250_000_000)
    stored = decoded(array)
    (status,) = stored["status"]
    assert status["name"] == "mta_sim: timing" and status["message"] == "ok"
    assert status["hardware_id"] == "mta_sim_ros"
    kv = {item["key"]: item["value"] for item in status["values"]}
    assert kv == {"p99": "0.0123457", "count": "1200", "rtf": "1", "ok": "True",
                  "scene": "lane_change", "big": "1.5e+12"}


@pytest.mark.parametrize("level", [4, -1, b"\x05", b"", b"\x00\x01"])
def test_diagnostics_refuse_unknown_levels(level):
    with pytest.raises(ValueError, match="diagnostic level"):
        ros_msgs.diagnostic_array(0.0, "x", level, "", {})


def test_markers_redrawn_in_place_equal_markers_built_afresh(lane_change):
    """The node's TrainMarkers reuses one MarkerArray; after any number of updates it equals,
    field by field, a MarkerArray built from scratch for the same outputs. (Not compared as CDR
    bytes: the serializer leaves alignment padding uninitialised.)"""
    sim, samples = lane_change
    redrawn = ros_msgs.TrainMarkers(sim.scene.train, "odom")
    for out in samples + [samples[0]]:  # along the run, then back to the start
        assert redrawn.update(out) == ros_msgs.train_markers(out, sim.scene.train, "odom")


# -- the node's encoding: CDR templates -------------------------------------------------------


def decode_with_mcap(type_name, data):
    decode, _ = codec(type_name)
    return plain(decode(data))


@pytest.mark.parametrize("frame_id", ["map", "odom", ""])
def test_encoded_outputs_decode_to_the_messages_built_field_by_field(lane_change, offset_hitch, frame_id):
    """OutputEncoder (the node's tick) writes values into CDR bytes serialized once; decoded with
    rclpy and, independently, with mcap_ros2, every topic equals output_messages of the same
    outputs. Several samples through one encoder: nothing of an earlier tick leaks into a later."""
    for sim, samples in (lane_change, offset_hitch):
        names = [c.name for c in sim.scene.train.carts]
        encoder = ros_msgs.OutputEncoder(names, frame_id)
        for out in samples + samples[::-1]:
            built = ros_msgs.output_messages(out, names, frame_id)
            data = encoder.encode(out)
            assert data.keys() == built.keys()
            for topic, msg in built.items():
                assert deserialize_message(data[topic], type(msg)) == msg, topic
                type_name = topics.TOPICS.get(topic) or "rosgraph_msgs/msg/Clock"
                assert decode_with_mcap(type_name, data[topic]) == decoded(msg), topic


def test_encoded_stamps_round_like_the_bag_stamp(lane_change):
    """Stamps written into the template carry sec and nanosec as ``bag.stamp`` rounds them,
    including the second boundary and large times."""
    import dataclasses

    sim, samples = lane_change
    encoder = ros_msgs.OutputEncoder([c.name for c in sim.scene.train.carts])
    for t in (0.0, 0.999999999, 1.0, 12.3456789, 3599.9999999996, 2.0**31 - 1.5):
        out = dataclasses.replace(samples[1], t=t)  # not the shared fixture's sample itself
        clock = deserialize_message(encoder.encode(out)["/clock"], ros_msgs.Clock)
        assert (clock.clock.sec, clock.clock.nanosec) == tuple(stamp(t).values()), t


def test_encoded_markers_decode_to_the_markers_built_afresh(lane_change, offset_hitch):
    """TrainMarkers.encode (the node's marker tick) equals train_markers built from scratch."""
    for sim, samples in (lane_change, offset_hitch):
        markers = ros_msgs.TrainMarkers(sim.scene.train, "odom")
        for out in samples + [samples[0]]:
            fresh = ros_msgs.train_markers(out, sim.scene.train, "odom")
            assert deserialize_message(markers.encode(out), type(fresh)) == fresh


def test_a_template_refuses_a_missing_or_repeated_sentinel():
    """A template whose message does not hold each sentinel exactly once is refused, naming it."""
    from std_msgs.msg import Float64MultiArray

    with pytest.raises(ValueError, match="value 1 found 0 times"):
        ros_msgs.CdrTemplate(Float64MultiArray(data=[ros_msgs.sentinel(0), 1.0]), 2, 0)
    with pytest.raises(ValueError, match="value 0 found 2 times"):
        ros_msgs.CdrTemplate(Float64MultiArray(data=[ros_msgs.sentinel(0)] * 2), 1, 0)
    with pytest.raises(ValueError, match="stamp found 0 times"):
        ros_msgs.CdrTemplate(ros_msgs.Clock(), 0, 1)
