"""Tests of the MCAP logging layer (mta_sim_ros.bag).

No ROS installation is needed: rclpy is used, when importable, only to
cross-check the CDR bytes (test_rclpy_interoperability is skipped otherwise).

Bags are read back with two independent readers: mcap + mcap_ros2 (through
mta_sim_ros.bag.reader) and rosbags.  rosbags 0.11 opens a bare ``.mcap``
file directly (``AnyReader([Path("run.mcap")])``: ``rosbags.rosbag2.Reader``
picks its MCAP storage by the ``.mcap`` suffix), no metadata.yaml directory
is needed; it requires profile "ros2" and a summary section, so a truncated
file must first go through ``recover()``.
"""

import json
import os
import resource
import signal
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import pytest
import yaml
from cdr_refs import assert_fields, rclpy_message
from child import call
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import StreamReader, breakup_chunk
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability, QosHistory, QosReliability
from rosbags.rosbag2.metadata import parse_qos
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from mta_sim_ros.bag import (
    DEFAULT_QOS_YAML,
    BagError,
    BagWriter,
    MessageDefinitionNotFound,
    clock,
    float64,
    holds_a_message,
    joint_state,
    message_definition,
    pose_array,
    qos_profiles_yaml,
    read_messages,
    read_metadata,
    recover,
    stamp,
    summary,
)
from mta_sim_ros.bag.schemas import SEPARATOR, share_dirs, vendored_dir
from mta_sim_ros.field.plan_io import PLAN_TYPE
from mta_sim_ros.messages.topics import BAG_TOPICS, STAMPED_CMD_VEL_TYPE

ROOT = Path(__file__).resolve().parents[1]

TOPICS = {
    "/hitch_poses": "geometry_msgs/msg/PoseArray",
    "/cart_velocities": "sensor_msgs/msg/JointState",
    "/traction_power": "std_msgs/msg/Float64",
    "/steering_angle": "std_msgs/msg/Float64",
    "/clock": "rosgraph_msgs/msg/Clock",
}
STEPS = 200
DT_NS = 50_000_000
METADATA = {"mta_sim_ros": {"scene": "unit_test", "dt": "0.05"}}
CARTS = ["cart_0", "cart_1", "cart_2"]


def expected_messages() -> list[tuple[str, int, dict]]:
    """The (topic, log_time_ns, message dict) sequence written by ``write_sample``."""
    out = []
    for i in range(STEPS):
        t_ns = i * DT_NS
        t = t_ns / 1e9
        hitches = [(0.1 * i - 4.0 * k, 0.01 * i * k, 0.003 * i * (k + 1)) for k in range(4)]
        out += [
            ("/clock", t_ns, clock(t)),
            ("/hitch_poses", t_ns, pose_array(t, "map", hitches)),
            ("/cart_velocities", t_ns, joint_state(
                t, CARTS, [0.5 * i + k for k in range(3)],
                [1.0 + 0.001 * i * k for k in range(3)])),
            ("/traction_power", t_ns, float64(1000.0 + 1.5 * i)),
            ("/steering_angle", t_ns, float64(-0.1 + 0.001 * i)),
        ]
    return out


def write_sample(path: Path, chunk_size: int = 8 * 1024) -> list[tuple[str, int, dict]]:
    """Write the sample bag; return the messages in write order."""
    messages = expected_messages()
    with BagWriter(path, metadata=METADATA, chunk_size=chunk_size) as bag:
        for topic, type_name in TOPICS.items():
            bag.add_topic(topic, type_name)
        for topic, t_ns, msg in messages:
            bag.write(topic, msg, log_time_ns=t_ns)
    return messages


def by_topic(messages) -> dict[str, list]:
    """Group ``(topic, time, msg)`` tuples per topic, keeping their order."""
    grouped = defaultdict(list)
    for topic, t_ns, msg in messages:
        grouped[topic].append((t_ns, msg))
    return dict(grouped)


def assert_messages_equal(actual, expected):
    """Same topics, same per-topic sequences of (log time, values)."""
    got, want = by_topic(actual), by_topic(expected)
    assert sorted(got) == sorted(want)
    for topic, items in want.items():
        assert len(got[topic]) == len(items), topic
        for (t_got, msg_got), (t_want, msg_want) in zip(got[topic], items):
            assert t_got == t_want
            assert_fields(msg_got, msg_want, topic)


def read_with_rosbags(path: Path):
    """All messages of a bare .mcap file, deserialized by rosbags; plus its connections."""
    with AnyReader([path]) as reader:
        messages = [(conn.topic, t_ns, reader.deserialize(raw, conn.msgtype))
                    for conn, t_ns, raw in reader.messages()]
        return messages, list(reader.connections)


def msg_file(type_name: str) -> str:
    """Verbatim installed .msg file of ``pkg/Name``."""
    pkg, name = type_name.split("/")
    for share in share_dirs():
        path = share / pkg / "msg" / f"{name}.msg"
        if path.is_file():
            return path.read_bytes().decode()
    raise AssertionError(f"{type_name}.msg not installed")


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    path = tmp_path_factory.mktemp("bag") / "sample.mcap"
    return path, write_sample(path)


@pytest.fixture
def fake_msgs(tmp_path) -> dict[str, str]:
    """The environment of a process that has a fake interface package on AMENT_PREFIX_PATH. The
    tests that read it run in such a process of their own (``child.call``): a process reads the
    variable, and caches the definitions, for good."""
    msg_dir = tmp_path / "prefix" / "share" / "fake_msgs" / "msg"
    msg_dir.mkdir(parents=True)
    (msg_dir / "Outer.msg").write_text(
        "# Outer: mentions Pose only in this comment\n"
        "std_msgs/Header header\n"
        "Inner[] inners\n"
        "Inner[2] pair\n"
        "Inner[<=4] bounded\n"
        "geometry_msgs/Point p\n"
        "string<=8 name\n"
        "float64[<=3] xs\n"
        "uint8 LIMIT=3\n")
    (msg_dir / "Inner.msg").write_text("geometry_msgs/Point where\nint32 k\n")
    (msg_dir / "Stamped.msg").write_text("Header header\nfloat64 value\n")
    (msg_dir / "Broken.msg").write_text("float64 ok\nMissing m\n")
    return {"AMENT_PREFIX_PATH": str(tmp_path / "prefix")}


# -- schemas -------------------------------------------------------------------

def sep(type_name: str) -> str:
    return f"\n{SEPARATOR}\nMSG: {type_name}\n"


def test_pose_array_definition_is_rosbag2_text():
    text = message_definition("geometry_msgs/msg/PoseArray")
    # rosbag2_cpp LocalMessageDefinitionSource: file verbatim, then each nested
    # type once, depth-first, dependencies of one file in sorted order.
    assert text == (
        msg_file("geometry_msgs/PoseArray")
        + sep("geometry_msgs/Pose") + msg_file("geometry_msgs/Pose")
        + sep("geometry_msgs/Point") + msg_file("geometry_msgs/Point")
        + sep("geometry_msgs/Quaternion") + msg_file("geometry_msgs/Quaternion")
        + sep("std_msgs/Header") + msg_file("std_msgs/Header")
        + sep("builtin_interfaces/Time") + msg_file("builtin_interfaces/Time"))
    assert message_definition("geometry_msgs/PoseArray") == text


@pytest.mark.parametrize("type_name", sorted(set(TOPICS.values())))
def test_definitions_match_rosbags_typestore(type_name):
    """rosbags parses our text into exactly the field definitions of its Jazzy store."""
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    types = get_types_from_msg(message_definition(type_name), type_name)
    assert type_name in types
    for name, fielddefs in types.items():
        assert fielddefs == jazzy.fielddefs[name], name


def test_vendored_definitions_are_the_installed_files_of_every_type_the_package_writes():
    """bag/msg holds, byte for byte, the installed .msg file of each type the package writes into a
    bag (the node's, a field plan's) and of each type those nest (the MSG: blocks of their
    definitions), and nothing else: a venv without ROS (test_no_ros.py) writes the schemas a ROS
    install writes."""
    needed = set()
    for type_name in set(BAG_TOPICS.values()) | {PLAN_TYPE, STAMPED_CMD_VEL_TYPE}:  # the node's bags, a plan's
        needed.add(type_name.replace("/msg/", "/"))
        needed.update(line[5:] for line in message_definition(type_name).splitlines() if line.startswith("MSG: "))
    root = Path(str(vendored_dir()))
    vendored = {f"{p.parent.name}/{p.stem}" for p in root.glob("*/*.msg")}
    assert vendored == needed
    for type_name in sorted(vendored):
        pkg, name = type_name.split("/")
        installed = [share / pkg / "msg" / f"{name}.msg" for share in share_dirs()]
        installed = [path for path in installed if path.is_file()]
        assert installed, f"{type_name}.msg is not installed here to compare with"
        assert (root / pkg / f"{name}.msg").read_bytes() == installed[0].read_bytes(), type_name
    hashes = json.loads((root / "type_hashes.json").read_text())
    assert set(hashes) == {t.replace("/", "/msg/") for t in vendored}
    for type_name in sorted(vendored):
        assert hashes[type_name.replace("/", "/msg/")] == installed_type_hash(type_name), type_name


def installed_type_hash(type_name: str) -> str:
    """The RIHS01 hash in the type description Jazzy's rosidl installed (share/<pkg>/msg/<Name>.json)."""
    pkg, name = type_name.replace("/msg/", "/").split("/")
    [path] = [p for p in (share / pkg / "msg" / f"{name}.json" for share in share_dirs()) if p.is_file()][:1]
    [entry] = [h for h in json.loads(path.read_text())["type_hashes"] if h["type_name"] == f"{pkg}/msg/{name}"]
    return entry["hash_string"]


def test_field_type_resolution(fake_msgs):
    call(field_type_resolution, env=fake_msgs)


def field_type_resolution():
    text = message_definition("fake_msgs/msg/Outer")
    blocks = [line[5:] for line in text.splitlines() if line.startswith("MSG: ")]
    # sorted per file, depth first, each once: Point comes via Inner first
    assert blocks == ["fake_msgs/Inner", "geometry_msgs/Point", "std_msgs/Header",
                      "builtin_interfaces/Time"]
    assert "MSG: geometry_msgs/Pose\n" not in text  # only mentioned in a comment
    assert sorted(get_types_from_msg(text, "fake_msgs/msg/Outer")) == [
        "builtin_interfaces/msg/Time", "fake_msgs/msg/Inner", "fake_msgs/msg/Outer",
        "geometry_msgs/msg/Point", "std_msgs/msg/Header"]
    stamped = message_definition("fake_msgs/msg/Stamped")
    assert sep("std_msgs/Header") in stamped  # bare Header means std_msgs/Header


def test_bounded_and_fixed_arrays_roundtrip(fake_msgs, tmp_path):
    call(bounded_and_fixed_arrays_roundtrip, str(tmp_path / "fake.mcap"), env=fake_msgs)


def bounded_and_fixed_arrays_roundtrip(bag_path: str):
    path = Path(bag_path)
    msg = {"header": {"stamp": {"sec": -2, "nanosec": 300_000_000}, "frame_id": "f"},
           "inners": [{"where": {"x": 1.0, "y": 2.0, "z": 3.0}, "k": -7}],
           "pair": [{"where": {"x": 0.5, "y": 0.0, "z": 0.0}, "k": 1},
                    {"where": {"x": 0.0, "y": 0.0, "z": 0.0}, "k": 2}],
           "bounded": [], "p": {"x": 0.0, "y": 0.0, "z": 2.5}, "name": "abc",
           "xs": [1.0, 2.0]}
    with BagWriter(path) as bag:
        bag.add_topic("/fake", "fake_msgs/msg/Outer")
        bag.write("/fake", msg, log_time_ns=5)
    [(topic, t_ns, decoded)] = list(read_messages(path))
    assert (topic, t_ns) == ("/fake", 5)
    assert_fields(decoded, msg)
    [(_, _, by_rosbags)], _ = read_with_rosbags(path)
    assert_fields(by_rosbags, msg)


def test_missing_definitions_name_the_type(fake_msgs):
    call(missing_definitions_name_the_type, env=fake_msgs)


def missing_definitions_name_the_type():
    with pytest.raises(MessageDefinitionNotFound, match="nope_msgs/msg/Nothing"):
        message_definition("nope_msgs/msg/Nothing")
    missing = r"fake_msgs/msg/Missing.*needed by fake_msgs/Broken"
    with pytest.raises(MessageDefinitionNotFound, match=missing):
        message_definition("fake_msgs/msg/Broken")
    with pytest.raises(ValueError, match="not a ROS 2 message type"):
        message_definition("Float64")


# -- writer --------------------------------------------------------------------

def test_qos_yaml_is_rosbag2_jazzy_format():
    assert DEFAULT_QOS_YAML == (
        "- history: keep_last\n  depth: 10\n  reliability: reliable\n  durability: volatile\n"
        "  deadline:\n    sec: 9223372036\n    nsec: 854775807\n"
        "  lifespan:\n    sec: 9223372036\n    nsec: 854775807\n"
        "  liveliness: automatic\n"
        "  liveliness_lease_duration:\n    sec: 9223372036\n    nsec: 854775807\n"
        "  avoid_ros_namespace_conventions: false")
    [qos] = parse_qos(qos_profiles_yaml("best_effort", "transient_local", "keep_last", 1))
    assert (qos.reliability, qos.durability, qos.history, qos.depth) == (
        QosReliability.BEST_EFFORT, QosDurability.TRANSIENT_LOCAL, QosHistory.KEEP_LAST, 1)
    with pytest.raises(ValueError, match="reliability"):
        qos_profiles_yaml(reliability="sometimes")


def test_builders():
    assert stamp(1.5) == {"sec": 1, "nanosec": 500_000_000}
    assert stamp(-1.7) == {"sec": -2, "nanosec": 300_000_000}
    assert stamp(2.9999999999) == {"sec": 3, "nanosec": 0}
    pose = pose_array(0.0, "map", [(1.0, 2.0, 3.141592653589793 / 2)])["poses"][0]
    assert pose["position"] == {"x": 1.0, "y": 2.0, "z": 0.0}
    assert pose["orientation"]["z"] == pytest.approx(2 ** -0.5)
    assert pose["orientation"]["w"] == pytest.approx(2 ** -0.5)
    with pytest.raises(ValueError):
        joint_state(0.0, ["a", "b"], [1.0], [1.0, 2.0])


def test_file_layout_read_with_mcap(sample):
    path, written = sample
    with open(path, "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        info = reader.get_summary()
    assert header.profile == "ros2"
    assert "mta_sim_ros" in header.library
    schemas = {s.name: s for s in info.schemas.values()}
    assert sorted(schemas) == sorted(set(TOPICS.values()))
    for schema in schemas.values():
        assert schema.encoding == "ros2msg"
        assert schema.data.decode() == message_definition(schema.name)
    pose_text = schemas["geometry_msgs/msg/PoseArray"].data.decode()
    for nested in ("geometry_msgs/Pose", "geometry_msgs/Point", "geometry_msgs/Quaternion",
                   "std_msgs/Header", "builtin_interfaces/Time"):
        assert f"{SEPARATOR}\nMSG: {nested}\n" in pose_text
    for channel in info.channels.values():
        assert channel.message_encoding == "cdr"
        assert info.schemas[channel.schema_id].name == TOPICS[channel.topic]
        [qos] = yaml.safe_load(channel.metadata["offered_qos_profiles"])
        assert qos["reliability"] == "reliable" and qos["depth"] == 10
        assert qos["deadline"] == {"sec": 9223372036, "nsec": 854775807}
        assert channel.metadata["topic_type_hash"] == installed_type_hash(TOPICS[channel.topic])
    counts = {info.channels[c].topic: n for c, n in info.statistics.channel_message_counts.items()}
    assert counts == {topic: STEPS for topic in TOPICS}
    assert info.statistics.message_count == len(written)


def test_chunks_are_small_compressed_and_crc_checked(sample):
    path, _ = sample
    with open(path, "rb") as f:
        chunks = [r for r in StreamReader(f, emit_chunks=True).records if isinstance(r, Chunk)]
    assert len(chunks) > 5
    largest_record = 600  # a PoseArray message record of the sample is ~300 bytes
    for chunk in chunks:
        assert chunk.compression == "zstd"
        assert chunk.uncompressed_crc != 0
        assert chunk.uncompressed_size <= 8 * 1024 + largest_record
        breakup_chunk(chunk, validate_crc=True)


def test_read_back_with_mcap_ros2(sample):
    path, written = sample
    assert_messages_equal(list(read_messages(path)), written)
    assert [t for t, _, _ in read_messages(path, topics=["/clock"])] == ["/clock"] * STEPS
    assert read_metadata(path) == METADATA
    assert summary(path) == {topic: {"type": type_name, "count": STEPS}
                             for topic, type_name in TOPICS.items()}


def test_read_back_with_rosbags(sample):
    path, written = sample
    messages, connections = read_with_rosbags(path)
    assert_messages_equal(messages, written)
    assert {c.topic: (c.msgtype, c.msgcount) for c in connections} == {
        topic: (type_name, STEPS) for topic, type_name in TOPICS.items()}
    for conn in connections:
        assert conn.ext.serialization_format == "cdr"
        [qos] = conn.ext.offered_qos_profiles
        assert qos.reliability == QosReliability.RELIABLE
        assert qos.durability == QosDurability.VOLATILE


def test_rclpy_interoperability(sample, tmp_path):
    """rclpy decodes the bag's CDR to the written values, and rclpy-serialized bytes
    stored with write_raw() decode back to them (only CDR padding bytes may differ)."""
    serialization = pytest.importorskip("rclpy.serialization")
    path, written = sample
    with open(path, "rb") as f:
        stored = [m.data for _, _, m in make_reader(f).iter_messages(log_time_order=False)]
    raw_path = tmp_path / "raw.mcap"
    with BagWriter(raw_path) as bag:
        for topic, type_name in TOPICS.items():
            bag.add_topic(topic, type_name)
        for data, (topic, t_ns, msg) in zip(stored, written):
            ros_msg = rclpy_message(TOPICS[topic], msg)
            assert serialization.deserialize_message(data, type(ros_msg)) == ros_msg, topic
            bag.write_raw(topic, serialization.serialize_message(ros_msg), t_ns)
    assert_messages_equal(list(read_messages(raw_path)), written)


def test_write_errors_keep_writer_usable(tmp_path):
    path = tmp_path / "errors.mcap"
    bag = BagWriter(path)
    bag.add_topic("/power", "std_msgs/msg/Float64")
    with pytest.raises(BagError, match="not registered"):
        bag.write("/nope", float64(1.0), log_time_ns=0)
    with pytest.raises(BagError, match="std_msgs/msg/Float64"):
        bag.write("/power", {"data": "not a number"}, log_time_ns=0)
    with pytest.raises(BagError, match="log_time_ns"):
        bag.write("/power", float64(1.0), log_time_ns=-1)
    with pytest.raises(BagError, match="already registered"):
        bag.add_topic("/power", "std_msgs/msg/Float32")
    with pytest.raises(BagError, match="str"):
        bag.add_metadata("m", {"k": 1})
    bag.add_topic("/power", "std_msgs/msg/Float64")  # same registration: no-op
    bag.write("/power", float64(2.0), log_time_ns=1)
    bag.close()
    bag.close()  # idempotent
    with pytest.raises(BagError, match="closed"):
        bag.write("/power", float64(3.0), log_time_ns=2)
    [(_, _, msg)] = list(read_messages(path))
    assert msg.data == 2.0


def test_unwritable_locations_raise_bag_error(tmp_path):
    not_a_dir = tmp_path / "file"
    not_a_dir.write_text("x")
    for path in (not_a_dir / "run.mcap", tmp_path / "missing_dir" / "run.mcap"):
        with pytest.raises(BagError, match=str(path)):
            BagWriter(path)


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_disk_full_at_open_raises_bag_error():
    with pytest.raises(BagError, match="/dev/full.*No space left"):
        BagWriter("/dev/full")


def run_child(code: str, *args: str, **kwargs) -> subprocess.Popen:
    """Start a Python child that can import mta_sim_ros from this checkout."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p))
    return subprocess.Popen([sys.executable, "-c", code, *args], env=env, text=True, **kwargs)


DISK_FULL_CHILD = r"""
import resource, signal, sys
from mta_sim_ros.bag import BagError, BagWriter, float64
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (40_000, resource.RLIM_INFINITY))
path = sys.argv[1]
bag = BagWriter(path, chunk_size=4096)
bag.add_topic("/power", "std_msgs/msg/Float64")
try:
    for i in range(1_000_000):
        bag.write("/power", float64(0.5 * i), log_time_ns=i)
except BagError as exc:
    assert path in str(exc) and bag.closed, exc
    bag.close()
    bag.close()
    print("FAILED ONCE:", exc)
"""


@pytest.mark.skipif(not hasattr(resource, "RLIMIT_FSIZE"), reason="needs RLIMIT_FSIZE")
def test_write_failure_raises_once_and_file_is_recoverable(tmp_path):
    path = tmp_path / "full.mcap"
    child = run_child(DISK_FULL_CHILD, str(path), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    out, err = child.communicate(timeout=120)
    assert child.returncode == 0, err
    assert "FAILED ONCE:" in out and "File too large" in out
    result = recover(path, tmp_path / "full_recovered.mcap")
    assert not result["complete"]
    messages, _ = read_with_rosbags(tmp_path / "full_recovered.mcap")
    assert len(messages) == result["total_messages"] > 100
    assert [m.data for _, _, m in messages] == [0.5 * i for i in range(len(messages))]


# -- recovery ------------------------------------------------------------------

def chunk_table(path: Path) -> list[tuple[int, int, int]]:
    """``(start offset, end offset, message count)`` of every chunk of a complete file."""
    table = []
    with open(path, "rb") as f:
        for index in make_reader(f).get_summary().chunk_indexes:
            f.seek(index.chunk_start_offset)
            chunk = next(StreamReader(f, skip_magic=True, emit_chunks=True).records)
            count = sum(isinstance(r, Message) for r in breakup_chunk(chunk))
            end = index.chunk_start_offset + index.chunk_length
            table.append((index.chunk_start_offset, end, count))
    return table


def data_section_end(path: Path) -> int:
    """Offset of the summary section, i.e. the end of a complete file's data section."""
    with open(path, "rb") as f:
        f.seek(-(8 + 9 + 20), os.SEEK_END)
        footer = next(StreamReader(f, skip_magic=True).records)
    return footer.summary_start


def channel_info(path: Path) -> dict[str, tuple]:
    with open(path, "rb") as f:
        info = make_reader(f).get_summary()
    return {c.topic: (info.schemas[c.schema_id].name, info.schemas[c.schema_id].data, c.metadata)
            for c in info.channels.values()}


@pytest.mark.parametrize("cut", [0.05, 0.6, 0.9, "len-7", "none"])
def test_recover_truncated_file(sample, tmp_path, cut):
    """Cut the file (fractions of its data section, or 7 bytes short) and recover it.

    A cut inside the data section is what a SIGKILL leaves behind: every chunk
    that ends before the cut must be recovered, i.e. at most the one chunk
    straddling the cut is lost.
    """
    path, written = sample
    data = path.read_bytes()
    if isinstance(cut, float):
        size = int(data_section_end(path) * cut)
    else:
        size = len(data) - (7 if cut == "len-7" else 0)
    truncated = tmp_path / "truncated.mcap"
    truncated.write_bytes(data[:size])
    if size < len(data):
        with pytest.raises(BagError, match="recover"):
            summary(truncated)

    recovered = tmp_path / "recovered.mcap"
    result = recover(truncated, recovered)
    assert holds_a_message(truncated) == (result["total_messages"] > 0)

    chunks = chunk_table(path)
    complete_chunks = [count for _, end, count in chunks if end <= size]
    started = sum(count for start, _, count in chunks if start < size)
    assert result["total_messages"] == sum(complete_chunks)
    assert result["total_messages"] >= started - max(count for _, _, count in chunks)
    assert result["chunks"] == len(complete_chunks)
    assert result["complete"] == isinstance(cut, str)
    if result["complete"]:
        assert result["bytes_dropped"] == 0
        assert result["total_messages"] == len(written)
    else:
        assert 0 < result["bytes_dropped"] < size
    # messages of complete chunks are a prefix of the written sequence
    prefix = written[:result["total_messages"]]
    assert result["messages"] == {t: len(v) for t, v in by_topic(prefix).items()}
    messages, _ = read_with_rosbags(recovered)
    assert_messages_equal(messages, prefix)
    assert_messages_equal(list(read_messages(recovered)), prefix)
    assert read_metadata(recovered) == METADATA
    assert channel_info(recovered) == channel_info(path)
    with open(recovered, "rb") as f:
        assert make_reader(f).get_header().profile == "ros2"


def test_flush_makes_open_chunk_recoverable(tmp_path):
    """After flush() everything written so far survives a kill (file copied while open)."""
    path = tmp_path / "open.mcap"
    bag = BagWriter(path)
    bag.add_topic("/power", "std_msgs/msg/Float64")
    for i in range(10):
        bag.write("/power", float64(i), log_time_ns=i)
    bag.flush()
    snapshot = tmp_path / "snapshot.mcap"
    snapshot.write_bytes(path.read_bytes())
    bag.close()
    result = recover(snapshot, tmp_path / "snapshot_recovered.mcap")
    assert result["messages"] == {"/power": 10}
    assert result["bytes_dropped"] == 0


def test_a_file_whose_only_chunk_fails_its_crc_holds_no_message(tmp_path):
    """One chunk, one byte of its data changed: recover drops it, and holds_a_message, which
    answers what recover would find, says no message; the file before the change says yes."""
    path = tmp_path / "one_chunk.mcap"
    with BagWriter(path, compression="none") as bag:
        bag.add_topic("/power", "std_msgs/msg/Float64")
        for i in range(10):
            bag.write("/power", float64(i), log_time_ns=i)
    [(start, end, count)] = chunk_table(path)
    assert count == 10 and holds_a_message(path)
    data = bytearray(path.read_bytes())
    data[end - 20] ^= 0xFF  # inside the last message of the chunk's records
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    assert not holds_a_message(damaged)
    assert recover(damaged, tmp_path / "damaged_recovered.mcap")["chunks_dropped"] == 1
    assert not holds_a_message(tmp_path / "missing.mcap")


def test_a_message_on_a_channel_recover_drops_is_not_a_message_held(tmp_path):
    """A message whose channel the file never registers (or registers with a lost schema) is
    one recover() drops: the file holds no message; the same message on its channel, one."""
    from mcap.writer import Writer

    for registered in (False, True):
        path = tmp_path / f"loose_{registered}.mcap"
        with open(path, "wb") as f:
            w = Writer(f, use_chunking=False)
            w.start("ros2", "test")
            channel = 7
            if registered:
                schema = w.register_schema("std_msgs/msg/Float64", "ros2msg", b"float64 data")
                channel = w.register_channel("/power", "cdr", schema)
            w.add_message(channel, log_time=1, data=b"\x00\x01\x00\x00" + bytes(8), publish_time=1)
            w.finish()
        assert holds_a_message(path) == registered
        assert recover(path, tmp_path / f"r_{registered}.mcap")["total_messages"] == int(registered)


def test_recover_cut_before_first_chunk(sample, tmp_path):
    """Only header and metadata survive: an empty but valid bag."""
    path, _ = sample
    truncated, recovered = tmp_path / "short.mcap", tmp_path / "short_recovered.mcap"
    truncated.write_bytes(path.read_bytes()[:1000])
    result = recover(truncated, recovered)
    assert not holds_a_message(truncated)
    assert (result["total_messages"], result["chunks"], result["complete"]) == (0, 0, False)
    assert read_metadata(recovered) == METADATA
    assert summary(recovered) == {}
    assert read_with_rosbags(recovered) == ([], [])


def test_recover_rejects_non_mcap(tmp_path):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all")
    with pytest.raises(BagError, match="junk.mcap"):
        recover(junk, tmp_path / "out.mcap")
    with pytest.raises(BagError, match="same file"):
        recover(junk, junk)


KILLED_CHILD = r"""
import sys
from mta_sim_ros.bag import BagWriter, float64
bag = BagWriter(sys.argv[1], chunk_size=int(sys.argv[2]))
bag.add_topic("/traction_power", "std_msgs/msg/Float64")
i = 0
while True:
    bag.write("/traction_power", float64(0.5 * i), log_time_ns=1000 * i)
    i += 1
    print(i, flush=True)
"""


def test_sigkill_loses_at_most_one_chunk(tmp_path):
    """A writer killed with SIGKILL loses only its open chunk (module docstring bound)."""
    path, chunk_size = tmp_path / "killed.mcap", 4096
    child = run_child(KILLED_CHILD, str(path), str(chunk_size), stdout=subprocess.PIPE)
    written = 0
    try:
        while written < 2000:
            written = int(child.stdout.readline())
    finally:
        child.send_signal(signal.SIGKILL)
        child.communicate(timeout=30)
    result = recover(path, tmp_path / "killed_recovered.mcap")
    record_size = 9 + 2 + 4 + 8 + 8 + 12  # Message record of a CDR Float64
    assert written - result["total_messages"] <= chunk_size // record_size + 1
    messages, _ = read_with_rosbags(tmp_path / "killed_recovered.mcap")
    assert [(t_ns, m.data) for _, t_ns, m in messages] == [
        (1000 * i, 0.5 * i) for i in range(result["total_messages"])]


def chunk_spans(path) -> list[tuple[int, int]]:
    """(first, last) log time of each chunk in the file, in file order."""
    with open(path, "rb") as f:
        return [(r.message_start_time, r.message_end_time)
                for r in StreamReader(f, emit_chunks=True).records if isinstance(r, Chunk)]


@pytest.mark.parametrize("flush_after_ns", [0, 50 * 10**7])
def test_flush_after_bounds_each_chunk_in_log_time(tmp_path, flush_after_ns):
    """With flush_after_ns a chunk is written once it spans that much log time, long before it
    fills (small messages, 64 KiB chunks); without it, by size only. messages_in_file counts what
    a kill would leave."""
    path = tmp_path / "timed.mcap"
    bag = BagWriter(path, flush_after_ns=flush_after_ns)
    bag.add_topic("/traction_power", "std_msgs/msg/Float64")
    for i in range(1000):  # 10 s of log time at 100 Hz, 23 bytes of data a message
        bag.write("/traction_power", float64(float(i)), log_time_ns=i * 10**7)
    in_file = bag.messages_in_file
    bag.close()
    spans = chunk_spans(path)
    if flush_after_ns:
        assert len(spans) == 1000 // 51 + 1 and in_file == 51 * (1000 // 51)
        assert all(last - first <= flush_after_ns for first, last in spans)
    else:
        assert len(spans) == 1 and in_file == 0
    assert bag.messages_in_file == 1000
