"""Pure pursuit of the tractor along a field path, and the error of the implement on it (no ROS;
follow_node.py runs it as the ROS node of ``mta follow``).

The tractor's rear axle B_1 = A_1 - l_1 e_1 is the reference point (its velocity is along e_1: the
bicycle model pure pursuit assumes); it steers towards the path point ``lookahead`` metres ahead:

    alpha = angle from e_1 to (look-ahead point - B_1),  kappa = 2 sin(alpha) / lookahead,
    psi_1 = atan(l_1 kappa)       (B_1 runs on radius l_1 / tan psi_1, MODEL.md)

What matters in the field is where the implement goes: the lateral error of the last cart's axle
B_n from the path on the straight passes, leaving out the first ``settle`` metres of each pass
(where the train is still straightening out of the turn) and the last train length (where the
tractor has begun the next turn and pulls the implement inwards: on a real headland the implement
is lifted there).
"""
from __future__ import annotations

import math

import numpy as np

from .paths import Path, lateral_error


def cart_axle(points, th, k: int, length: float) -> np.ndarray:
    """B_k = A_k - l_k e_k from the hitch point A_k (``points[k]``, x and y) and heading ``th[k]``."""
    return np.array(points[k]) - length * np.array([math.cos(th[k]), math.sin(th[k])])


def train_length(train) -> float:
    """From the tractor's front A_1 to the last axle B_n, the train straight, m."""
    return sum(c.length + c.hitch_offset for c in train.carts[:-1]) + train.carts[-1].length


class Follower:
    """Pure pursuit fed pose by pose: ``steering`` answers the hitch points A_k and headings th_k of
    one pose with the steering command (clipped to ``max_angle``), and measures the implement's
    error; at the path's end it answers 0 and is ``done``."""

    def __init__(self, train, path: Path, lookahead: float, settle: float, max_angle: float):
        self.train, self.path, self.lookahead, self.settle, self.max_angle = train, path, lookahead, settle, max_angle
        self.tractor_index = 0
        self.implement_index = 0
        self.errors: list[float] = []
        self.done = False
        # arc length along the path, and where each pass starts
        seg = np.hypot(*np.diff(path.xy, axis=0).T)
        self.s = np.concatenate(([0.0], np.cumsum(seg)))
        self.pass_start, self.pass_end = {}, {}
        for i, p in enumerate(path.pass_index):
            self.pass_start.setdefault(int(p), self.s[i])
            self.pass_end[int(p)] = self.s[i]
        self.tail = train_length(train)

    def steering(self, points, th) -> float:
        """The steering command answering one pose (``points``: the A_k as (x, y); ``th``: the th_k)."""
        l1 = self.train.carts[0].length
        b1, th1 = cart_axle(points, th, 0, l1), th[0]
        self.tractor_index = self.path.nearest(b1, self.tractor_index)
        target_s = self.s[self.tractor_index] + self.lookahead
        if target_s >= self.s[-1]:
            self.done = True
            return 0.0
        target = self.path.xy[int(np.searchsorted(self.s, target_s))]
        d = target - b1
        alpha = math.atan2(d[1], d[0]) - th1
        kappa = 2.0 * math.sin(alpha) / self.lookahead
        steer = math.atan(l1 * kappa)
        self._measure(points, th)
        return max(-self.max_angle, min(self.max_angle, steer))

    def _measure(self, points, th) -> None:
        last = self.train.n - 1
        bn = cart_axle(points, th, last, self.train.carts[last].length)
        self.implement_index = self.path.nearest(bn, self.implement_index)
        i = self.implement_index
        p = int(self.path.pass_index[i])
        if (self.path.straight[i] and self.s[i] - self.pass_start[p] > self.settle
                and self.pass_end[p] - self.s[i] > self.tail):
            self.errors.append(lateral_error(self.path, bn, i))

    def figures(self) -> dict:
        """What the run measured (``mta follow --report``)."""
        e = np.abs(np.array(self.errors)) if self.errors else np.array([math.nan])
        return {"samples": len(self.errors), "max_m": float(np.max(e)),
                "rms_m": float(np.sqrt(np.mean(e**2))), "settle_m": self.settle,
                "lookahead_m": self.lookahead}

    def summary(self) -> str:
        """What the run measured, in a log line."""
        figures = self.figures()
        return (f"lateral error of '{self.train.carts[-1].name}' on the straight passes (after {self.settle:.0f} m, "
                f"before the last {self.tail:.0f} m): "
                f"max {figures['max_m']:.3f} m, RMS {figures['rms_m']:.3f} m over {len(self.errors)} samples")
