"""CDR templates (mta_sim_ros.bag.template): a message encoded once with slots, then filled.

A filled template must be byte for byte the message encoded from scratch with those values, for
any values (none of them is looked for in the bytes), any number of fills in a row, and the same
bytes however often it is built.
"""
from __future__ import annotations

import struct

import numpy as np
import pytest

from mta_sim_ros.bag import cdr
from mta_sim_ros.bag.cdr import EncodeError, Slot
from mta_sim_ros.bag.template import TIME_SLOTS, CdrTemplate

from cdr_refs import mcap_ros2_bytes

POSES = "geometry_msgs/msg/PoseArray"


def pose_array(frame: str, time, xyzw) -> dict:
    """A PoseArray with these stamp and (x, y, z, w) per pose (numbers or slots)."""
    return {"header": {"stamp": time, "frame_id": frame},
            "poses": [{"position": {"x": x, "y": y, "z": 0.0}, "orientation": {"z": z, "w": w}}
                      for x, y, z, w in xyzw]}


def pose_template(n: int, frame: str = "map") -> CdrTemplate:
    return CdrTemplate(POSES, pose_array(frame, TIME_SLOTS, [[Slot("v", 4 * k + i) for i in range(4)]
                                                              for k in range(n)]))


@pytest.mark.parametrize("n, frame", [(0, ""), (1, "a"), (3, "odom"), (17, "base_link")])
def test_a_filled_template_is_the_message_encoded_from_scratch(n, frame):
    template = pose_template(n, frame)
    rng = np.random.default_rng(n)
    for sec, nanosec in ((0, 0), (-7, 999_999_999), (2 ** 31 - 1, 1), (12, 345_678_901)):
        values = rng.normal(size=4 * n) * 1e3
        values[::5] = 0.0  # zeros and repeats: nothing in the bytes is mistaken for a slot
        if n:
            values[-1] = values[0]
        filled = template.fill(v=values, sec=sec, nanosec=nanosec) if n else template.fill(sec=sec, nanosec=nanosec)
        expected = pose_array(frame, {"sec": sec, "nanosec": nanosec}, values.reshape(n, 4).tolist())
        assert filled == cdr.encode(POSES, expected)


def test_templates_are_deterministic_and_their_padding_zero():
    """Built twice, the same bytes; and those of the message with zeros in the slots as
    mcap_ros2 writes it (whose padding is zero)."""
    a, b = pose_template(5, "odd"), pose_template(5, "odd")
    assert a.buf == b.buf
    zeros = pose_array("odd", {"sec": 0, "nanosec": 0}, [[0.0] * 4] * 5)
    assert bytes(a.buf) == mcap_ros2_bytes(POSES, [zeros])[0]


def test_slot_offsets_are_where_the_serializer_wrote_them():
    """Float64MultiArray after a string of each length mod 4: the data starts at another
    padding each time; slot i must land in data[i] whatever the layout."""
    for label in ("", "a", "ab", "abc", "abcd"):
        msg = {"layout": {"dim": [{"label": label, "size": 3, "stride": 3}], "data_offset": 1},
               "data": [Slot("d", 1), 7.0, Slot("d", 0)]}
        t = CdrTemplate("std_msgs/msg/Float64MultiArray", msg)
        assert t.size("d") == 2
        data = t.fill(d=[1.5, -2.5])
        assert data == cdr.encode("std_msgs/msg/Float64MultiArray", {**msg, "data": [-2.5, 7.0, 1.5]})
        t.put("d", [3.0, 4.0])
        assert struct.unpack("<3d", bytes(t.buf[-24:])) == (4.0, 7.0, 3.0)


def test_a_broadcast_group_sets_every_slot_and_an_unset_group_keeps_its_values():
    t = CdrTemplate("visualization_msgs/msg/MarkerArray",
                    {"markers": [{"header": {"stamp": TIME_SLOTS}, "id": Slot("id", k)} for k in range(3)]})
    assert (t.size("sec"), t.size("id")) == (1, 3)
    t.fill(id=[4, 5, 6])
    data = t.fill(sec=9, nanosec=8)
    expected = {"markers": [{"header": {"stamp": {"sec": 9, "nanosec": 8}}, "id": k} for k in (4, 5, 6)]}
    assert data == cdr.encode("visualization_msgs/msg/MarkerArray", expected)


@pytest.mark.parametrize("msg, match", [
    ({"poses": [{"position": {"x": Slot("g", 0)}}], "header": {"stamp": {"sec": Slot("g", 1)}}},
     r"slot group 'g': slots in fields of different types \['float64', 'int32'\]"),
    ({"poses": [{"position": {"x": Slot("g", 0), "y": Slot("g")}}]}, "some slots have an index, some not"),
    ({"poses": [{"position": {"x": Slot("g", 0), "y": Slot("g", 2)}}]}, r"indices must be 0\.\.1, each once"),
    ({"poses": [{"position": {"x": Slot("g", 1), "y": Slot("g", 1)}}]}, r"indices must be 0\.\.1, each once"),
    ({"header": {"frame_id": Slot("g")}}, r"header\.frame_id: expected a str"),
])
def test_mixed_groups_are_refused(msg, match):
    with pytest.raises(EncodeError, match=match) as err:
        CdrTemplate(POSES, msg)
    assert str(err.value).startswith(POSES)


def test_slots_only_in_numeric_fields():
    with pytest.raises(EncodeError, match=r"data: Slot\('b', None\): slots are for numeric fields, not bool"):
        CdrTemplate("std_msgs/msg/Bool", {"data": Slot("b")})
