"""The coverage of a field worked live, as an occupancy grid over the field (what ``mta follow
--plan/--field`` publishes as nav_msgs/OccupancyGrid). ROS-free; numbers only.

The grid covers the field's bounds (plus a margin) in its local frame, ``resolution`` m cells,
row-major from its lower left corner (nav_msgs/OccupancyGrid's order). A cell is taken by its
centre. Each answered tick the implement's bar (``width`` wide across the implement cart's axis,
centred on the working point W, as field/coverage.py lays it) has swept the quadrilateral between
its last two positions if the implement was lowered over that tick; the cells whose centre lies in
it are worked by that pass. A pass is a lowered stretch cut where the cart has turned PIECE_TURN
(coverage.py's pieces): a cell under two passes is worked twice. The plan's target cells that are
not worked once W's station along the route has gone ``lag`` m past the last station the plan's
own strip covers them at (the route's end for those it never covers) are skipped.

Values (int8, OccupancyGrid's 0..100 and -1):

    -1   outside the field (or in an obstacle)
     0   in the field, not worked (yet)
    40   worked once
    70   worked twice or more
   100   skipped: the plan meant to work it, the implement has passed, it was not worked
"""
from __future__ import annotations

import math

import numpy as np
import shapely

from .coverage import PIECE_TURN
from .types import Plan

OUTSIDE, OPEN, ONCE, TWICE, SKIPPED = -1, 0, 40, 70, 100
#: m of margin round the field's bounds
MARGIN = 2.0
#: most cells a grid may have
MAX_CELLS = 4_000_000


def inside(px: np.ndarray, py: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Whether each point is inside ``polygon`` ((k, 2) vertices, closed implicitly), by the
    crossing number (even-odd): a quadrilateral that folds over itself counts what it covers once."""
    result = np.zeros(px.shape, dtype=bool)
    k = polygon.shape[0]
    for i in range(k):
        (x0, y0), (x1, y1) = polygon[i], polygon[(i + 1) % k]
        if y0 == y1:
            continue
        crosses = (y0 > py) != (y1 > py)
        x_at = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
        result ^= crosses & (px < x_at)
    return result


class CoverageGrid:
    """The live coverage of ``plan``'s field by an implement ``width`` wide (module docstring)."""

    def __init__(self, plan: Plan, width: float, resolution: float = 0.5, lag: float | None = None):
        self.plan, self.width, self.resolution = plan, float(width), float(resolution)
        self.lag = float(width) if lag is None else float(lag)
        x0, y0, x1, y1 = plan.field.polygon.bounds
        self.origin = (x0 - MARGIN, y0 - MARGIN)
        self.cols = int(math.ceil((x1 - x0 + 2 * MARGIN) / resolution))
        self.rows = int(math.ceil((y1 - y0 + 2 * MARGIN) / resolution))
        if self.cols * self.rows > MAX_CELLS:
            raise ValueError(f"a grid of {self.cols} x {self.rows} cells of {resolution:g} m is over {MAX_CELLS}: "
                             f"take larger cells")
        cx, cy = self.centres()
        self.field = shapely.contains_xy(plan.field.polygon, cx, cy)
        self.target = shapely.contains_xy(plan.target, cx, cy) & self.field
        self.count = np.zeros((self.rows, self.cols), dtype=np.int32)
        self.last_pass = np.full((self.rows, self.cols), -1, dtype=np.int64)
        self.planned = self._planned_stations()
        self.passes = -1
        self.turned = 0.0
        self.bar = None  # (left, right, heading) at the last pose
        self.lowered = False  # over the tick from the last pose on
        self.new_pass = True  # the next lowered tick starts a pass

    def centres(self, r0: int = 0, r1: int | None = None, c0: int = 0, c1: int | None = None):
        """The cell centres (x, y) of rows r0..r1 and columns c0..c1 (2-D arrays)."""
        r1 = self.rows if r1 is None else r1
        c1 = self.cols if c1 is None else c1
        xs = self.origin[0] + (np.arange(c0, c1) + 0.5) * self.resolution
        ys = self.origin[1] + (np.arange(r0, r1) + 0.5) * self.resolution
        return np.meshgrid(xs, ys)

    def _cells(self, polygon: np.ndarray):
        """(row slice, column slice, mask) of the cells whose centre lies in ``polygon``."""
        res, (ox, oy) = self.resolution, self.origin
        lo, hi = polygon.min(axis=0), polygon.max(axis=0)
        c0, c1 = max(int(math.floor((lo[0] - ox) / res)), 0), min(int(math.ceil((hi[0] - ox) / res)), self.cols)
        r0, r1 = max(int(math.floor((lo[1] - oy) / res)), 0), min(int(math.ceil((hi[1] - oy) / res)), self.rows)
        if c1 <= c0 or r1 <= r0:
            return None
        cx, cy = self.centres(r0, r1, c0, c1)
        return slice(r0, r1), slice(c0, c1), inside(cx, cy, polygon)

    def _planned_stations(self) -> np.ndarray:
        """Per cell, the last route station at which the plan's own bar (across the route's
        heading at W's path) covers it; the route's end for every other cell."""
        route = self.plan.route
        normal = np.column_stack((-np.sin(route.heading), np.cos(route.heading))) * (0.5 * self.width)
        left, right = route.xy + normal, route.xy - normal
        planned = np.full((self.rows, self.cols), -np.inf)
        for i in np.flatnonzero(route.working[:-1]):
            cells = self._cells(np.array([left[i], left[i + 1], right[i + 1], right[i]]))
            if cells is not None:
                rows, cols, mask = cells
                block = planned[rows, cols]
                block[mask] = np.maximum(block[mask], route.s[i + 1])
        planned[~np.isfinite(planned)] = route.s[-1]
        return planned

    def add(self, point, heading: float, lowered: bool) -> None:
        """The implement at W = ``point`` (x, y) with its cart's ``heading``, lowered from now on
        (``lowered``) or not: the strip since the last pose is worked if it was lowered since."""
        normal = np.array([-math.sin(heading), math.cos(heading)]) * (0.5 * self.width)
        w = np.asarray(point[:2], dtype=float)
        bar = (w + normal, w - normal, heading)
        if self.bar is not None and self.lowered:
            turn = abs(math.remainder(heading - self.bar[2], 2.0 * math.pi))
            self.turned += turn
            if self.passes < 0 or self.turned >= PIECE_TURN or self.new_pass:
                self.passes, self.turned, self.new_pass = self.passes + 1, 0.0, False
            cells = self._cells(np.array([self.bar[0], bar[0], bar[1], self.bar[1]]))
            if cells is not None:
                rows, cols, mask = cells
                fresh = mask & (self.last_pass[rows, cols] != self.passes)
                self.count[rows, cols] += fresh
                self.last_pass[rows, cols][fresh] = self.passes
        if not lowered:
            self.new_pass = True  # the next lowered stretch is a pass of its own
        self.bar, self.lowered = bar, bool(lowered)

    def values(self, station: float) -> np.ndarray:
        """The grid's int8 values (module docstring), rows x cols, W at ``station`` m along the route."""
        out = np.full((self.rows, self.cols), OPEN, dtype=np.int8)
        out[self.count == 1] = ONCE
        out[self.count >= 2] = TWICE
        out[self.target & (self.count == 0) & (self.planned + self.lag < station)] = SKIPPED
        out[~self.field] = OUTSIDE
        return out

    def worked(self) -> np.ndarray:
        """Whether each cell in the field is worked (once or more)."""
        return (self.count > 0) & self.field


def outlines(plan: Plan) -> list[np.ndarray]:
    """The field's outline and each obstacle's, closed rings of (x, y), outline first."""
    polygon = plan.field.polygon
    return [np.asarray(polygon.exterior.coords)] + [np.asarray(r.coords) for r in polygon.interiors]
