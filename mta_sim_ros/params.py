"""The node's parameters as plain data: names, defaults, ranges and choices, which may change
while running, and their checks. No ROS here: the node turns each :class:`Param` into a ROS
ParameterDescriptor, the run session (session.py) checks values with :func:`check_value`."""
from __future__ import annotations

from dataclasses import dataclass

from .integrate import METHODS


@dataclass(frozen=True)
class Param:
    name: str
    default: object
    description: str
    live: bool  # may change while running
    low: float | None = None
    high: float | None = None
    choices: tuple = ()


PARAMS = (
    Param("scene_file", "scenes/headland_turn.yaml",
          "scene YAML: the train, its start pose and the integrator (its steering table is not used: "
          "the node is steered over steering_angle)", live=False),
    Param("integrator_method", "", f"integrator, '' = the scene's; one of {', '.join(METHODS)}", live=False,
          choices=("",) + METHODS),
    Param("integrator_step", 0.0, "integrator step, s; 0 = the scene's", live=False, low=0.0, high=1.0),
    Param("publish_rate", 100.0, "ticks (and publications) per second of simulated time, Hz", live=False,
          low=1.0, high=1000.0),
    Param("real_time_factor", 1.0, "simulated seconds per wall second; 0 = as fast as possible", live=True,
          low=0.0, high=1000.0),
    Param("watchdog_timeout", 1.0, "a steering command older than this (wall s) is stale; 0 = never", live=True,
          low=0.0, high=3600.0),
    Param("watchdog_action", "hold", "on a stale command: 'hold' the last one or steer 'straight'", live=True,
          choices=("hold", "straight")),
    Param("frame_id", "map", "frame of hitch_poses and markers", live=True),
    Param("bag_dir", "bags", "folder of the run bags <UTC start>_<run id>.mcap", live=False),
    Param("record", True, "write every run to an MCAP bag", live=False),
    Param("marker_rate", 10.0, "markers per second of simulated time, Hz", live=False, low=0.1, high=1000.0),
    Param("tick_cpu", -1, "CPU for the tick's thread alone (the node's other threads move off it; start "
          "other processes elsewhere for a reserved core); -1 = no pinning", live=False, low=-1, high=4095),
    Param("fidelity", "", "model level: '' = the scene's (auto: the cheapest meeting its needs), or auto, "
          "kinematic, dynamic, slip; a change applies at the next reset", live=True,
          choices=("", "auto", "kinematic", "dynamic", "slip")),
)

BY_NAME = {p.name: p for p in PARAMS}


class ConfigError(ValueError):
    """Invalid node configuration: one clear message, the node does not start."""


def check_value(p: Param, v) -> str:
    """What is wrong with value v for parameter p ('' if nothing): its type (that of the
    default; an int is taken for a float), choices and range."""
    kind = type(p.default)
    if kind is float:
        ok = isinstance(v, (int, float)) and not isinstance(v, bool)
    else:
        ok = isinstance(v, kind) and (kind is bool or not isinstance(v, bool))
    if not ok:
        return f"{v!r} must be of type {kind.__name__}"
    if p.choices and v not in p.choices:
        return f"{v!r} must be one of {', '.join(map(repr, p.choices))}"
    if p.low is not None and not p.low <= v <= p.high:
        return f"{v} must be in [{p.low:g}, {p.high:g}]"
    return ""


def check_config(cfg: dict) -> None:
    """Raise ConfigError naming the first parameter of ``cfg`` (name -> value, all of PARAMS)
    that is wrong, alone or against another (the integrator step against the tick)."""
    for p in PARAMS:
        problem = check_value(p, cfg[p.name])
        if problem:
            raise ConfigError(f"parameter {p.name}: {problem}")
    if cfg["integrator_step"] and cfg["integrator_step"] > 1.0 / cfg["publish_rate"]:
        raise ConfigError(f"parameter integrator_step: {cfg['integrator_step']} must not exceed the tick "
                          f"1 / publish_rate = {1.0 / cfg['publish_rate']:g} s")
