"""Reference paths for steering controllers (no ROS): a field of straight passes joined by
headland U-turns, as a densely sampled polyline with the pieces labelled.

Passes run along +x / -x alternately, ``spacing`` apart in +y (to the left of the first pass,
REP-103), joined by half circles of radius spacing / 2, turning left and right alternately. A seeder of width w needs passes w apart; where a U-turn of
radius w / 2 is too tight for the train (model.steady: R_B1 > the smallest radius that lets the
last cart follow), farmers skip passes: spacing = 2 w gives radius w.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Path:
    xy: np.ndarray  # N x 2, m
    heading: np.ndarray  # N, rad, direction of travel
    straight: np.ndarray  # N, bool: on a straight pass
    pass_index: np.ndarray  # N, int: which pass (-1 on turns)

    def nearest(self, point, hint: int = 0, window: int = 400) -> int:
        """Index of the path point nearest to ``point``, searched forward from ``hint``."""
        lo, hi = max(0, hint - 20), min(len(self.xy), hint + window)
        d = np.hypot(*(self.xy[lo:hi] - point).T)
        return lo + int(np.argmin(d))


def field_path(passes: int = 3, length: float = 80.0, spacing: float = 24.0, step: float = 0.25,
               x0: float = 0.0, y0: float = 0.0) -> Path:
    """``passes`` straight passes of ``length`` m, ``spacing`` m apart, starting at (x0, y0) along +x."""
    xy, heading, straight, index = [], [], [], []
    radius = spacing / 2.0
    for p in range(passes):
        forward = p % 2 == 0
        y = y0 + p * spacing
        xs = np.arange(0.0, length, step)
        direction = 1.0 if forward else -1.0
        start = x0 if forward else x0 + length
        for s in xs:
            xy.append((start + direction * s, y))
            heading.append(0.0 if forward else math.pi)
            straight.append(True)
            index.append(p)
        if p + 1 < passes:  # half circle towards the next pass: a left turn, then a right one, ...
            end_x = start + direction * length
            cx, cy = end_x, y + radius
            n = max(2, int(math.pi * radius / step))
            for i in range(n):
                a = -math.pi / 2 + math.pi * i / n  # angle of the point seen from the centre
                a = a if forward else math.pi - a
                xy.append((cx + radius * math.cos(a), cy + radius * math.sin(a)))
                heading.append(math.pi * i / n if forward else math.pi - math.pi * i / n)
                straight.append(False)
                index.append(-1)
    return Path(np.array(xy), np.array(heading), np.array(straight), np.array(index))


def lateral_error(path: Path, point, index: int) -> float:
    """Signed distance of ``point`` from the path at ``index`` (m, positive = left of travel)."""
    d = np.asarray(point) - path.xy[index]
    th = path.heading[index]
    return float(-d[0] * math.sin(th) + d[1] * math.cos(th))
