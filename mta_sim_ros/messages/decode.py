"""The command messages a controller sends, read from their CDR bytes without ROS: cmd_vel
(geometry_msgs/Twist, or TwistStamped with the node's cmd_vel_stamped), ackermann_cmd (ackermann_msgs/AckermannDriveStamped) and implement_lowered
(std_msgs/Bool).

The node hands the session the bytes it received (the bag records them as they are) and the
session reads the few numbers the command rule needs (commands.twist_setting,
commands.ackermann_setting). Both layouts are fixed by their ``.msg`` files (CDR, XCDR1 as
rmw_fastrtps writes them: a 4-byte encapsulation header, then each primitive aligned to its size
counted from the end of the header); ``test/test_commands.py`` holds them to rclpy's serializer.
"""
from __future__ import annotations

import struct

TWIST_TYPE = "geometry_msgs/msg/Twist"
TWIST_STAMPED_TYPE = "geometry_msgs/msg/TwistStamped"
ACKERMANN_TYPE = "ackermann_msgs/msg/AckermannDriveStamped"
BOOL_TYPE = "std_msgs/msg/Bool"

#: the encapsulation identifiers of plain CDR: big and little endian
_ENDIAN = {b"\x00\x00": ">", b"\x00\x01": "<"}


class CommandDecodeError(ValueError):
    """Bytes that are not a CDR message of the expected type."""


def _endian(data: bytes, type_name: str) -> str:
    order = _ENDIAN.get(bytes(data[:2]))
    if order is None:
        raise CommandDecodeError(f"{type_name}: encapsulation {bytes(data[:2]).hex()} is not plain CDR")
    return order


def decode_twist(data: bytes) -> tuple[float, float]:
    """(linear.x, angular.z) of a geometry_msgs/Twist: linear (x, y, z) then angular (x, y, z),
    six float64 from offset 4."""
    order = _endian(data, TWIST_TYPE)
    if len(data) < 4 + 48:
        raise CommandDecodeError(f"{TWIST_TYPE}: {len(data)} bytes, expected at least 52")
    linear_x, _, _, _, _, angular_z = struct.unpack_from(order + "6d", data, 4)
    return linear_x, angular_z


def decode_twist_stamped(data: bytes) -> tuple[float, float]:
    """(twist.linear.x, twist.angular.z) of a geometry_msgs/TwistStamped: header (stamp: int32
    sec, uint32 nanosec; frame_id: uint32 length with the NUL, the characters), then the twist's
    six float64 aligned to 8."""
    order = _endian(data, TWIST_STAMPED_TYPE)
    offset = _after_header(data, order, TWIST_STAMPED_TYPE)
    offset += -offset % 8
    body = memoryview(data)[4:]
    if len(body) < offset + 48:
        raise CommandDecodeError(f"{TWIST_STAMPED_TYPE}: {len(data)} bytes, too short for its header and twist")
    linear_x, _, _, _, _, angular_z = struct.unpack_from(order + "6d", body, offset)
    return linear_x, angular_z


def _after_header(data: bytes, order: str, type_name: str) -> int:
    """The offset (from the end of the encapsulation) just after a std_msgs/Header."""
    body = memoryview(data)[4:]
    if len(body) < 12:
        raise CommandDecodeError(f"{type_name}: {len(data)} bytes, too short for a header")
    (length,) = struct.unpack_from(order + "I", body, 8)
    return 12 + length


def decode_ackermann(data: bytes) -> tuple[float, float, float]:
    """(steering_angle, steering_angle_velocity, speed) of an ackermann_msgs/AckermannDriveStamped:
    header (stamp: int32 sec, uint32 nanosec; frame_id: uint32 length with the NUL, the
    characters), then drive (float32 steering_angle, steering_angle_velocity, speed,
    acceleration, jerk) aligned to 4."""
    order = _endian(data, ACKERMANN_TYPE)
    body = memoryview(data)[4:]
    offset = _after_header(data, order, ACKERMANN_TYPE)
    length = offset - 12
    offset += -offset % 4
    if len(body) < offset + 20:
        raise CommandDecodeError(f"{ACKERMANN_TYPE}: {len(data)} bytes, too short for its frame_id of "
                                 f"{length} bytes and the drive")
    steering, rate, speed, _, _ = struct.unpack_from(order + "5f", body, offset)
    return steering, rate, speed


def decode_bool(data: bytes) -> bool:
    """data of a std_msgs/Bool: one byte from offset 4, 0 false, else true (as rclpy and the bag
    readers take it)."""
    _endian(data, BOOL_TYPE)
    if len(data) < 5:
        raise CommandDecodeError(f"{BOOL_TYPE}: {len(data)} bytes, expected at least 5")
    return data[4] != 0
