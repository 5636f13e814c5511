"""The node's parameters as plain data: names, defaults, ranges and choices, which may change
while running, and their checks. No ROS here: the node turns each :class:`Param` into a ROS
ParameterDescriptor, the run session (run_session.py) checks values with :func:`check_value`, and
:func:`read_params_file` checks a ROS parameters file by the same rules before ROS reads it."""
from __future__ import annotations

import fnmatch
import os
from dataclasses import dataclass

from .. import validate
from ..integrate import METHODS
from ..messages.topics import COMMAND_TOPICS, MESSAGE_COMMANDS


def last_cpu() -> int:
    """The highest-numbered CPU this process may run on: the end of tick_cpu's range, so that
    the declared range names CPUs of this machine (timing.reserve_cpu still refuses one outside
    the process's affinity, or the only one)."""
    try:
        return max(os.sched_getaffinity(0))
    except (AttributeError, OSError, ValueError):  # not Linux
        return max(0, (os.cpu_count() or 1) - 1)


#: the topics a lockstep answer may be made of (lockstep_answer)
ANSWER_TOPICS = (*COMMAND_TOPICS, *MESSAGE_COMMANDS)


def answer_topics(value: str) -> tuple[str, ...]:
    """The topics of a lockstep_answer value ('' : none, each message answers)."""
    return tuple(t.strip() for t in value.split(",")) if value.strip() else ()


@dataclass(frozen=True)
class Param:
    name: str
    default: object
    description: str
    live: bool  # may change while running
    low: float | None = None
    high: float | None = None
    choices: tuple = ()
    text: validate.Rule | None = None  # a rule on a string value (its text says what it must be)




PARAMS = (
    Param("scene_file", "scenes/headland_turn.yaml",
          "scene YAML: the train, its start pose and the integrator (its steering table is not used: "
          "the node is steered over steering_angle)", live=False),
    Param("integrator_method", "", f"integrator, '' = the scene's; one of {', '.join(METHODS)}", live=False,
          choices=("",) + METHODS),
    Param("integrator_step", 0.0, "integrator step, s; 0 = the scene's", live=False, low=0.0, high=1.0),
    Param("publish_rate", 100.0, "ticks (and publications) per second of simulated time, Hz", live=False,
          low=validate.PUBLISH_RATE.low, high=validate.PUBLISH_RATE.high),
    Param("real_time_factor", 1.0, "simulated seconds per wall second; 0 = as fast as possible", live=True,
          low=0.0, high=1000.0),
    Param("watchdog_timeout", 1.0, "a steering command older than this (wall s) is stale; 0 = never", live=True,
          low=0.0, high=3600.0),
    Param("watchdog_action", "hold", "on a stale command: 'hold' the last one or steer 'straight'", live=True,
          choices=("hold", "straight")),
    Param("frame_id", "map", "frame of hitch_poses and markers", live=True, text=validate.FRAME_ID),
    Param("publish_cart_frames", True, "publish the frames of the robot model's joints (each cart through its "
          "hitch, the steered wheels, the fixed joints) on /tf and /tf_static; false when robot_state_publisher "
          "publishes them from robot_description and joint_states (odom -> base_link and frame_id -> odom "
          "stay the node's)", live=False),
    Param("cmd_vel_stamped", False, "cmd_vel is geometry_msgs/TwistStamped (nav2's enable_stamped_cmd_vel, the "
          "Jazzy ros2_controllers' drive controllers) instead of Twist", live=False),
    Param("bag_dir", "bags", "folder of the run bags <UTC start>_<run id>.mcap", live=False),
    Param("record", True, "write every run to an MCAP bag", live=False),
    Param("marker_rate", 10.0, "markers per second of simulated time, Hz", live=False, low=0.1, high=1000.0),
    Param("tick_cpu", -1, "CPU for the tick's thread alone (the node's other threads move off it; start "
          "other processes elsewhere for a reserved core); -1 = no pinning", live=False, low=-1, high=last_cpu()),
    Param("fidelity", "", "model level: '' = the scene's (auto: the cheapest meeting its needs), or auto, "
          "kinematic, dynamic, slip; a change applies at the next reset", live=True,
          choices=("", "auto", "kinematic", "dynamic", "slip")),
    Param("lockstep", False, "advance one tick only when a controller has answered the last outputs with a "
          "command on any command topic (pacing.py: the protocol); real_time_factor and the watchdog do not "
          "apply", live=False),
    Param("lockstep_answer", "", "lockstep: the command topics whose messages make one answer together, comma "
          "separated (e.g. steering_angle,speed_setpoint,implement_lowered: a tick runs once each has a message "
          "since the last one); '' = each command message is an answer", live=False, text=validate.Rule(
              f"'' or command topics separated by commas, each one of {', '.join(ANSWER_TOPICS)}",
              lambda v: v == "" or all(t in ANSWER_TOPICS for t in answer_topics(v)))),
    Param("lockstep_timeout", 5.0, "lockstep: wall s without an answer before the node says in the log and "
          "/diagnostics (WARN) which topics it waits on; it keeps waiting", live=True, low=0.01, high=3600.0),
)

BY_NAME = {p.name: p for p in PARAMS}


#: the node's name, as params files address it (``mta_sim:``, ``/unit1/mta_sim:``, ``/**:``)
NODE_NAME = "mta_sim"
ROS_PARAMETERS = "ros__parameters"


class ConfigError(validate.InputError):
    """Invalid node configuration: one clear message, the node does not start."""


def value_rule(p: Param, v) -> str:
    """The rule value v breaks for parameter p ('' if none): its type (that of the default; an
    int is taken for a float), a finite number, its choices and range."""
    kind = type(p.default)
    if kind is float:
        ok = validate.is_number(v)
    else:
        ok = isinstance(v, kind) and (kind is bool or not isinstance(v, bool))
    if not ok:
        return f"of type {kind.__name__}"
    if p.choices and v not in p.choices:
        return f"one of {', '.join(map(repr, p.choices))}"
    if p.text is not None and not p.text.test(v):
        return p.text.text
    if kind in (int, float) and not validate.is_finite(v):
        return "a finite number" + (f" in [{p.low:g}, {p.high:g}]" if p.low is not None else "")
    if p.low is not None and not p.low <= v <= p.high:
        return f"in [{p.low:g}, {p.high:g}]"
    return ""


def check_value(p: Param, v) -> str:
    """What is wrong with value v for parameter p ('' if nothing): VALUE must be RULE."""
    rule = value_rule(p, v)
    return f"{validate.show(v)} must be {rule}" if rule else ""


def config_problem(cfg: dict) -> tuple[str, str]:
    """(name, rule) of the first parameter of ``cfg`` (name -> value, all of PARAMS) that is
    wrong, alone or against another (the integrator step against the tick); ('', '') if none."""
    for p in PARAMS:
        rule = value_rule(p, cfg[p.name])
        if rule:
            return p.name, rule
    step = validate.step_rule(cfg["publish_rate"])
    if cfg["integrator_step"] and not step.test(cfg["integrator_step"]):
        return "integrator_step", step.text + " (or 0: the scene's)"
    return "", ""


def check_config(cfg: dict) -> None:
    """Raise ConfigError naming the first parameter of ``cfg`` that is wrong (config_problem)."""
    name, rule = config_problem(cfg)
    if name:
        raise ConfigError(f"parameter {name}: {validate.show(cfg[name])} must be {rule}")


# --------------------------------------------------------------------------- a ROS params file


def addresses_node(key: object, node: str = NODE_NAME) -> bool:
    """Whether a params file's top-level key names this node: ``/**``, ``NODE``, ``/NS/NODE``,
    or a pattern of ``*`` (one name) and ``**`` (any namespace) that matches it."""
    if not isinstance(key, str) or not key:
        return False
    last = key.rstrip("/").rsplit("/", 1)[-1]
    return last in ("**", "*") or fnmatch.fnmatchcase(node, last)


def read_params_file(path: str | os.PathLike, node: str = NODE_NAME) -> dict:
    """The parameters a ROS params file gives node ``node`` (name -> value), checked before ROS
    reads it: an existing, readable YAML mapping of ``<node or /**>: {ros__parameters: {...}}``,
    known parameter names, each value by value_rule with ROS's types (an integer is no double),
    and together with the defaults by config_problem. Raises ConfigError (one line)."""
    source = str(path)
    data = validate.read_mapping(path, ConfigError)
    values: dict = {}
    for key, section in data.items():
        where = _section_where(key, section, node, source)
        params = section[ROS_PARAMETERS]
        for name, value in params.items():
            _check_file_value(name, value, where, source)
        values.update(params)
    name, rule = config_problem({**{p.name: p.default for p in PARAMS}, **values})
    if name:
        validate.fail(name, validate.show(values.get(name)), rule, "the parameters", source, ConfigError)
    return values


def _section_where(key: object, section: object, node: str, source: str) -> str:
    """Where a top-level section's parameters sit (for messages), once it is checked to be
    ``<this node or a pattern of it>: {ros__parameters: {NAME: VALUE, ...}}``."""
    where = key if isinstance(key, str) and len(key) <= validate.SHOW_WIDTH else validate.show(key)
    if not addresses_node(key, node):
        validate.fail(where, validate.show(section), f"a section of this node: /**, {node} or /NAMESPACE/{node} "
                      f"(a params file for node {node}){validate.closest(key, ('/**', node))}", "top level", source,
                      ConfigError)
    if not isinstance(section, dict) or list(section) != [ROS_PARAMETERS]:
        validate.fail(where, validate.show(section), f"a mapping with the one key {ROS_PARAMETERS}", "top level", source,
                      ConfigError)
    if not isinstance(section[ROS_PARAMETERS], dict):
        validate.fail(ROS_PARAMETERS, validate.show(section[ROS_PARAMETERS]), "a mapping of NAME: VALUE", where,
                      source, ConfigError)
    return f"{where}.{ROS_PARAMETERS}"


def _check_file_value(name: object, value: object, where: str, source: str) -> None:
    """One parameter of a params file: a known name, a value its rules and ROS's types take."""
    shown_name = name if isinstance(name, str) and len(name) <= validate.SHOW_WIDTH else validate.show(name)
    p = BY_NAME.get(name) if isinstance(name, str) else None
    if p is None:
        validate.fail(shown_name, validate.show(value), validate.unknown_name_rule(name, BY_NAME, "parameter"), where,
                      source, ConfigError)
    rule = value_rule(p, value)
    if not rule and isinstance(p.default, float) and isinstance(value, int):
        rule = f"a float: write {value}.0 (ROS takes no integer for a double parameter)"
    if rule:
        validate.fail(shown_name, validate.show(value), rule, where, source, ConfigError)


def check_ros_args(argv: list[str]) -> None:
    """Check every params file given to ROS in ``argv`` (``--ros-args ... --params-file F``) for
    this node (renamed by ``-r __node:=NAME``), before rclpy reads them. Raises ConfigError."""
    ros, node, files = False, NODE_NAME, []
    for i, arg in enumerate(argv):
        if arg == "--ros-args":
            ros = True
        elif arg == "--":
            ros = False
        elif ros and arg == "--params-file":
            files.append(argv[i + 1] if i + 1 < len(argv) else "")
        elif ros and arg.startswith(("__node:=", "__name:=")):
            node = arg.split(":=", 1)[1]
    for path in files:
        read_params_file(path, node)


def override_problem(argv: list[str]) -> str:
    """'' if every parameter override ``-p NAME:=VALUE`` after ``--ros-args`` in ``argv`` is one rcl
    can parse (NAME:=VALUE, VALUE one YAML value), else the first fault in one line. Checked here,
    before rclpy.init: rcl's own parser says it in a log line and an exception of its own."""
    import yaml

    ros = False
    for i, arg in enumerate(argv):
        if arg == "--ros-args":
            ros = True
        elif arg == "--":
            ros = False
        elif ros and arg in ("-p", "--param"):
            rule = argv[i + 1] if i + 1 < len(argv) else ""
            name, sep, value = rule.partition(":=")
            if not sep or not name:
                return f"--ros-args {arg} {validate.show(rule)}: must be NAME:=VALUE"
            try:
                yaml.safe_load(value)
            except yaml.YAMLError as err:
                reason = str(getattr(err, "problem", "") or "not YAML")
                return f"--ros-args {arg} {validate.show(rule)}: the value must be one YAML value ({reason})"
    return ""


def argument(name: str):
    """An argparse ``type`` for a command-line option that sets numeric parameter ``name``: its
    range here, so a command and the node refuse the same values."""
    p = BY_NAME[name]
    return validate.number_arg(validate.Range.of(p.low, p.high), type(p.default))
