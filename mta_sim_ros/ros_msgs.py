"""rclpy message objects from the simulator's outputs, for the ROS node.

The node publishes these messages and records them with
``BagWriter.write_raw(topic, rclpy.serialization.serialize_message(msg), ...)``. The offline run
writes the plain dicts of :func:`mta_sim_ros.topics.output_messages` instead; both bags must hold
the same values, so every builder here reuses the dict builders' formulas (``stamp``,
``yaw_quaternion``) and ``test/test_ros_msgs.py`` compares the two CDR encodings field by field.

Besides the topics of :data:`mta_sim_ros.topics.TOPICS` this module builds the node's extras:
:func:`train_markers` (a ``visualization_msgs/MarkerArray`` drawing of the train for Foxglove or
RViz) and :func:`diagnostic_array` (one ``diagnostic_msgs/DiagnosticStatus``).

rclpy message packages only; nothing here creates a node or touches the middleware.
"""
from __future__ import annotations

import importlib
import math
import numbers
import struct
from typing import Mapping, Sequence

import numpy as np
from rclpy.serialization import serialize_message

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Pose, PoseArray, Quaternion, Vector3
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA, Float64, Header
from visualization_msgs.msg import Marker, MarkerArray

from .bag.schemas import split_type_name
from .bag.writer import stamp, stamp_parts, yaw_quaternion

#: hardware_id of every DiagnosticStatus the simulator reports.
HARDWARE_ID = "mta_sim_ros"

#: Width of a cart's outline when nothing says otherwise (the tractor, a cart without draft), m.
DEFAULT_WIDTH = 2.5

# Marker namespaces, one per kind of marker; within each the id is the cart index (the single
# sphere list of hitch points has id 0). Stable ids make every message replace the previous one.
NS_OUTLINE = "outline"
NS_AXLE = "axle"
NS_HITCHES = "hitches"
NS_LABEL = "label"

LINE_WIDTH = 0.1  # m, outlines and axles
HITCH_DIAMETER = 0.5  # m, hitch point spheres
TEXT_HEIGHT = 1.0  # m, cart name labels

# Cart colours (RGB), in train order, repeated for long trains. Multiples of 1/16, exact in the
# message's float32 fields, so a received marker equals the one sent.
_PALETTE = (
    (0.125, 0.5, 0.75),  # blue
    (1.0, 0.5, 0.0625),  # orange
    (0.1875, 0.625, 0.1875),  # green
    (0.875, 0.125, 0.125),  # red
    (0.5625, 0.375, 0.75),  # purple
    (0.5625, 0.3125, 0.25),  # brown
)

_DIAGNOSTIC_LEVELS = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}


def message_class(type_name: str) -> type:
    """The rclpy message class of a type name of the topic table, e.g.
    ``message_class(topics.TOPICS["hitch_poses"])`` is ``geometry_msgs.msg.PoseArray``.

    Raises:
        ValueError: malformed type name.
        ImportError, AttributeError: the message package or type is not installed.
    """
    pkg, name = split_type_name(type_name)
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


def time_msg(t_seconds: float) -> Time:
    """builtin_interfaces/Time of ``t_seconds``, rounded to the nanosecond like
    ``bag.writer.stamp``."""
    return Time(**stamp(t_seconds))


def header(t_seconds: float, frame_id: str) -> Header:
    """std_msgs/Header with stamp ``t_seconds`` and ``frame_id``."""
    return Header(stamp=time_msg(t_seconds), frame_id=frame_id)


def float64(x: float) -> Float64:
    """std_msgs/Float64."""
    return Float64(data=float(x))


def output_messages(out, cart_names: Sequence[str], frame_id: str = "map") -> dict[str, object]:
    """The published messages (topic -> rclpy message) for one ``sim.Outputs`` sample: the
    same topics and values as :func:`mta_sim_ros.topics.output_messages`."""
    if len(cart_names) != len(out.heading):
        raise ValueError(f"output_messages: {len(cart_names)} cart names for "
                         f"{len(out.heading)} carts")
    t = out.t
    poses = [Pose(position=Point(x=float(p[0]), y=float(p[1]), z=0.0),
                  orientation=Quaternion(**yaw_quaternion(float(th))))
             for p, th in zip(out.front, out.heading)]
    return {
        "hitch_poses": PoseArray(header=header(t, frame_id), poses=poses),
        "cart_velocities": JointState(header=header(t, ""),
                                      name=[str(n) for n in cart_names],
                                      position=[float(th) for th in out.heading],
                                      velocity=[float(v) for v in out.com_speed],
                                      effort=[float(f) for f in out.resistance]),
        "traction_power": float64(out.power),
        "applied_steering": float64(out.steering),
        "/clock": Clock(clock=time_msg(t)),
    }


# -- encoding by patching a template ---------------------------------------------------------

#: Bit pattern of the first sentinel double (about 2.7e300; never a real output). Sentinel i is
#: the double whose bits are SENTINEL_BITS + i: distinct for every i, finite, unmistakable.
SENTINEL_BITS = 0x7E5A_0000_0000_0000
#: The sentinel stamp (sec, nanosec) set in every header of a template.
SENTINEL_STAMP = (0x5EC0_7A11, 987_654_321)
_ENCAPSULATION = 4  # CDR starts with a 4-byte encapsulation header; alignment counts from after it


def sentinel(i: int) -> float:
    """The i-th sentinel double (see SENTINEL_BITS)."""
    return struct.unpack("<d", struct.pack("<Q", SENTINEL_BITS + i))[0]


class CdrTemplate:
    """A message of fixed shape serialized once by rclpy, then re-encoded by writing new values
    over the old ones in the CDR bytes: no message objects, no typesupport conversion per tick.

    Build it from a message whose variable float64 fields hold ``sentinel(0) ... sentinel(m - 1)``
    (in the order ``fill`` will give the values) and whose stamps (builtin_interfaces/Time) all
    hold ``SENTINEL_STAMP``; the constructor finds where each sits in the serialized bytes and
    refuses a template where one is missing or ambiguous. Strings, sequence lengths and every
    other field keep the template's values. ``test/test_ros_msgs.py`` decodes filled templates
    with rclpy and compares them with messages built field by field.
    """

    def __init__(self, msg, values: int, stamps: int):
        self.type_name = type(msg).__name__
        self.buf = bytearray(serialize_message(msg))
        if self.buf[:2] != b"\x00\x01":
            raise ValueError(f"{self.type_name}: not little-endian CDR ({bytes(self.buf[:4])!r})")
        words = (len(self.buf) - _ENCAPSULATION) // 4
        self.f64 = np.frombuffer(self.buf, dtype="<f8", count=words // 2, offset=_ENCAPSULATION)
        self.u32 = np.frombuffer(self.buf, dtype="<u4", count=words, offset=_ENCAPSULATION)
        slots = []
        for i in range(values):
            (where,) = self._find(struct.pack("<d", sentinel(i)), 8, 1, f"value {i}")
            slots.append(where // 8)
        self.values = np.array(slots, dtype=np.intp)
        found = self._find(struct.pack("<iI", *SENTINEL_STAMP), 4, stamps, "stamp") if stamps else []
        self.sec = np.array([w // 4 for w in found], dtype=np.intp)
        self.nanosec = self.sec + 1

    def _find(self, pattern: bytes, align: int, count: int, what: str) -> list[int]:
        """Offsets (from after the encapsulation header) of the ``count`` occurrences of pattern."""
        found, start = [], 0
        while (at := self.buf.find(pattern, start)) >= 0:
            if (at - _ENCAPSULATION) % align == 0:
                found.append(at - _ENCAPSULATION)
            start = at + 1
        if len(found) != count:
            raise ValueError(f"{self.type_name} template: {what} found {len(found)} times, expected {count}")
        return found

    def fill(self, values, sec_nanosec: tuple[int, int] | None = None) -> bytes:
        """The CDR bytes of the message with these values (in sentinel order) and every stamp set
        to ``sec_nanosec`` (see ``bag.writer.stamp_parts``)."""
        self.f64[self.values] = values
        if sec_nanosec is not None:
            self.u32[self.sec] = sec_nanosec[0] & 0xFFFF_FFFF  # int32 sec, two's complement
            self.u32[self.nanosec] = sec_nanosec[1]
        return bytes(self.buf)



class OutputEncoder:
    """CDR bytes of :func:`output_messages` straight from the Outputs, for the node's tick: the
    same messages (``test_ros_msgs.py`` decodes and compares them), about a tenth of the work."""

    def __init__(self, cart_names: Sequence[str], frame_id: str = "map"):
        self.n, self.frame_id = len(cart_names), frame_id
        n = self.n
        s = [sentinel(i) for i in range(4 * n)]
        Stamp = Time(sec=SENTINEL_STAMP[0], nanosec=SENTINEL_STAMP[1])
        poses = [Pose(position=Point(x=s[4 * k], y=s[4 * k + 1], z=0.0),
                      orientation=Quaternion(x=0.0, y=0.0, z=s[4 * k + 2], w=s[4 * k + 3])) for k in range(n)]
        self.poses = CdrTemplate(PoseArray(header=Header(stamp=Stamp, frame_id=frame_id), poses=poses), 4 * n, 1)
        self.joints = CdrTemplate(JointState(header=Header(stamp=Stamp, frame_id=""), name=[str(c) for c in cart_names],
                                             position=s[:n], velocity=s[n:2 * n], effort=s[2 * n:3 * n]), 3 * n, 1)
        self.scalar = CdrTemplate(Float64(data=s[0]), 1, 0)
        self.clock = CdrTemplate(Clock(clock=Stamp), 0, 1)
        self.pose_values = np.zeros((n, 4))

    def encode(self, out) -> dict[str, bytes]:
        """topic -> CDR bytes, the topics and values of :func:`output_messages`."""
        if len(out.heading) != self.n:
            raise ValueError(f"OutputEncoder: {self.n} cart names for {len(out.heading)} carts")
        t, v = stamp_parts(out.t), self.pose_values
        v[:, :2] = out.front
        for k, th in enumerate(out.heading.tolist()):  # yaw_quaternion's math, bit for bit
            v[k, 2], v[k, 3] = math.sin(th / 2.0), math.cos(th / 2.0)
        return {
            "hitch_poses": self.poses.fill(v.ravel(), t),
            "cart_velocities": self.joints.fill(np.concatenate((out.heading, out.com_speed, out.resistance)), t),
            "traction_power": self.scalar.fill(out.power),
            "applied_steering": self.scalar.fill(out.steering),
            "/clock": self.clock.fill((), t),
        }


# -- markers -------------------------------------------------------------------


def cart_widths(train) -> list[float]:
    """Width of each cart's outline, m: DEFAULT_WIDTH for the tractor; for a towed cart the
    widest ``Draft.width`` acting on it (the draft width is taken as metres), else
    DEFAULT_WIDTH."""
    widths = [DEFAULT_WIDTH]
    for cart in train.carts[1:]:
        drafts = [d.width for d in train.draft if d.cart == cart.name]
        widths.append(max(drafts, default=DEFAULT_WIDTH))
    return widths


def _point(x: float, y: float) -> Point:
    return Point(x=float(x), y=float(y), z=0.0)


def _color(k: int) -> ColorRGBA:
    r, g, b = _PALETTE[k % len(_PALETTE)]
    return ColorRGBA(r=r, g=g, b=b, a=1.0)


def _marker(t: float, frame_id: str, ns: str, marker_id: int, marker_type: int,
            scale: Vector3, color: ColorRGBA) -> Marker:
    """A Marker to ADD (replacing the one with the same ns and id) with identity pose."""
    return Marker(header=header(t, frame_id), ns=ns, id=marker_id, type=marker_type,
                  action=Marker.ADD, pose=Pose(), scale=scale, color=color)


def train_markers(out, train, frame_id: str = "map") -> MarkerArray:
    """A drawing of the train at ``out.t`` (z = 0), for Foxglove or RViz.

    Per cart k (ns / id = k): ``outline``, a closed LINE_STRIP rectangle along the cart's axis
    from A_k back to the rearmost of B_k and its rear hitch point (A_{k+1}, or ``out.rear_hitch``
    for the last cart), as wide as :func:`cart_widths` says; ``axle``, a LINE_LIST segment
    through B_k across the axis, as long as the cart is wide; ``label``, a TEXT_VIEW_FACING with
    the cart's name at the outline's centre. Plus one SPHERE_LIST (ns ``hitches``, id 0) of the
    points A_k, each in its cart's colour.
    """
    return TrainMarkers(train, frame_id).update(out)


class TrainMarkers:
    """The MarkerArray of :func:`train_markers`, built once and redrawn in place for each new
    Outputs: the node's marker tick then only sets coordinates and stamps instead of building
    3 n + 1 Marker messages (for 100 carts that build alone took ~7 ms of a 10 ms tick).
    ``update`` returns the same MarkerArray object each time: serialize it before the next call."""

    def __init__(self, train, frame_id: str = "map"):
        self.train, self.frame_id = train, frame_id
        self.widths = cart_widths(train)
        self.outlines, self.axles, self.labels = [], [], []
        markers = []
        for k, cart in enumerate(train.carts):
            color = _color(k)
            outline = _marker(0.0, frame_id, NS_OUTLINE, k, Marker.LINE_STRIP, Vector3(x=LINE_WIDTH), color)
            outline.points = [Point() for _ in range(5)]
            axle = _marker(0.0, frame_id, NS_AXLE, k, Marker.LINE_LIST, Vector3(x=LINE_WIDTH), color)
            axle.points = [Point(), Point()]
            label = _marker(0.0, frame_id, NS_LABEL, k, Marker.TEXT_VIEW_FACING, Vector3(z=TEXT_HEIGHT), color)
            label.text = cart.name
            self.outlines.append(outline)
            self.axles.append(axle)
            self.labels.append(label)
            markers += [outline, axle, label]
        n = len(train.carts)
        self.hitches = _marker(0.0, frame_id, NS_HITCHES, 0, Marker.SPHERE_LIST,
                               Vector3(x=HITCH_DIAMETER, y=HITCH_DIAMETER, z=HITCH_DIAMETER), _color(0))
        self.hitches.points = [Point() for _ in range(n)]
        self.hitches.colors = [_color(k) for k in range(n)]
        markers.append(self.hitches)
        self.array = MarkerArray(markers=markers)
        self.stamps = [m.header.stamp for m in markers]
        # Every drawn point, in the order of _coordinates: per cart the outline's 5 corners, the
        # axle's 2 ends and the label's position, then the hitch points.
        self.points = [p for k in range(n) for p in (*self.outlines[k].points, *self.axles[k].points,
                                                      self.labels[k].pose.position)]
        self.points += self.hitches.points
        self._set(SENTINEL_STAMP, [sentinel(i) for i in range(2 * len(self.points))])
        self.template = CdrTemplate(self.array, 2 * len(self.points), len(self.stamps))

    def update(self, out) -> MarkerArray:
        self._set(stamp_parts(out.t), self._coordinates(out))
        return self.array

    def encode(self, out) -> bytes:
        """The CDR bytes of ``update(out)``, without touching the message objects."""
        return self.template.fill(self._coordinates(out), stamp_parts(out.t))

    def _set(self, sec_nanosec, xy: list[float]) -> None:
        for s in self.stamps:
            s.sec, s.nanosec = sec_nanosec
        for i, p in enumerate(self.points):
            p.x, p.y = xy[2 * i], xy[2 * i + 1]

    def _coordinates(self, out) -> list[float]:
        """x, y of every point in ``self.points`` order."""
        n = len(self.train.carts)
        if len(out.front) != n:
            raise ValueError(f"train_markers: {len(out.front)} carts in the outputs, {n} in train "
                             f"{self.train.name!r}")
        xy: list[float] = []
        front, axle_pts, heading = out.front.tolist(), out.axle.tolist(), out.heading.tolist()
        rear_points = front[1:] + [[float(v) for v in out.rear_hitch]]
        for k in range(n):
            ax, ay = front[k]
            bx, by = axle_pts[k]
            rx, ry = rear_points[k]
            ex, ey = math.cos(heading[k]), math.sin(heading[k])  # along the axis
            nx, ny = -ey, ex  # to the cart's left
            half = self.widths[k] / 2.0
            # How far back of A_k the outline reaches (the rear hitch may be ahead of the axle).
            back = max((ax - bx) * ex + (ay - by) * ey, (ax - rx) * ex + (ay - ry) * ey)
            tx, ty = ax - back * ex, ay - back * ey  # centre of the outline's rear edge
            xy += (ax + half * nx, ay + half * ny, ax - half * nx, ay - half * ny,  # outline
                   tx - half * nx, ty - half * ny, tx + half * nx, ty + half * ny,
                   ax + half * nx, ay + half * ny,
                   bx + half * nx, by + half * ny, bx - half * nx, by - half * ny,  # axle
                   (ax + tx) / 2.0, (ay + ty) / 2.0)  # label
        for x, y in front:
            xy += (x, y)
        return xy


# -- diagnostics ---------------------------------------------------------------


def _level_byte(level: int | bytes) -> bytes:
    """DiagnosticStatus.level as rclpy (Jazzy) holds it: a ``bytes`` of length 1.

    Accepts an int 0..3 or one of the ``DiagnosticStatus.OK/WARN/ERROR/STALE`` constants
    (themselves bytes of length 1).
    """
    if isinstance(level, (bytes, bytearray)):
        if len(level) != 1:
            raise ValueError(f"diagnostic level must be 1 byte, got {level!r}")
        value = level[0]
    else:
        value = int(level)
    if value not in _DIAGNOSTIC_LEVELS:
        raise ValueError(f"diagnostic level must be one of {_DIAGNOSTIC_LEVELS}, got {level!r}")
    return bytes([value])


def format_value(value: object) -> str:
    """A diagnostic value as text: non-integral numbers with %.6g, everything else with str()."""
    if isinstance(value, numbers.Real) and not isinstance(value, numbers.Integral):
        return f"{float(value):.6g}"
    return str(value)


def diagnostic_array(t: float, name: str, level: int | bytes, message: str,
                     values: Mapping[str, object]) -> DiagnosticArray:
    """diagnostic_msgs/DiagnosticArray stamped ``t`` with one DiagnosticStatus (hardware_id
    :data:`HARDWARE_ID`), its values as KeyValue strings (see :func:`format_value`).

    Args:
        level: 0 OK, 1 WARN, 2 ERROR, 3 STALE, as an int or a ``DiagnosticStatus`` constant.

    Raises:
        ValueError: unknown level.
    """
    status = DiagnosticStatus(level=_level_byte(level), name=name, message=message,
                              hardware_id=HARDWARE_ID,
                              values=[KeyValue(key=str(k), value=format_value(v))
                                      for k, v in values.items()])
    return DiagnosticArray(header=header(t, ""), status=[status])
