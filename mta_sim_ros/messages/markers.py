"""A drawing of the train as a visualization_msgs/MarkerArray (for Foxglove or RViz), ROS-free.

Per cart k (ns / id = k): ``outline``, a closed LINE_STRIP rectangle along the cart's axis from
A_k back to the rearmost of B_k and its rear hitch point (A_{k+1}, or ``out.rear_hitch`` for the
last cart), as wide as :func:`~mta_sim_ros.physics.outline.cart_widths` says; ``axle``, a LINE_LIST segment through B_k across
the axis, as long as the cart is wide; ``label``, a TEXT_VIEW_FACING with the cart's name at the
outline's centre. Plus one SPHERE_LIST (ns ``hitches``, id 0) of the points A_k, each in its
cart's colour. Everything lies in z = 0 with identity poses; stable ids make every message
replace the previous one. A train on a scene's tilted plane (``train.terrain``) also draws the
ground: a CUBE (ns ``terrain``, id 0) TERRAIN_SIZE m square and TERRAIN_THICKNESS thick, its top
at z = 0 and its centre under A_1, in the frame of the plane (the node's odom is the plane: the
train is drawn on it and the ground tilts with it in RViz and Foxglove). On a height grid
(``train.relief``) every point drawn lies on the surface (its height at the point, x, y being
horizontal there) and the ground is a TRIANGLE_LIST (ns ``terrain``, id 0) through the grid's
nodes, every few nodes where the grid is large (at most MAX_TERRAIN_TRIANGLES triangles),
TERRAIN_DROP below them so the lines on the surface show; it is the same in every message.

:func:`train_markers` gives the message as plain dicts; :class:`TrainMarkers` its CDR bytes from
a template (the node's marker tick), byte for byte ``bag.cdr.encode`` of the dicts.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ..bag.cdr import Slot
from ..bag.template import TIME_SLOTS, CdrTemplate
from ..bag.writer import stamp, stamp_parts
from ..physics.outline import cart_widths
from .frames import surface_at

MARKERS_TYPE = "visualization_msgs/msg/MarkerArray"

# visualization_msgs/Marker constants (Marker.msg).
CUBE, LINE_STRIP, LINE_LIST, SPHERE_LIST, TEXT_VIEW_FACING, TRIANGLE_LIST = 1, 4, 5, 7, 9, 11
ADD = 0

# Marker namespaces, one per kind of marker; within each the id is the cart index (the single
# sphere list of hitch points has id 0).
NS_OUTLINE = "outline"
NS_AXLE = "axle"
NS_HITCHES = "hitches"
NS_LABEL = "label"
NS_TERRAIN = "terrain"

LINE_WIDTH = 0.1  # m, outlines and axles
HITCH_DIAMETER = 0.5  # m, hitch point spheres
TEXT_HEIGHT = 1.0  # m, cart name labels
TERRAIN_SIZE = 200.0  # m, the side of the ground drawn under the train on a tilted plane
TERRAIN_THICKNESS = 0.0625  # m
MAX_TERRAIN_TRIANGLES = 5000  # a height grid's mesh: its nodes decimated to at most this many triangles
TERRAIN_DROP = 0.125  # m, the mesh below the grid's nodes (a mesh's flat triangles cut the curved surface)
TERRAIN_COLOR = {"r": 0.5625, "g": 0.4375, "b": 0.25, "a": 0.5}  # soil, half transparent (exact in float32)

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

# Points per cart in coordinates() order: the outline's 5 corners, the axle's 2 ends, the label.
_POINTS_PER_CART = 8


def relief_of(train):
    """The train's height grid, or None (a train without the attribute has none)."""
    return getattr(train, "relief", None)


@functools.lru_cache(maxsize=1)
def terrain_mesh(relief) -> tuple[dict, ...]:
    """The triangles (3 points each, counter-clockwise seen from above) through the height grid's
    nodes, every ``step``-th node along each axis (and the last), ``step`` the smallest that keeps
    them at most MAX_TERRAIN_TRIANGLES; TERRAIN_DROP below the nodes."""
    heights = relief.heights
    ny, nx = heights.shape
    step = 1
    while 2 * math.ceil((nx - 1) / step) * math.ceil((ny - 1) / step) > MAX_TERRAIN_TRIANGLES:
        step += 1
    cols = sorted(set(range(0, nx, step)) | {nx - 1})
    rows = sorted(set(range(0, ny, step)) | {ny - 1})
    node = {(i, j): {"x": float(relief.xs[j]), "y": float(relief.ys[i]), "z": float(heights[i, j]) - TERRAIN_DROP}
            for i in rows for j in cols}
    points = []
    for i0, i1 in zip(rows, rows[1:]):
        for j0, j1 in zip(cols, cols[1:]):
            points += (node[i0, j0], node[i0, j1], node[i1, j1], node[i0, j0], node[i1, j1], node[i1, j0])
    return tuple(points)


def coordinates(out, train, widths: list[float]) -> list[float]:
    """x, y of every point drawn: per cart the outline's 5 corners, the axle's 2 ends and the
    label's position, then the hitch points A_k, then on a tilted plane the ground's centre (A_1);
    on a height grid x, y, z of each, z the surface's height there.

    Raises:
        ValueError: the outputs are of another train (another number of carts).
    """
    n = len(train.carts)
    if len(out.front) != n:
        raise ValueError(f"train_markers: {len(out.front)} carts in the outputs, {n} in train "
                         f"{train.name!r}")
    xy: list[float] = []
    front, axle_pts, heading = out.front.tolist(), out.axle.tolist(), out.heading.tolist()
    rear_points = front[1:] + [[float(v) for v in out.rear_hitch]]
    for k in range(n):
        ax, ay = front[k]
        bx, by = axle_pts[k]
        rx, ry = rear_points[k]
        ex, ey = math.cos(heading[k]), math.sin(heading[k])  # along the axis
        nx, ny = -ey, ex  # to the cart's left
        half = widths[k] / 2.0
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
    if train.terrain is not None:
        xy += front[0]
    relief = relief_of(train)
    if relief is not None:
        pts = np.asarray(xy).reshape(-1, 2)
        heights = [surface_at(relief, x, y).z for x, y in pts.tolist()]
        xy = np.column_stack((pts, heights)).ravel().tolist()
    return xy


def cart_color(k: int) -> dict:
    """The colour of cart k (0 = the tractor), as std_msgs/ColorRGBA fields: the markers' and the URDF's."""
    r, g, b = _PALETTE[k % len(_PALETTE)]
    return {"r": r, "g": g, "b": b, "a": 1.0}


def marker_array(train, frame_id: str, time: dict, xy: list) -> dict:
    """The MarkerArray of the module docstring as plain dicts, every stamp ``time``
    (builtin_interfaces/Time) and the points' x, y (on a height grid x, y, z) taken in order from
    ``xy`` (numbers, or :class:`~mta_sim_ros.bag.cdr.Slot` for a template)."""
    relief = relief_of(train)
    if relief is None:
        pairs = iter(zip(xy[0::2], xy[1::2], [0.0] * (len(xy) // 2)))
    else:
        pairs = iter(zip(xy[0::3], xy[1::3], xy[2::3]))

    def points(count: int) -> list[dict]:
        return [{"x": x, "y": y, "z": z} for x, y, z in (next(pairs) for _ in range(count))]

    def marker(ns: str, marker_id: int, marker_type: int, scale: dict, color: dict, **fields) -> dict:
        """A Marker to ADD (replacing the one with the same ns and id), identity pose unless given."""
        return {"header": {"stamp": time, "frame_id": frame_id}, "ns": ns, "id": marker_id,
                "type": marker_type, "action": ADD, "scale": scale, "color": color, **fields}

    markers = []
    for k, cart in enumerate(train.carts):
        color = cart_color(k)
        markers += [
            marker(NS_OUTLINE, k, LINE_STRIP, {"x": LINE_WIDTH}, color, points=points(5)),
            marker(NS_AXLE, k, LINE_LIST, {"x": LINE_WIDTH}, color, points=points(2)),
            marker(NS_LABEL, k, TEXT_VIEW_FACING, {"z": TEXT_HEIGHT}, color,
                   pose={"position": points(1)[0]}, text=cart.name),
        ]
    n = len(train.carts)
    markers.append(marker(NS_HITCHES, 0, SPHERE_LIST, {"x": HITCH_DIAMETER, "y": HITCH_DIAMETER, "z": HITCH_DIAMETER},
                          cart_color(0), points=points(n), colors=[cart_color(k) for k in range(n)]))
    if train.terrain is not None:
        centre = {**points(1)[0], "z": -TERRAIN_THICKNESS / 2.0}
        markers.append(marker(NS_TERRAIN, 0, CUBE, {"x": TERRAIN_SIZE, "y": TERRAIN_SIZE, "z": TERRAIN_THICKNESS},
                              TERRAIN_COLOR, pose={"position": centre, "orientation": {"w": 1.0}}))
    if relief is not None:
        markers.append(marker(NS_TERRAIN, 0, TRIANGLE_LIST, {"x": 1.0, "y": 1.0, "z": 1.0}, TERRAIN_COLOR,
                              pose={"orientation": {"w": 1.0}}, points=list(terrain_mesh(relief))))
    return {"markers": markers}


def train_markers(out, train, frame_id: str = "map") -> dict:
    """The drawing of the train at ``out.t`` (see the module docstring), as plain dicts."""
    return marker_array(train, frame_id, stamp(out.t), coordinates(out, train, cart_widths(train)))


class TrainMarkers:
    """CDR bytes of :func:`train_markers` for a train, from a template: per call only the
    coordinates and the stamps are computed and written."""

    def __init__(self, train, frame_id: str = "map"):
        self.train, self.frame_id = train, frame_id
        self.widths = cart_widths(train)
        count = (_POINTS_PER_CART + 1) * len(train.carts) + (train.terrain is not None)
        slots = [Slot("xy", i) for i in range((2 if relief_of(train) is None else 3) * count)]
        self.template = CdrTemplate(MARKERS_TYPE, marker_array(train, frame_id, TIME_SLOTS, slots))

    def encode(self, out) -> bytes:
        """The CDR bytes of ``train_markers(out, train, frame_id)``."""
        sec, nanosec = stamp_parts(out.t)
        return self.template.fill(xy=coordinates(out, self.train, self.widths), sec=sec, nanosec=nanosec)
