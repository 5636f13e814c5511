"""A field plan worked live against the node: what ``mta follow --plan/--field`` decides, ROS-free
(field_node.py is its rclpy glue). No ROS.

- The start: the node's scene puts the train where the offline run starts it (drive.start_pose:
  straight along the route's first heading, W on its first vertex, at the first stretch's speed),
  on the dynamic level, rk4 at the offline step, one tick per controller tick (Settings.tick).
  ``start_files`` writes that scene and the node's parameters for it (lockstep, answers of three
  topics); a first pose whose W is more than START_TOLERANCE from the route's start is refused.
- Each tick (``Follow.answer``): the tracker's law (tracker.py: the offline loop's own), its
  answer sent as steering_angle, speed_setpoint and implement_lowered; the coverage grid
  (field/grid.py) told where the implement is.
- It ends when W passes the route's end (the train stopped, the implement lifted), or stops when
  W is farther than Settings.off_route from the route (as the offline run does).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ...field.grid import CoverageGrid
from ...field.types import Plan
from . import loop
from .design import Settings
from .drive import law_inputs, rk4_step, start_pose
from .tracker import Answer, Tracker

#: m: the first pose's W at most this far from the route's start
START_TOLERANCE = 1.0
#: the topics one answer is made of (the node's lockstep_answer)
ANSWER_TOPICS = ("steering_angle", "speed_setpoint", "implement_lowered")
DONE, STOPPED, REFUSED = "done", "stopped", "refused"


def start_scene_text(plan: Plan, train, settings: Settings, name: str) -> str:
    """The node's scene (YAML) of the offline run's start (module docstring)."""
    _, R, _ = law_inputs(plan.route, train, settings)
    x, y, heading = start_pose(train, plan.route)
    speed = float(R[0, loop.R_SPEED])
    duration = 2.0 * float(np.sum(np.diff(R[:, loop.R_S]) / np.abs(R[:-1, loop.R_SPEED]))) + 600.0
    return "\n".join([
        f"# The start of {plan.field.name}'s route for mta follow (written by mta follow --write-scene):",
        "# the train straight along the route's first heading, its working point on the first vertex.",
        f"name: {name}",
        f"train: {Path(train.source).resolve()}",
        f"duration: {duration:.1f}",
        f"initial: {{x: {x!r}, y: {y!r}, heading: {heading!r}, speed: {speed!r}}}",
        "steering: {maneuver: straight}",
        f"speed: {abs(speed)!r}" if speed > 0 else f"speed: {{table: {{time: [0], speed: [{speed!r}]}}}}",
        f"integrator: {{method: rk4, step: {rk4_step(train, settings)!r}}}",
        f"publish_rate: {1.0 / settings.tick!r}",
        "fidelity: dynamic", ""])


def node_params_text(scene_file: Path, settings: Settings, bag_dir: str = "bags") -> str:
    """The node's parameters for that scene: its rate (one tick a controller tick), lockstep, one
    answer of ANSWER_TOPICS a tick."""
    return "\n".join([
        "# The simulator node for mta follow --plan/--field (written by mta follow --write-scene):",
        "# mta node --params-file THIS",
        "/**:", "  ros__parameters:", f"    scene_file: {str(scene_file)!r}",
        f"    publish_rate: {1.0 / settings.tick!r}", "    lockstep: true",
        f"    lockstep_answer: {','.join(ANSWER_TOPICS)}", "    lockstep_timeout: 5.0",
        f"    bag_dir: {bag_dir!r}", "    record: true", ""])


def start_files(folder: Path, plan: Plan, train, settings: Settings) -> tuple[Path, Path]:
    """scene.yaml and sim.yaml in ``folder`` (made): the start (start_scene_text) and the node's
    parameters (node_params_text)."""
    folder.mkdir(parents=True, exist_ok=True)
    scene, params = folder / "scene.yaml", folder / "sim.yaml"
    scene.write_text(start_scene_text(plan, train, settings, f"{plan.field.name}_follow"))
    params.write_text(node_params_text(scene.resolve(), settings))
    return scene, params


class Follow:
    """The controller of ``mta follow --plan/--field`` without ROS: answers poses, keeps the grid."""

    def __init__(self, plan: Plan, train, settings: Settings = Settings(), resolution: float = 0.5):
        self.plan, self.train, self.settings = plan, train, settings
        self.tracker = Tracker(plan.route, train, settings)
        self.grid = CoverageGrid(plan, train.implement.width, resolution)
        self.cart = self.tracker.controller.cart
        self.status, self.reason = "", ""
        self.last: Answer | None = None
        self.station = 0.0

    @property
    def done(self) -> bool:
        return bool(self.status)

    def answer(self, points, th, psi: float, speed: float) -> tuple[float, float, bool]:
        """(steering, speed set-point, lowered) answering one pose (tracker.Tracker.answer's
        arguments); the train stopped and the implement lifted once it is done or stopped."""
        a = self.tracker.answer(points, th, psi, speed)
        if self.last is None and math.hypot(*np.subtract(a.point[:2], self.plan.route.xy[0])) > START_TOLERANCE:
            gap = math.hypot(*np.subtract(a.point[:2], self.plan.route.xy[0]))
            self.status, self.reason = REFUSED, (
                f"the node's train is not at the route's start: its working point is {gap:.2f} m from it (at most "
                f"{START_TOLERANCE:g}); start the node with the scene of mta follow --write-scene")
            return a.steering, 0.0, False
        self.grid.add(a.point[:2], th[self.cart], a.lowered)
        self.last, self.station = a, max(self.station, a.station)
        if a.finished:
            self.status, self.reason = DONE, "the working point has passed the route's end"
        elif abs(a.error) > self.settings.off_route:
            self.status, self.reason = STOPPED, (f"off the route: the working point is {abs(a.error):.2f} m from it "
                                                 f"(limit {self.settings.off_route:g} m)")
        if self.status:
            return a.steering, 0.0, False
        return a.steering, a.speed, a.lowered

    def grid_values(self) -> np.ndarray:
        """The coverage grid now (at the end: every target cell not worked is skipped)."""
        return self.grid.values(math.inf if self.status == DONE else self.station)

    def figures(self) -> dict:
        return {**self.tracker.figures(), "status": self.status or "running", "reason": self.reason,
                "station_m": self.station, "worked_cells": int(self.grid.worked().sum()),
                "resolution_m": self.grid.resolution}

    def summary(self) -> str:
        return f"{self.status or 'running'} ({self.reason}); {self.tracker.summary()}"
