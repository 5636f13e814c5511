"""The route as arrays (types.Route): stretches of constant curvature and polylines, sampled.

A plan is built as a chain of stretches, each one Segment of the route: a swath, a headland ring,
a turn or a transit. A stretch is either a list of ``Move`` s from a pose (straights, arcs and
clothoids: headings and curvatures exact, a clothoid's points integrated to ~1e-12 m) or a polyline (a headland ring as shapely drew it). Sampling puts
vertices at most ``spacing`` apart; the vertex where two stretches meet belongs to the later one
(a vertex's flags hold from it to the next).

Heading is the direction of motion (driven backwards: the opposite of the cart's), curvature
d(heading)/ds, > 0 to the left. On moves both are the exact values at the vertex; on a polyline
the heading is its chord's to the next vertex and the curvature the turn at the vertex over the
mean of the two chords beside it. ``s`` is the length of the polyline through the vertices.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely import geometry as sg

from .types import Route, Segment

#: m: longest distance between route vertices
SPACING = 0.5


@dataclass(frozen=True)
class Pose:
    x: float
    y: float
    heading: float  # rad, the cart's heading (the way its front points)

    @property
    def xy(self) -> np.ndarray:
        return np.array([self.x, self.y])


@dataclass(frozen=True)
class Move:
    """Driving ``length`` m along a path of ``curvature`` (1/m, of the direction of motion, > 0
    left) at its start, forwards or backwards; ``sharpness`` (1/m^2) is the curvature's rate along
    the path: 0 a straight or an arc, else a clothoid (curvature + sharpness x s)."""

    length: float
    curvature: float = 0.0
    reverse: bool = False
    sharpness: float = 0.0

    @property
    def end_curvature(self) -> float:
        return self.curvature + self.sharpness * self.length

    @property
    def turn(self) -> float:
        """rad: the heading's change over the move."""
        return self.curvature * self.length + 0.5 * self.sharpness * self.length ** 2


@dataclass
class Stretch:
    """One segment of the route, sampled: (k, 2) points, (k,) heading and curvature, both ends in."""

    kind: str
    xy: np.ndarray
    heading: np.ndarray
    curvature: np.ndarray
    working: bool
    reverse: bool
    index: int = -1

    @property
    def line(self) -> sg.LineString:
        return sg.LineString(self.xy)

    @property
    def length(self) -> float:
        return float(np.hypot(*np.diff(self.xy, axis=0).T).sum())


def wrap(angle):
    """Angles to [-pi, pi)."""
    return (np.asarray(angle) + math.pi) % (2.0 * math.pi) - math.pi


def end_of(pose: Pose, move: Move) -> Pose:
    """The pose after ``move``."""
    xy, heading, _ = sample_move(pose, move, max(move.length, 1.0))
    return Pose(float(xy[-1, 0]), float(xy[-1, 1]), pose.heading + move.turn)


#: Gauss-Legendre nodes and weights on [0, 1] (degree 15 exact): a clothoid's chords integrated
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_GL_X, _GL_W = 0.5 * (_GL_X + 1.0), 0.5 * _GL_W
#: m: the longest piece of a clothoid one Gauss-Legendre rule integrates (its error ~ (h kappa)^16)
CLOTHOID_PIECE = 0.5


def clothoid_points(phi0: float, kappa0: float, sharpness: float, u: np.ndarray) -> np.ndarray:
    """(len(u), 2): the displacement from the start of a path of heading phi0 + kappa0 s +
    sharpness s^2 / 2 at the stations ``u`` (increasing, u[0] = 0), integrated piece by piece with
    Gauss-Legendre's rule (the chords cut to CLOTHOID_PIECE)."""
    cuts = np.unique(np.concatenate([u, np.arange(0.0, u[-1], CLOTHOID_PIECE)]))
    h = np.diff(cuts)
    s = cuts[:-1, None] + h[:, None] * _GL_X[None, :]
    phi = phi0 + kappa0 * s + 0.5 * sharpness * s * s
    step = np.column_stack([(np.cos(phi) @ _GL_W) * h, (np.sin(phi) @ _GL_W) * h])
    run = np.vstack([np.zeros((1, 2)), np.cumsum(step, axis=0)])
    return run[np.searchsorted(cuts, u)]


def sample_move(pose: Pose, move: Move, spacing: float):
    """(points, motion headings, curvatures) along ``move`` from ``pose``, both ends in: arcs and
    straights in closed form, clothoids integrated (``clothoid_points``)."""
    n = max(1, math.ceil(move.length / spacing - 1e-9))
    u = np.linspace(0.0, move.length, n + 1)
    phi0 = pose.heading + (math.pi if move.reverse else 0.0)
    phi = phi0 + move.curvature * u + 0.5 * move.sharpness * u * u
    if move.sharpness != 0.0:
        xy = np.array([pose.x, pose.y]) + clothoid_points(phi0, move.curvature, move.sharpness, u)
        return xy, phi, move.curvature + move.sharpness * u
    if move.curvature == 0.0:
        x = pose.x + u * math.cos(phi0)
        y = pose.y + u * math.sin(phi0)
    else:
        x = pose.x + (np.sin(phi) - math.sin(phi0)) / move.curvature
        y = pose.y - (np.cos(phi) - math.cos(phi0)) / move.curvature
    return np.column_stack([x, y]), phi, np.full(n + 1, move.curvature)


def moves_stretch(kind: str, pose: Pose, moves, working: bool = False, index: int = -1,
                  spacing: float = SPACING) -> list[Stretch]:
    """The moves from ``pose`` as stretches of ``kind``: one for each run of the same direction
    (a reversed run is its own segment). Zero-length moves are left out."""
    out: list[Stretch] = []
    for move in moves:
        if move.length <= 1e-9:
            continue
        xy, heading, curvature = sample_move(pose, move, spacing)
        if out and out[-1].reverse == move.reverse:
            last = out[-1]
            last.xy = np.vstack([last.xy[:-1], xy])
            last.heading = np.concatenate([last.heading[:-1], heading])
            last.curvature = np.concatenate([last.curvature[:-1], curvature])
        else:
            out.append(Stretch(kind, xy, heading, curvature, working, move.reverse, index))
        pose = Pose(float(xy[-1, 0]), float(xy[-1, 1]), pose.heading + move.turn)
    return out


def polyline_arrays(xy: np.ndarray, closed: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(heading, curvature) at the vertices of a polyline without repeated points (module
    docstring); ``closed``: its last point is its first, and it turns there as anywhere else."""
    step = np.diff(xy, axis=0)
    chord = np.hypot(step[:, 0], step[:, 1])
    heading = np.arctan2(step[:, 1], step[:, 0])
    curvature = np.zeros(len(xy))
    curvature[1:-1] = wrap(np.diff(heading)) / (0.5 * (chord[:-1] + chord[1:]))
    if closed and len(chord) > 1:
        curvature[0] = wrap(heading[0] - heading[-1]) / (0.5 * (chord[0] + chord[-1]))
        curvature[-1] = curvature[0]
    return np.concatenate([heading, heading[-1:]]), curvature


def polyline_stretch(kind: str, line: sg.LineString, working: bool, index: int = -1,
                     spacing: float = SPACING) -> Stretch:
    """A polyline driven forwards, its chords cut to at most ``spacing``."""
    xy = np.asarray(shapely.segmentize(line, spacing * (1.0 - 1e-9)).coords)[:, :2]
    step = np.diff(xy, axis=0)
    xy = xy[np.concatenate([[True], np.hypot(step[:, 0], step[:, 1]) > 1e-9])]
    heading, curvature = polyline_arrays(xy, line.is_ring)
    return Stretch(kind, xy, heading, curvature, working, False, index)


def stretch_pose(stretch: Stretch, end: bool = True) -> Pose:
    """The cart's pose at a stretch's last (or first) vertex."""
    i = -1 if end else 0
    back = math.pi if stretch.reverse else 0.0
    return Pose(float(stretch.xy[i, 0]), float(stretch.xy[i, 1]), float(stretch.heading[i]) - back)


def assemble(stretches: list[Stretch], spacing: float = SPACING) -> tuple[Route, tuple[Segment, ...]]:
    """The Route of the chained stretches and its Segments (each stretch one)."""
    parts, segments, first = [], [], 0
    for j, st in enumerate(stretches):
        last_one = j == len(stretches) - 1
        count = len(st.xy) if last_one else len(st.xy) - 1
        parts.append((st, count))
        segments.append(Segment(st.kind, first, first + len(st.xy) - 1, st.reverse, st.index))
        first += count
    xy = np.vstack([st.xy[:c] for st, c in parts])
    heading = np.concatenate([st.heading[:c] for st, c in parts])
    curvature = np.concatenate([st.curvature[:c] for st, c in parts])
    working = np.concatenate([np.full(c, st.working) for st, c in parts])
    reverse = np.concatenate([np.full(c, st.reverse) for st, c in parts])
    segment = np.concatenate([np.full(c, j) for j, (_, c) in enumerate(parts)])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    route = Route(xy=xy, s=s, heading=wrap(heading), curvature=curvature, working=working.astype(bool),
                  reverse=reverse.astype(bool), segment=segment.astype(int), spacing=spacing)
    return route, tuple(segments)
