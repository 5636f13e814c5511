"""The implement-tracking controller fed pose by pose: what its node runs (implement_node.py), as
reversing.Reverser answers poses. No ROS.

One control law, two drivers: each answer is ``loop.law``, the very compiled code the offline
loop (``loop.drive``) runs each tick (the working point projected on the route, the error state,
u = feedforward - K (x - x_ref), the forward guard, the speed schedule, lowered or lifted), called
through ``loop.answer`` on a state built from the pose given. Fed the offline run's states tick by
tick, it gives the offline run's commands bit for bit (test/test_follow_field.py).

A pose is what the node publishes each tick: the hitch points A_k and headings th_k of every cart
(hitch_poses), the applied steering psi_1 (joint_states) and the speed V of A_1 (odom gives B_1's,
V cos psi_1). The law reads no more of the state (not the governor's integral).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...field.types import Route
from ...physics.dynamics import Model
from ...run.simulation import kernel_path
from . import loop
from .design import Settings
from .drive import law_inputs


@dataclass(frozen=True)
class Answer:
    """One answer: the commands and where the working point W is."""

    steering: float  # rad, the steering command
    speed: float  # m/s, the speed set-point V (signed)
    lowered: bool  # the implement lowered (W's stretch of the route is worked)
    error: float  # m, W's lateral offset from the route (> 0 left of travel)
    segment: int  # the route segment W is projected on (a vertex index)
    station: float  # m along the route
    finished: bool  # W is beyond the route's last vertex
    point: tuple  # W (x, y, heading)


class Tracker:
    """The law of ``train``'s implement along ``route`` under ``settings``, one state at a time
    (``compiled``: as Simulation's). Keeps W's error on the worked stretches (``errors``)."""

    def __init__(self, route: Route, train, settings: Settings = Settings(), compiled: bool | None = None):
        self.train, self.settings = train, settings
        self.controller, self.table, self.params = law_inputs(route, train, settings)
        model = Model(train)
        self.P, self.size = model.P, model.layout.size
        use, _ = kernel_path(model, compiled)
        self.compiled = bool(use)
        self._answer = loop.answer if use else loop.answer.py_func
        self.K = np.ascontiguousarray(self.controller.K)
        self.ref = np.empty((self.table.shape[0], train.n + 1))
        self.cursor = np.zeros(loop.CURSOR)
        self.out = np.empty(loop.ANSWER)
        self.errors: list[float] = []
        self.answers = 0
        self.done = False

    def state(self, points, th, psi: float, speed: float) -> np.ndarray:
        """The state the law reads: A_1 of ``points`` (the A_k as (x, y)), the headings ``th``, the
        steering psi_1 and V; the governor's integral (not read) 0."""
        n = self.train.n
        y = np.zeros(self.size)
        y[0], y[1] = points[0][0], points[0][1]
        y[2:2 + n] = th
        y[n + 2], y[n + 3] = psi, speed
        return y

    def answer_state(self, y: np.ndarray) -> Answer:
        """The law at state ``y`` (the dynamic level's layout)."""
        out = self.out
        self._answer(self.P, np.ascontiguousarray(y, dtype=np.float64), self.table, self.ref, self.cursor, self.K,
                     self.controller.row, self.params, out)
        j, u = int(out[loop.A_SEGMENT]), float(out[loop.A_SHARE])
        R = self.table
        w = min(max(u, 0.0), 1.0)
        station = float(R[j, loop.R_S] + w * (R[j + 1, loop.R_S] - R[j, loop.R_S]))
        a = Answer(float(out[loop.A_COMMAND]), float(out[loop.A_SPEED]), bool(out[loop.A_LOWERED]),
                   float(out[loop.A_ERROR]), j, station, bool(out[loop.A_FINISHED]),
                   (float(out[loop.A_WX]), float(out[loop.A_WY]), float(out[loop.A_WTH])))
        self.answers += 1
        if a.lowered:
            self.errors.append(a.error)
        self.done = a.finished
        return a

    def answer(self, points, th, psi: float, speed: float) -> Answer:
        """The law at the pose given (``state``)."""
        return self.answer_state(self.state(points, th, psi, speed))

    def figures(self) -> dict:
        """What the run measured: W's error while lowered, the answers."""
        e = np.abs(np.array(self.errors)) if self.errors else np.array([math.nan])
        return {"answers": self.answers, "lowered_samples": len(self.errors), "max_m": float(e.max()),
                "rms_m": float(np.sqrt(np.mean(e ** 2))), "finished": self.done,
                "route_m": float(self.table[-1, loop.R_S])}

    def summary(self) -> str:
        f = self.figures()
        return (f"{f['answers']} answers, {'at the route end' if self.done else 'not at the route end'}; working "
                f"point's error while lowered: max {f['max_m']:.3f} m, RMS {f['rms_m']:.3f} m over "
                f"{f['lowered_samples']} samples")
