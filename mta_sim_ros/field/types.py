"""What the field room hands on: a plan's options, the plan itself (its route as arrays a compiled
controller reads), and the trace of a field worked (what the coverage metrics read). Data only.

Frames and units: the field's local metric frame (x east, y north, m: boundary.py), headings in
rad from +x counterclockwise, curvature in 1/m (> 0 turning left, whatever the direction of travel).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np
from shapely import geometry as sg

from .boundary import Field

ROUTES = ("auto", "boustrophedon", "skip", *(f"skip{k}" for k in range(2, 10)))  # order.ORDERS
TURNS = ("auto", "u", "bulb", "fishtail")
SEGMENT_KINDS = ("swath", "headland", "turn", "transit")


@dataclass(frozen=True)
class PlanOptions:
    """How a field is to be worked (the CLI's flags, a field scene's ``plan:``, a sweep's factors)."""

    width: float  # m, the implement's working width (train.implement.width)
    overlap: float = 0.0  # share of the width neighbouring swaths overlap, in [0, 0.5)
    angle: Optional[float] = None  # rad from +x: the swaths' direction; None: the angle that minimises turns
    headlands: Optional[int] = None  # headland rings; None: the field's own
    route: str = "auto"  # ROUTES: the order of the swaths (auto: the fewest turns narrower than the narrowest U)
    turn: str = "auto"  # TURNS: the kind of a turn narrower than the narrowest U (a U wherever one fits)
    work_headlands: bool = True  # the headland rings are worked, last, after the swaths


@dataclass(frozen=True)
class Segment:
    """A stretch of the route: route vertices first..last (inclusive)."""

    kind: str  # SEGMENT_KINDS
    first: int
    last: int
    reverse: bool = False  # driven backwards
    index: int = -1  # swath or headland ring number, -1 for turns and transits


@dataclass(frozen=True)
class Route:
    """The path the implement's working point follows, as arrays of m vertices (m >= 2), spaced at
    most ``spacing`` apart along it. Vertex i's flags hold on the stretch from vertex i to i + 1."""

    xy: np.ndarray  # (m, 2) m
    s: np.ndarray  # (m,) arc length from the start, m (increasing)
    heading: np.ndarray  # (m,) rad: the direction of travel's tangent (reversed stretches: the tangent
    #                       the implement moves along, i.e. the cart points the opposite way)
    curvature: np.ndarray  # (m,) 1/m of the path at the vertex
    working: np.ndarray  # (m,) bool: implement lowered
    reverse: np.ndarray  # (m,) bool: driven backwards
    segment: np.ndarray  # (m,) int: index into Plan.segments
    spacing: float  # m


@dataclass(frozen=True)
class Plan:
    """A coverage plan of one field for one implement width."""

    field: Field
    options: PlanOptions
    angle: float  # rad: the swaths' direction used
    headland_rings: tuple  # shapely LineStrings: the headland passes' centre lines, outermost first
    inner: sg.base.BaseGeometry  # the ground inside the headlands (the swaths cover it)
    target: sg.base.BaseGeometry  # the ground the plan means to work (inner, plus the headlands if worked)
    swaths: tuple  # shapely LineStrings, in the order driven (each in its direction of travel)
    segments: tuple[Segment, ...]
    route: Route
    turn_radius: float  # m: the smallest radius of the implement's path in a turn (the train's own)
    headland_width: float  # m: the headland band's width (rings x width, or what the turns need)
    notes: tuple[str, ...] = field(default_factory=tuple)  # choices made, in words (auto angle, route...)


@dataclass
class FieldTrace:
    """A field worked, tick by tick (``ticks + 1`` rows, row 0 the start). What the coverage
    metrics and the report read; ROS-free, no bag needed."""

    plan: Plan
    tick: float  # s between rows
    t: np.ndarray  # (r,) s
    implement: np.ndarray  # (r, 2) the working point, m
    lowered: np.ndarray  # (r,) bool: implement working from this row to the next
    segment: np.ndarray  # (r,) int: the route segment being driven
    tracking_error: np.ndarray  # (r,) signed lateral offset of the working point from the route, m (> 0: left)
    axle: np.ndarray  # (r, n, 2) B_k of every cart, m
    heading: np.ndarray  # (r, n) th_k, rad
    hitch_angle: np.ndarray  # (r, n - 1) rad
    margin: np.ndarray  # (r,) smallest jackknife margin, rad
    speed: np.ndarray  # (r,) V, m/s
    power: np.ndarray  # (r,) traction power F_A1 V, W
    verdict: str = "ok"  # ok | stopped
    reason: str = ""  # why it stopped
