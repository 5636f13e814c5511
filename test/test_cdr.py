"""The CDR serializer (mta_sim_ros.bag.cdr) against three independent references.

mcap_ros2's public writer (the serializer the project's bags were written with until now): equal
bytes, so bags stay identical; rclpy and rosbags: the bytes decode to the message built field by
field. Every primitive type, nested messages and sequences, strings of every length modulo 4
(padding), defaults, and the errors of bad input.
"""
from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from rclpy.serialization import deserialize_message

from mta_sim_ros.bag import BagError, BagWriter, MessageDefinitionNotFound, cdr, writer
from mta_sim_ros.bag.cdr import EncodeError, MessageEncoder, Slot
from mta_sim_ros.bag.definition import DefinitionError, parse_definition

from cdr_refs import assert_fields, mcap_ros2_bytes, rclpy_message, rosbags_decode

NAMES = ["", "a", "ab", "abc", "abcd", "tractor", "air_cart", "seeder"]  # every length mod 4


def marker(i: int, text: str) -> dict:
    return {"header": writer.header(0.5 * i, "map"), "ns": text, "id": i, "type": 4, "action": 0,
            "pose": {"position": {"x": 1.0 * i, "y": -2.0, "z": 0.0}},
            "scale": {"x": 0.1}, "color": {"r": 0.125, "g": 0.5, "b": 0.75, "a": 1.0},
            "lifetime": {"sec": 1, "nanosec": 5}, "frame_locked": bool(i % 2),
            "points": [{"x": 0.5 * k, "y": 1.5, "z": 0.0} for k in range(i)],
            "colors": [{"r": 1.0, "g": 0.0625, "b": 0.0, "a": 1.0}] * (i % 3),
            "texture_resource": text[:i], "texture": {"format": text, "data": bytes(range(i))},
            "uv_coordinates": [{"u": 0.25, "v": 0.75}] * (i % 2), "text": text * 2,
            "mesh_resource": text[1:], "mesh_file": {"filename": text + ".dae", "data": list(range(i % 5))},
            "mesh_use_embedded_materials": True}


def diagnostics(t: float, values: dict) -> dict:
    return {"header": writer.header(t, ""),
            "status": [{"level": level, "name": name, "message": name * 3, "hardware_id": "mta_sim_ros",
                        "values": [{"key": k, "value": v} for k, v in values.items()]}
                       for level, name in enumerate(NAMES[:4])]}


#: Messages of every type the project writes: nested sequences, strings of odd lengths, negative
#: and large stamps, empty sequences.
PROJECT_MESSAGES = {
    "geometry_msgs/msg/PoseArray": [
        writer.pose_array(0.0, "", []),
        writer.pose_array(12.345, "map", [(1.0, 2.0, 0.3)]),
        writer.pose_array(-1.5, "odom", [(0.1 * k, -0.2 * k, 0.7 * k) for k in range(7)]),
    ],
    "sensor_msgs/msg/JointState": [
        writer.joint_state(0.25, NAMES[:k], [0.5] * k, [k * 1.0] * k, efforts=[-1.0] * k if k % 2 else ())
        for k in range(len(NAMES) + 1)
    ] + [writer.joint_state(3.0, NAMES, list(range(8)), [0.0] * 8, frame_id="base_link")],
    "std_msgs/msg/Float64": [writer.float64(x) for x in (0.0, -2.5, 1e300, math.pi)],
    "rosgraph_msgs/msg/Clock": [writer.clock(t) for t in (0.0, 1.999999999, 2.0 ** 31 - 1.5)],
    "visualization_msgs/msg/MarkerArray": [{"markers": []}, {"markers": [marker(i, NAMES[i]) for i in range(8)]}],
    "diagnostic_msgs/msg/DiagnosticArray": [
        diagnostics(3.25, {}), diagnostics(1.0, {name: name * 5 for name in NAMES})],
}
PROJECT_CASES = [(t, i) for t, msgs in PROJECT_MESSAGES.items() for i in range(len(msgs))]


@pytest.mark.parametrize("type_name", sorted(PROJECT_MESSAGES))
def test_bytes_equal_mcap_ros2s_writer_for_every_type_we_write(type_name):
    messages = PROJECT_MESSAGES[type_name]
    assert [cdr.encode(type_name, m) for m in messages] == mcap_ros2_bytes(type_name, messages)


@pytest.mark.parametrize("type_name, i", PROJECT_CASES)
def test_bytes_decode_with_rclpy_and_rosbags(type_name, i):
    msg = PROJECT_MESSAGES[type_name][i]
    data = cdr.encode(type_name, msg)
    expected = rclpy_message(type_name, msg)
    assert deserialize_message(data, type(expected)) == expected
    assert_fields(rosbags_decode(type_name, data), msg)


# -- every primitive type ------------------------------------------------------------------------

ALL_TYPES = "test_msgs/msg/AllTypes"
ALL_TYPES_TEXT = """\
# Every primitive of a .msg file, as scalars and in arrays; constants and defaults.
uint8 ANSWER=42
string GREETING = hello
bool flag
byte octet
char letter
float32 f32
float64 f64
int8 i8
uint8 u8
int16 i16
uint16 u16
int32 i32
uint32 u32
int64 i64
uint64 u64
string text  # a comment after a field
string<=5 short_text
float64 with_default 1.5
int32 int_default -7
string str_default "a b"
bool bool_default true
float64[] f64_seq
float32[3] f32_fixed
int16[<=4] i16_bounded
uint8[] u8_seq
byte[2] byte_fixed
bool[] bool_seq
int64[2] i64_fixed
uint64[] u64_seq
string[] text_seq
string<=3[<=2] bounded_texts
Inner inner
Inner[] inners
Inner[2] inner_pair
Empty empty
Empty[] empties
uint8 tail
================================================================================
MSG: test_msgs/Inner
int8 small
float64 big
string name
================================================================================
MSG: test_msgs/Empty
"""


def all_types(k: int) -> dict:
    """An AllTypes message; k varies the lengths (so the padding) and the values."""
    return {
        "flag": bool(k % 2), "octet": 255 - k, "letter": 65 + k, "f32": 0.5 * k, "f64": math.pi * k,
        "i8": -128 + k, "u8": 255 - k, "i16": -32768 + k, "u16": 65535 - k, "i32": -2 ** 31 + k,
        "u32": 2 ** 32 - 1 - k, "i64": -2 ** 63 + k, "u64": 2 ** 64 - 1 - k,
        "text": NAMES[k % len(NAMES)], "short_text": "xyz"[:k % 4],
        "with_default": -0.25, "int_default": k, "str_default": NAMES[(k + 1) % len(NAMES)], "bool_default": False,
        "f64_seq": [0.1 * j for j in range(k)], "f32_fixed": [1.0, -2.5, float(k)], "i16_bounded": [-3] * (k % 5),
        "u8_seq": bytes(range(k)), "byte_fixed": [k, 7], "bool_seq": [True, False][: k % 3],
        "i64_fixed": [k, -k], "u64_seq": [2 ** 63 + j for j in range(k % 3)],
        "text_seq": NAMES[:k], "bounded_texts": ["a", "bcd"][: k % 3],
        "inner": {"small": -k, "big": 1e10 * k, "name": NAMES[k % 8]},
        "inners": [{"small": j, "big": -1.0 * j, "name": NAMES[j % 8]} for j in range(k % 4)],
        "inner_pair": [{"small": 1, "big": 2.0, "name": "p"}, {"small": 3, "big": 4.0, "name": "qq"}],
        "empty": {}, "empties": [{}] * (k % 3), "tail": k,
    }


ALL_TYPES_MESSAGES = [all_types(k) for k in range(9)]


def test_every_primitive_type_equals_mcap_ros2():
    encoder = MessageEncoder(ALL_TYPES, ALL_TYPES_TEXT)
    assert [encoder.encode(m) for m in ALL_TYPES_MESSAGES] == mcap_ros2_bytes(
        ALL_TYPES, ALL_TYPES_MESSAGES, ALL_TYPES_TEXT)


@pytest.mark.parametrize("k", range(9))
def test_every_primitive_type_decodes_with_rosbags(k):
    msg = all_types(k)
    decoded = rosbags_decode(ALL_TYPES, MessageEncoder(ALL_TYPES, ALL_TYPES_TEXT).encode(msg), ALL_TYPES_TEXT)
    assert decoded.octet % 256 == msg.pop("octet")  # rosbags reads byte as int8: the same bits
    assert_fields(decoded, msg)


def test_numpy_values_give_the_same_bytes_as_python_values():
    encoder = MessageEncoder(ALL_TYPES, ALL_TYPES_TEXT)
    msg = all_types(5)
    as_numpy = {**msg, "f64": np.float64(msg["f64"]), "i32": np.int32(msg["i32"]), "flag": np.bool_(msg["flag"]),
                "f64_seq": np.array(msg["f64_seq"]), "f32_fixed": np.array(msg["f32_fixed"], dtype=np.float32),
                "i16_bounded": np.array(msg["i16_bounded"], dtype=np.int64), "u8_seq": np.frombuffer(msg["u8_seq"], np.uint8),
                "u64_seq": np.array(msg["u64_seq"], dtype=np.uint64), "bool_seq": np.array(msg["bool_seq"], dtype=bool),
                "i64_fixed": tuple(msg["i64_fixed"]), "byte_fixed": [bytes([b]) for b in msg["byte_fixed"]]}
    assert encoder.encode(as_numpy) == encoder.encode(msg)


def test_missing_fields_take_the_definitions_defaults_as_mcap_ros2_does():
    encoder = MessageEncoder(ALL_TYPES, ALL_TYPES_TEXT)
    partial = [{}, {"inner": {}, "inner_pair": [{"name": "x"}, {}]}, {"f64": None, "text_seq": None}]
    assert [encoder.encode(m) for m in partial] == mcap_ros2_bytes(ALL_TYPES, partial, ALL_TYPES_TEXT)
    decoded = rosbags_decode(ALL_TYPES, encoder.encode({}), ALL_TYPES_TEXT)
    assert (decoded.with_default, decoded.int_default, decoded.str_default, decoded.bool_default) == (1.5, -7, "a b", True)
    assert list(decoded.f32_fixed) == [0.0] * 3 and len(decoded.inner_pair) == 2
    # geometry_msgs/Quaternion says w 1: a pose without orientation is the identity
    pose = {"poses": [{"position": {"x": 1.0}}]}
    data = cdr.encode("geometry_msgs/msg/PoseArray", pose)
    assert data == mcap_ros2_bytes("geometry_msgs/msg/PoseArray", [pose])[0]
    assert rosbags_decode("geometry_msgs/msg/PoseArray", data).poses[0].orientation.w == 1.0


def test_array_defaults():
    text = 'float64[2] pair [1.5, -2]\nstring[] words ["a, b", \'c\', d]\nint8[<=3] few [1,2]\n'
    decoded = rosbags_decode("test_msgs/msg/Defaults", MessageEncoder("test_msgs/msg/Defaults", text).encode({}), text)
    assert list(decoded.pair) == [1.5, -2.0] and decoded.words == ["a, b", "c", "d"] and list(decoded.few) == [1, 2]


# -- the byte layout, by hand -----------------------------------------------------------------------

def test_padding_is_zero_and_counted_from_after_the_header():
    text = "uint8 a\nfloat64 b\nstring s\nint16 c\nint64[] d\nuint8 e\nfloat32 f\n"
    data = MessageEncoder("test_msgs/msg/Pad", text).encode(
        {"a": 1, "b": 2.0, "s": "xy", "c": -1, "d": [5], "e": 9, "f": 0.5})
    expected = (b"\x00\x01\x00\x00" + b"\x01" + bytes(7) + struct.pack("<d", 2.0)  # b at 8
                + struct.pack("<I", 3) + b"xy\x00" + bytes(1) + struct.pack("<h", -1)  # c at 24
                + bytes(2) + struct.pack("<I", 1) + struct.pack("<q", 5)  # count at 28, d[0] at 32
                + b"\x09" + bytes(3) + struct.pack("<f", 0.5))  # f at 44
    assert data == expected


def test_empty_sequences_and_messages():
    text = "uint8 a\nfloat64[] none\nEmpty e\nuint8 b\n================\nMSG: test_msgs/Empty\n"
    data = MessageEncoder("test_msgs/msg/Holes", text).encode({"a": 1, "none": [], "b": 2})
    # an empty float64 sequence is its count alone (no padding for elements that are not there);
    # a message without fields is one zero byte
    assert data == b"\x00\x01\x00\x00" + b"\x01" + bytes(3) + bytes(4) + b"\x00" + b"\x02"
    assert cdr.encode("std_msgs/msg/Empty", {}) == b"\x00\x01\x00\x00\x00"


def test_wstring_is_utf16_code_units_each_a_uint32():
    """rmw_fastrtps (Jazzy) writes a wstring as its count of UTF-16 code units, each as uint32,
    no terminator (rosidl_typesupport_fastrtps_cpp/serialization_helpers.hpp)."""
    data = MessageEncoder("test_msgs/msg/W", "uint8 a\nwstring w\nwstring[] ws\n").encode(
        {"a": 1, "w": "h\u00e9\U0001f600", "ws": [""]})
    units = [0x68, 0xE9, 0xD83D, 0xDE00]
    assert data == (b"\x00\x01\x00\x00\x01" + bytes(3) + struct.pack("<5I", 4, *units)
                    + struct.pack("<II", 1, 0))


# -- definitions ---------------------------------------------------------------------------------------

def test_definition_fields_constants_and_bounds():
    specs = parse_definition(ALL_TYPES, ALL_TYPES_TEXT)
    assert sorted(specs) == ["test_msgs/AllTypes", "test_msgs/Empty", "test_msgs/Inner"]
    fields = {f.name: f for f in specs["test_msgs/AllTypes"].fields}
    assert "ANSWER" not in fields and "GREETING" not in fields
    assert list(fields)[:3] == ["flag", "octet", "letter"] and list(fields)[-1] == "tail"
    assert (fields["short_text"].string_bound, fields["i16_bounded"].array, fields["i16_bounded"].size) == (5, "sequence", 4)
    assert (fields["f32_fixed"].array, fields["f32_fixed"].size, fields["f64_seq"].size) == ("fixed", 3, None)
    assert fields["inners"].type == "test_msgs/Inner" and specs["test_msgs/Empty"].fields == ()
    header = {f.name: f for f in parse_definition("a/B", "Header h\nb/msg/C c\n")["a/B"].fields}
    assert (header["h"].type, header["c"].type) == ("std_msgs/Header", "b/C")


@pytest.mark.parametrize("text, match", [
    ("float64\n", "a field needs a type and a name"),
    ("float64 2x\n", "is not a field name"),
    ("float64[<=] x\n", "needs a bound"),
    ("float64[0] x\n", "size must be > 0"),
    ("int8 x 300\n", r"int8 must be in \[-128, 127\]"),
    ("bool x maybe\n", "a bool is true, false, 1 or 0"),
    ("float64[2] x [1]\n", "1 elements for an array of 2"),
    ("float64<=3 x\n", "only string and wstring take an upper bound"),
    ("geometry_msgs/Point p 1\n", "takes no default"),
])
def test_malformed_definitions_name_type_and_line(text, match):
    with pytest.raises(DefinitionError, match=match) as err:
        MessageEncoder("test_msgs/msg/Bad", text)
    assert "test_msgs/Bad" in str(err.value)


# -- bad input -------------------------------------------------------------------------------------------

POSES = "geometry_msgs/msg/PoseArray"


def poses_with(**position) -> dict:
    return {"poses": [{"position": {"x": 1.0}}, {"position": {"x": 0.0, **position}}]}


@pytest.mark.parametrize("type_name, msg, match", [
    (POSES, poses_with(x="a"), r"poses\[1\]\.position\.x: expected a real number \(float64\), got str 'a'"),
    (POSES, poses_with(y=True), r"poses\[1\]\.position\.y: expected a real number"),
    (POSES, poses_with(z=[1.0]), r"poses\[1\]\.position\.z: expected a real number"),
    (POSES, poses_with(z=10 ** 400), r"poses\[1\]\.position\.z: .* beyond the float64 range"),
    (POSES, poses_with(w=1.0), r"poses\[1\]\.position: unknown field\(s\) w for geometry_msgs/Point"),
    (POSES, {"header": {"stamp": {"sec": 2 ** 31}}}, r"header\.stamp\.sec: int32 must be in \[-2147483648, 2147483647\]"),
    (POSES, {"header": {"stamp": {"nanosec": -1}}}, r"header\.stamp\.nanosec: uint32 must be in \[0, 4294967295\]"),
    (POSES, {"header": {"stamp": {"sec": 1.5}}}, r"header\.stamp\.sec: expected an integer \(int32\), got float"),
    (POSES, {"header": {"frame_id": 3}}, r"header\.frame_id: expected a str \(string\), got int 3"),
    (POSES, {"header": "map"}, r"header: expected a std_msgs/Header message \(a mapping\), got str"),
    (POSES, {"poses": {"x": 1.0}}, r"poses: expected a sequence \(geometry_msgs/Pose\[\]\), got dict"),
    (POSES, {"poses": [1.0]}, r"poses\[0\]: expected a geometry_msgs/Pose message"),
    ("sensor_msgs/msg/JointState", {"position": [0.0, "x"]}, r"position\[1\]: expected a real number"),
    ("sensor_msgs/msg/JointState", {"position": np.array(["x"])}, r"position\[0\]: expected a real number"),
    ("sensor_msgs/msg/JointState", {"name": "abc"}, r"name: expected a sequence \(string\[\]\)"),
    ("std_msgs/msg/Float64", {"data": Slot("data")}, r"data: Slot\('data', None\) outside a template"),
    ("std_msgs/msg/Float32", {"data": 1e39}, r"data: 1e\+39 is beyond the float32 range"),
    ("std_msgs/msg/UInt8", {"data": 256}, r"data: uint8 must be in \[0, 255\], got 256"),
    ("std_msgs/msg/Bool", {"data": 1}, r"data: expected a bool, got int 1"),
    ("diagnostic_msgs/msg/DiagnosticStatus", {"level": b"\x01\x02"}, r"level: expected a byte"),
    ("geometry_msgs/msg/PoseWithCovariance", {"covariance": [0.0] * 35}, r"covariance: 35 elements for float64\[36\]"),
    ("std_msgs/msg/String", {"data": "\ud800"}, r"data: not encodable"),
])
def test_bad_input_raises_one_error_naming_the_field(type_name, msg, match):
    with pytest.raises(EncodeError, match=match) as err:
        cdr.encode(type_name, msg)
    assert str(err.value).startswith(type_name + ": ")


def test_bounds_are_enforced():
    encoder = MessageEncoder(ALL_TYPES, ALL_TYPES_TEXT)
    for field, value, match in [("i16_bounded", [1] * 5, r"5 elements for int16\[<=4\]"),
                                ("short_text", "toolong", r"7 characters, more than the bound string<=5"),
                                ("bounded_texts", ["abcd"], r"bounded_texts\[0\]: 4 characters"),
                                ("octet", 256, r"byte must be in \[0, 255\], got 256"),
                                ("u64", 2 ** 64, r"uint64 must be in")]:
        with pytest.raises(EncodeError, match=match):
            encoder.encode({field: value})


def test_non_finite_floats_are_fine():
    for x in (math.inf, -math.inf, math.nan):
        for type_name, fmt in (("std_msgs/msg/Float64", "<d"), ("std_msgs/msg/Float32", "<f")):
            assert cdr.encode(type_name, {"data": x})[4:] == struct.pack(fmt, x)
    data = cdr.encode("sensor_msgs/msg/JointState", {"position": [math.nan, math.inf]})
    assert data == mcap_ros2_bytes("sensor_msgs/msg/JointState", [{"position": [math.nan, math.inf]}])[0]


def test_unknown_types_are_named():
    with pytest.raises(MessageDefinitionNotFound, match="nope_msgs/msg/Nothing"):
        cdr.encode("nope_msgs/msg/Nothing", {})
    with pytest.raises(EncodeError, match="the definition has no type test_msgs/Missing .needed by test_msgs/Uses"):
        MessageEncoder("test_msgs/msg/Uses", "Missing m\n")


def test_the_bag_writer_names_the_field(tmp_path):
    with BagWriter(tmp_path / "bad.mcap") as bag:
        bag.add_topic("/poses", POSES)
        with pytest.raises(BagError, match=r"/poses: geometry_msgs/msg/PoseArray: poses\[1\]\.position\.x: expected"):
            bag.write("/poses", poses_with(x="a"), log_time_ns=0)
        bag.write("/poses", poses_with(x=2.0), log_time_ns=1)  # still usable


def test_char_is_an_unsigned_byte():
    """A .msg char is IDL uint8 (rosidl); rclpy reads 200 back, and -1 is out of range."""
    from std_msgs.msg import Char

    data = cdr.encode("std_msgs/msg/Char", {"data": 200})
    assert data == b"\x00\x01\x00\x00\xc8" and deserialize_message(data, Char).data == 200
    with pytest.raises(EncodeError, match=r"data: char must be in \[0, 255\], got -1"):
        cdr.encode("std_msgs/msg/Char", {"data": -1})


def test_the_serializer_imports_only_the_standard_library_numpy_and_its_own_layer():
    """No rclpy, no mcap_ros2 (least of all its private _dynamic), nothing of ROS."""
    import ast
    import sys
    from pathlib import Path

    bag = Path(cdr.__file__).parent
    for name in ("cdr.py", "definition.py", "template.py"):
        tree = ast.parse((bag / name).read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                tops = [alias.name.split(".")[0] for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:  # relative: only the serializer's own modules and the schemas
                    assert node.level == 1 and node.module in ("schemas", "definition", "cdr"), (name, node.module)
                    continue
                tops = [node.module.split(".")[0]]
            else:
                continue
            for top in tops:
                assert top in sys.stdlib_module_names or top in ("numpy", "__future__"), (name, top)
