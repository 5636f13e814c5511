"""Independent references for the CDR bytes of mta_sim_ros.bag.cdr, for the tests.

* :func:`mcap_ros2_bytes`: what mcap_ros2's public writer stores for plain-dict messages (written
  with ``mcap_ros2.writer.Writer``, read back raw with ``mcap.reader``): the serializer the
  project's bags were written with before, so equal bytes mean old and new bags are identical;
* :func:`rosbags_decode`: rosbags' own CDR deserializer, from its Jazzy type store or from a
  definition text;
* :func:`rclpy_message`: an rclpy message built field by field from a plain dict, to compare with
  ``rclpy.serialization.deserialize_message`` of the bytes;
* :func:`assert_fields`: a decoded message (attributes) against the dict it came from.
"""
from __future__ import annotations

import copy
import importlib
import io

import numpy as np
from mcap.reader import make_reader
from mcap.writer import CompressionType
from mcap_ros2.writer import Writer as McapRos2Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from mta_sim_ros.bag import message_definition, schema_name


def mcap_ros2_bytes(type_name: str, messages: list, definition: str | None = None) -> list[bytes]:
    """The CDR bytes mcap_ros2's writer stores for each message (deep copies: it pads fixed
    arrays of the caller's lists in place)."""
    f = io.BytesIO()
    writer = McapRos2Writer(f, compression=CompressionType.NONE)
    schema = writer.register_msgdef(schema_name(type_name), definition or message_definition(type_name))
    for i, msg in enumerate(messages):
        writer.write_message("/t", schema, copy.deepcopy(msg), log_time=i)
    writer.finish()
    f.seek(0)
    return [m.data for _, _, m in make_reader(f).iter_messages(log_time_order=False)]


_JAZZY = get_typestore(Stores.ROS2_JAZZY)


def rosbags_decode(type_name: str, data: bytes, definition: str | None = None):
    """``data`` deserialized by rosbags: with its Jazzy store, or with the types of
    ``definition`` (a concatenated ros2msg text) registered in an empty store."""
    store = _JAZZY
    if definition is not None:
        store = get_typestore(Stores.EMPTY)
        store.register(get_types_from_msg(definition, schema_name(type_name)))
    return store.deserialize_cdr(data, schema_name(type_name))


def rclpy_message(type_name: str, data: dict):
    """The rclpy message of ``type_name`` holding the plain-dict ``data``, set field by field."""
    pkg, _, name = schema_name(type_name).split("/")
    msg = getattr(importlib.import_module(f"{pkg}.msg"), name)()
    field_types = msg.get_fields_and_field_types()  # e.g. "sequence<geometry_msgs/Pose>", "octet"
    for key, value in data.items():
        field_type = field_types[key]
        nested = field_type.removeprefix("sequence<").split(",")[0].rstrip(">").replace("/", "/msg/")
        if isinstance(value, dict):
            value = rclpy_message(nested, value)
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            value = [rclpy_message(nested, item) for item in value]
        elif field_type == "octet" and isinstance(value, int):
            value = bytes([value])
        setattr(msg, key, value)
    return msg


def assert_fields(actual, expected, where: str = "msg") -> None:
    """Every field of the dict ``expected`` (recursively) equals the attribute of ``actual``;
    fields the dict leaves out are not compared."""
    if isinstance(expected, dict):
        for key, value in expected.items():
            assert_fields(getattr(actual, key), value, f"{where}.{key}")
    elif isinstance(expected, (bytes, bytearray)):
        assert bytes(actual) == expected, where  # uint8[] as bytes, array('B') or a numpy array
    elif isinstance(expected, (list, tuple)):
        actual = list(actual)
        assert len(actual) == len(expected), where
        for i, (a, e) in enumerate(zip(actual, expected)):
            assert_fields(a, e, f"{where}[{i}]")
    else:
        if isinstance(actual, (bytes, bytearray)) and isinstance(expected, int):
            actual = actual[0]  # rclpy holds a byte as bytes of length 1
        if isinstance(actual, np.generic):
            actual = actual.item()
        assert actual == expected or (expected != expected and actual != actual), \
            f"{where}: {actual!r} != {expected!r}"
