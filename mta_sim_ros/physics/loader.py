"""Read trains and scenes from YAML into the frozen dataclasses of ``spec.py``, checking every rule.

Every fault raises :class:`SpecError` with one line of the form

    FIELD: VALUE in LOCATION of FILE must be RULE

e.g. ``mass: -3 in carts[1] of trains/x.yaml must be > 0``. LOCATION is a path into the
document (``top level``, ``carts[1]`` with 0-based list indices, ``forces.traction``,
``steering.params``), or a line for syntax faults; FILE is the path as given.

Units are SI. Angles are in radians, or in degrees under the same key with ``_deg`` appended
(``max_angle_deg: 40``); giving both forms is a fault. Numbers may be ints or floats
(``1e-8`` is read as a float, unlike plain YAML 1.1) and must be finite.
"""
from __future__ import annotations

import math
import os
import sys
from typing import Any, Callable, Iterable, NoReturn, Optional, Union

import numpy as np

from .. import validate
from ..validate import ANY, NON_NEGATIVE, POSITIVE, Rule
from . import maneuvers, spec

INTEGRATOR_METHODS = spec.INTEGRATOR_METHODS
TRACTION_LAWS = ("constant", "governor", "prescribed_speed")


class SpecError(validate.InputError):
    """A train or scene file breaks a rule; the message says which field, where and why."""


# --------------------------------------------------------------------------- reading YAML


def _fail(field: str, value: str, where: str, source: str, rule: str) -> NoReturn:
    raise SpecError(validate.fault_message(field, value, rule, where, source))


def _read(path: Union[str, os.PathLike]) -> tuple[dict, str]:
    """The top-level mapping of a YAML file, and the path as given (for messages); the file's
    size, nesting and aliases are bounded (validate.py)."""
    source = str(path)
    return validate.read_mapping(path, SpecError), source


def _parse(text: str, source: str) -> tuple[dict, str]:
    """The top-level mapping of a YAML text, and its source."""
    return validate.parse_mapping(text, source, SpecError), source


# --------------------------------------------------------------------------- rules and fields


_REQUIRED = object()  # default meaning "the field must be given"


class _Missing:
    """Stands for the value of a field that was not given, in messages."""

    def __str__(self) -> str:
        return "(missing)"


_show = validate.show
_is_number = validate.is_number


class _Section:
    """One YAML mapping being read: its fields are taken one by one, each checked.

    ``fields`` are the allowed keys; each key in ``angles`` may instead be given in degrees
    as KEY_deg (a number or list of numbers), converted to radians here.
    """

    def __init__(self, data: dict, path: str, source: str, fields: Optional[Iterable[str]], angles: Iterable[str] = ()):
        self.path, self.source = path, source
        self.where = path or "top level"
        self.raw = data
        self.angles = tuple(angles)
        self.degrees: dict[str, Any] = {}  # key -> value as given in degrees
        self.values = dict(data)
        for key in self.angles:
            self._convert_degrees(key)
        if fields is not None:
            self.check_fields(fields)

    def check_fields(self, fields: Iterable[str]) -> None:
        """Fault on the first key that is not one of ``fields`` (a typo, most likely)."""
        allowed = tuple(fields)
        for key, value in self.values.items():
            if key not in allowed:
                spelled = [f"{k}[_deg]" if k in self.angles else k for k in allowed]
                name = key if isinstance(key, str) and len(key) <= validate.SHOW_WIDTH else _show(key)
                self.fail(name, value, validate.unknown_name_rule(key, allowed, spelled=spelled))

    def _convert_degrees(self, key: str) -> None:
        deg_key = key + "_deg"
        if deg_key not in self.values:
            return
        value = self.values.pop(deg_key)
        if key in self.values:
            self.fail(deg_key, value, f"given alone: {key} (radians) is given too")
        if _is_number(value):
            self.values[key] = math.radians(value)
        elif isinstance(value, list) and all(_is_number(v) for v in value):
            self.values[key] = [math.radians(v) for v in value]
        else:
            self.fail(deg_key, value, "a number or a list of numbers (degrees)")
        self.degrees[key] = value

    def fail(self, key: str, value: Any, rule: str) -> NoReturn:
        """Raise the SpecError for field ``key``, spelled and valued as the user wrote it."""
        if key in self.degrees:
            if _is_number(value):
                rule += f" (given in degrees: {value:.6g} rad)"
            key, value = key + "_deg", self.degrees[key]
        _fail(key, _show(value), self.where, self.source, rule)

    def fail_item(self, key: str, index: int, rule: str) -> NoReturn:
        """Raise the SpecError for entry ``index`` of the list under ``key``, as the user wrote it."""
        spelled, given = (key + "_deg", self.degrees[key]) if key in self.degrees else (key, self.values[key])
        _fail(f"{spelled}[{index}]", _show(given[index]), self.where, self.source, rule)

    def has(self, key: str) -> bool:
        return key in self.values

    def _absent(self, key: str, default: Any, kind: str) -> Any:
        """The default of a field that is not given; a fault if it is required."""
        if default is _REQUIRED:
            self.fail(key, _Missing(), f"given: {kind}")
        return default

    def number(self, key: str, rule: Rule = ANY, default: Any = _REQUIRED) -> float:
        """A finite number obeying ``rule``; ``default`` if absent (unless required)."""
        if key not in self.values:
            return self._absent(key, default, "a number" if rule is ANY else f"a number {rule.text}")
        value = self.values[key]
        problem = validate.check_number(value, ANY)
        if problem:
            self.fail(key, value, problem)
        if not rule.test(value):
            self.fail(key, value, rule.text)
        return float(value)

    def numbers(self, key: str, rule: Rule = ANY, default: Any = _REQUIRED) -> tuple[float, ...]:
        """A list of finite numbers, each obeying ``rule``."""
        if key not in self.values:
            return self._absent(key, default, "a list of numbers")
        value = self.values[key]
        if not isinstance(value, list):
            self.fail(key, value, "a list of numbers")
        if len(value) > validate.MAX_TABLE:
            self.fail(key, value, f"a list of at most {validate.MAX_TABLE} numbers (it has {len(value)})")
        for i, item in enumerate(value):
            if not validate.is_finite(item) or not rule.test(item):
                self.fail_item(key, i, "a finite number" if rule is ANY else f"a finite number {rule.text}")
        return tuple(float(item) for item in value)

    def text(self, key: str, default: Any = _REQUIRED) -> str:
        """A non-empty string."""
        if key not in self.values:
            return self._absent(key, default, "a non-empty string")
        value = self.values[key]
        if not isinstance(value, str) or not value.strip():
            self.fail(key, value, "a non-empty string")
        return value

    def flag(self, key: str, default: Any = _REQUIRED) -> bool:
        """true or false."""
        if key not in self.values:
            return self._absent(key, default, "true or false")
        value = self.values[key]
        if not isinstance(value, bool):
            self.fail(key, value, "true or false")
        return value

    def choice(self, key: str, choices: Iterable[str], default: Any = _REQUIRED) -> str:
        """One of ``choices``, matched case-insensitively and returned as spelled there."""
        choices = tuple(choices)
        value = self.values[key] if key in self.values else self._absent(key, default, f"one of {', '.join(choices)}")
        by_lower = {c.lower(): c for c in choices}
        if not isinstance(value, str) or value.lower() not in by_lower:
            self.fail(key, value, f"one of {', '.join(choices)}")
        return by_lower[value.lower()]

    def section(self, key: str, fields: Optional[Iterable[str]], angles: Iterable[str] = (), required: bool = False):
        """The mapping under ``key`` as a _Section (an empty one if absent and not required).

        ``fields=None`` leaves the check of its keys to the caller (see check_fields).
        """
        value = self.values.get(key, _REQUIRED if required else {})
        if value is _REQUIRED:
            self._absent(key, _REQUIRED, "a mapping of fields")
        if not isinstance(value, dict):
            self.fail(key, value, "a mapping of fields")
        return _Section(value, self._child(key), self.source, fields, angles)

    def sections(self, key: str, fields: Iterable[str], angles: Iterable[str] = (), required: bool = False):
        """The list of mappings under ``key`` as _Sections (empty if absent and not required)."""
        value = self.values.get(key, _REQUIRED if required else [])
        if value is _REQUIRED:
            self._absent(key, _REQUIRED, "a non-empty list of mappings")
        if not isinstance(value, list) or (required and not value):
            self.fail(key, value, "a non-empty list of mappings" if required else "a list of mappings")
        for i, item in enumerate(value):
            if not isinstance(item, dict):
                _fail(f"{key}[{i}]", _show(item), self.where, self.source, "a mapping of fields")
        return [_Section(item, f"{self._child(key)}[{i}]", self.source, fields, angles) for i, item in enumerate(value)]

    def _child(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path else key


# --------------------------------------------------------------------------- trains

# --------------------------------------------------------------------------- ranges
# Every number has a range, orders of magnitude beyond any machine, so that no accepted train or
# scene overflows the model's arithmetic (a ratio a_k / l_k squared) or makes it too stiff to step.


def _up_to(high: float, unit: str) -> Rule:
    return Rule(f"> 0 and <= {high:g} {unit}", lambda x: 0 < x <= high)


def _span(low: float, high: float, unit: str) -> Rule:
    return Rule(f"in [{low:g}, {high:g}] {unit}", lambda x: low <= x <= high)


def _magnitude(limit: float, unit: str) -> Rule:
    return Rule(f"within +-{limit:g} {unit}".rstrip(), lambda x: abs(x) <= limit)


LENGTH = _span(0.01, 1000.0, "m")
OFFSET = _magnitude(1000.0, "m")
MASS = _up_to(1e7, "kg")
YAW_INERTIA = _up_to(1e10, "kg m^2")
STIFFNESS = _up_to(1e10, "N/rad")
FORCE = _magnitude(1e8, "N")
MAX_FORCE = _up_to(1e8, "N")
MAX_POWER = _up_to(1e9, "W")
SPEED = _magnitude(100.0, "m/s")
GAIN = _up_to(1e9, "N per m/s")
INTEGRAL_GAIN = _span(0.0, 1e9, "N per m")
TIME_CONSTANT = _span(1e-3, 1e6, "s")
ACCELERATION = _up_to(1e3, "m/s^2")
DRAFT_COEFFICIENT = _span(0.0, 1e8, "N per unit")
DRAFT_SIZE = _up_to(1e3, "(factor, m or cm)")
STEER_RATE = _up_to(100.0, "rad/s")
GRAVITY = _up_to(100.0, "m/s^2")
SMOOTHING = _span(1e-6, 10.0, "m/s")
POSITION = _magnitude(1e7, "m")
HEADING = _magnitude(1e3, "rad")
TIME = _magnitude(validate.MAX_DURATION, "s")
TOLERANCE = _up_to(1.0, "(relative or absolute)")
MANEUVER_PARAM = _magnitude(validate.MAX_DURATION, "")  # s, rad, m/s, m: each manoeuvre checks its own


CART_FIELDS = ("name", "length", "hitch_offset", "com_offset", "mass", "yaw_inertia", "max_hitch_angle",
               "cornering_stiffness")
HITCH_ANGLE = Rule("in (0, pi]", lambda x: 0 < x <= math.pi)


def _cart(s: _Section) -> spec.Cart:
    """One cart: l_k > 0, a_k and c_k any finite, m_k > 0, J_k > 0 (MODEL.md, Geometry)."""
    return spec.Cart(
        name=s.text("name"),
        length=s.number("length", LENGTH),
        hitch_offset=s.number("hitch_offset", OFFSET),
        com_offset=s.number("com_offset", OFFSET),
        mass=s.number("mass", MASS),
        yaw_inertia=s.number("yaw_inertia", YAW_INERTIA),
        max_hitch_angle=s.number("max_hitch_angle", HITCH_ANGLE, spec.Cart.max_hitch_angle),
        cornering_stiffness=s.number("cornering_stiffness", STIFFNESS, None),
    )


def _carts(top: _Section) -> tuple[spec.Cart, ...]:
    carts: list[spec.Cart] = []
    for s in top.sections("carts", CART_FIELDS, ("max_hitch_angle",), required=True):
        cart = _cart(s)
        for j, other in enumerate(carts):
            if other.name == cart.name:
                s.fail("name", cart.name, f"unique: carts[{j}] has it too")
        carts.append(cart)
    return tuple(carts)


_TRACTION_FIELDS = {
    "constant": ("law", "force"),
    "governor": ("law", "set_speed", "max_force", "max_power", "kp", "ki", "windup_time"),
    "prescribed_speed": ("law", "set_speed", "response_time", "max_accel"),
}


def _traction(forces: _Section) -> spec.Traction:
    """Traction at A_1; the fields allowed and required depend on the law (spec.Traction)."""
    s = forces.section("traction", None, required=True)
    law = s.choice("law", TRACTION_LAWS)
    s.check_fields(_TRACTION_FIELDS[law])
    defaults = spec.Traction(law=law)
    if law == "constant":
        return spec.Traction(law=law, force=s.number("force", FORCE))
    if law == "governor":
        return spec.Traction(
            law=law,
            set_speed=s.number("set_speed", SPEED),
            max_force=s.number("max_force", MAX_FORCE),
            max_power=s.number("max_power", MAX_POWER),
            kp=s.number("kp", GAIN),
            ki=s.number("ki", INTEGRAL_GAIN),
            windup_time=s.number("windup_time", TIME_CONSTANT, defaults.windup_time),
        )
    return spec.Traction(
        law=law,
        set_speed=s.number("set_speed", SPEED, defaults.set_speed),
        response_time=s.number("response_time", TIME_CONSTANT),
        max_accel=s.number("max_accel", ACCELERATION, defaults.max_accel),
    )


def _cart_name(s: _Section, names: tuple[str, ...]) -> str:
    """The ``cart`` field of a force element: the name of a cart of this train."""
    name = s.text("cart")
    if name not in names:
        s.fail("cart", name, f"the name of a cart: one of {', '.join(names)}")
    return name


ROLLING_COEFFICIENT = Rule("in [0, 1)", lambda x: 0 <= x < 1)


def _rolling(s: _Section, names: tuple[str, ...]) -> spec.Rolling:
    """Rolling resistance f m_k g at B_k, 0 <= f < 1."""
    return spec.Rolling(cart=_cart_name(s, names), coefficient=s.number("coefficient", ROLLING_COEFFICIENT))


def _draft(s: _Section, names: tuple[str, ...]) -> spec.Draft:
    """ASABE D497 draft F_i (A + B S + C S^2) W T at B_k: A, B, C >= 0; F_i, W, T > 0."""
    return spec.Draft(
        cart=_cart_name(s, names),
        A=s.number("A", DRAFT_COEFFICIENT),
        B=s.number("B", DRAFT_COEFFICIENT, 0.0),
        C=s.number("C", DRAFT_COEFFICIENT, 0.0),
        soil_factor=s.number("soil_factor", DRAFT_SIZE, 1.0),
        width=s.number("width", DRAFT_SIZE, 1.0),
        depth=s.number("depth", DRAFT_SIZE, 1.0),
    )


MAX_STEER = Rule("in (0, pi/2)", lambda x: 0 < x < math.pi / 2)


def _actuator(top: _Section) -> spec.Actuator:
    """Steering actuator: first-order lag with rate and angle limits (spec.Actuator)."""
    if not top.has("steering_actuator"):
        return spec.Train.actuator
    s = top.section("steering_actuator", ("time_constant", "max_rate", "max_angle"), ("max_rate", "max_angle"))
    return spec.Actuator(
        time_constant=s.number("time_constant", TIME_CONSTANT),
        max_rate=s.number("max_rate", STEER_RATE),
        max_angle=s.number("max_angle", MAX_STEER),
    )


TRAIN_FIELDS = ("name", "carts", "forces", "steering_actuator", "smoothing_speed", "gravity")


def _train(data: dict, source: str) -> spec.Train:
    top = _Section(data, "", source, TRAIN_FIELDS)
    carts = _carts(top)
    names = tuple(c.name for c in carts)
    forces = top.section("forces", ("traction", "rolling", "draft"), required=True)
    rolling_fields = ("cart", "coefficient")
    draft_fields = ("cart", "A", "B", "C", "soil_factor", "width", "depth")
    return spec.Train(
        name=_name(top, source),
        carts=carts,
        traction=_traction(forces),
        rolling=tuple(_rolling(s, names) for s in forces.sections("rolling", rolling_fields)),
        draft=tuple(_draft(s, names) for s in forces.sections("draft", draft_fields)),
        actuator=_actuator(top),
        gravity=top.number("gravity", GRAVITY, spec.GRAVITY),
        smoothing_speed=top.number("smoothing_speed", SMOOTHING, spec.Train.smoothing_speed),
        source=source,
    )


NAME_CHARS = 100


def _name(top: _Section, source: str) -> str:
    """The train's or scene's name (default: the file's stem): a plain word, for it names the
    bag of a run (bags/<scene name>.mcap), never a path."""
    name = top.text("name", _stem(source))
    if top.has("name") and (len(name) > NAME_CHARS or not name.isprintable() or any(c in name for c in "/\\")):
        top.fail("name", name, f"a name of at most {NAME_CHARS} printable characters without / or \\")
    return name


def _stem(source: str) -> str:
    return os.path.splitext(os.path.basename(source))[0]


def load_train(path: Union[str, os.PathLike]) -> spec.Train:
    """Read and check a train file (layout: config/trains/default.yaml)."""
    return _train(*_read(path))


def train_from_data(data: dict, source: str) -> spec.Train:
    """Check a train given as the mapping a train file reads to (a sweep's scheme: the base file
    with fields changed); ``source`` names it in messages."""
    return _train(data, source)


def scene_from_data(data: dict, source: str, train: spec.Train) -> spec.Scene:
    """Check a scene given as the mapping a scene file reads to, run with ``train`` (whatever its
    ``train:`` names)."""
    return _scene(data, source, train)


def read_yaml_mapping(path: Union[str, os.PathLike]) -> dict:
    """The top-level mapping of a train or scene file, bounded (validate.py), faults as SpecError."""
    return _read(path)[0]


#: the reader of one YAML mapping, field by field (for the readers of other files: sweep specs)
Section = _Section


def load_train_text(text: str, source: str) -> spec.Train:
    """Check a train given as YAML text (e.g. as a bag recorded it); ``source`` names it in
    messages."""
    return _train(*_parse(text, source))


# --------------------------------------------------------------------------- scenes


def _table(s: _Section, value_key: str, value_rule: Rule = ANY) -> spec.Table:
    """A piecewise-linear table {time: [...], VALUE_KEY: [...]}: time strictly increasing."""
    time = s.numbers("time", TIME)
    value = s.numbers(value_key, value_rule)
    if not time:
        s.fail("time", s.values["time"], "a non-empty list of numbers")
    if any(later <= earlier for earlier, later in zip(time, time[1:])):
        s.fail("time", s.values["time"], "strictly increasing")
    if len(value) != len(time):
        s.fail(value_key, s.values[value_key], f"as long as time ({len(time)} entries)")
    return spec.Table(time=time, value=value)


def _speed(top: _Section) -> Optional[spec.Table]:
    """The speed command: a number (held), a {table: {time, speed}}, or None (set_speed)."""
    if not top.has("speed"):
        return None
    value = top.values["speed"]
    if _is_number(value):
        return spec.Table(time=(0.0,), value=(top.number("speed", SPEED),))
    if not isinstance(value, dict):
        top.fail("speed", value, "a number or {table: {time: [...], speed: [...]}}")
    outer = top.section("speed", ("table",))
    return _table(outer.section("table", ("time", "speed"), required=True), "speed", SPEED)


def _steering_limit(train: spec.Train) -> Rule:
    """|psi_1| <= max_angle: what the steering actuator can reach."""
    limit = train.actuator.max_angle
    return Rule(f"within +-max_angle = {limit:.4g} rad of the steering actuator", lambda x: abs(x) <= limit)


def _initial(top: _Section, train: spec.Train) -> spec.Initial:
    """Start pose: A_1 position, heading th_1, speed V, steering psi_1, hitch angles."""
    fields = ("x", "y", "heading", "speed", "steering", "hitch_angles")
    s = top.section("initial", fields, ("heading", "steering", "hitch_angles"))
    hitch_angles = s.numbers("hitch_angles", ANY, ())
    if hitch_angles and len(hitch_angles) != train.n - 1:
        s.fail("hitch_angles", s.values["hitch_angles"], f"a list of {train.n - 1} angles (one per hitch) or empty")
    for i, (angle, cart) in enumerate(zip(hitch_angles, train.carts[1:])):
        if abs(angle) >= cart.max_hitch_angle:
            rule = f"smaller in size than max_hitch_angle {cart.max_hitch_angle:.4g} rad of {cart.name}"
            s.fail_item("hitch_angles", i, rule)
    return spec.Initial(
        x=s.number("x", POSITION, 0.0),
        y=s.number("y", POSITION, 0.0),
        heading=s.number("heading", HEADING, 0.0),
        speed=s.number("speed", SPEED, 0.0),
        steering=s.number("steering", _steering_limit(train), 0.0),
        hitch_angles=hitch_angles,
    )


def _integrator(top: _Section, publish_rate: float) -> spec.Integrator:
    """Integrator method and tolerances; the step must fit in one publishing period."""
    s = top.section("integrator", ("method", "step", "rtol", "atol", "split_kinks"))
    default = spec.Integrator()
    return spec.Integrator(
        method=s.choice("method", INTEGRATOR_METHODS, default.method),
        step=s.number("step", validate.step_rule(publish_rate), default.step),
        rtol=s.number("rtol", TOLERANCE, default.rtol),
        atol=s.number("atol", TOLERANCE, default.atol),
        split_kinks=s.flag("split_kinks", default.split_kinks),
    )


def _speed_at(speed: Optional[spec.Table], initial: spec.Initial, traction: spec.Traction) -> Callable[[float], float]:
    """The speed command as a function of time, for manoeuvres that need a speed.

    The scene's speed table if given; else the traction law's set_speed (the speed the
    governor or prescribed-speed law drives to); for the constant-force law, the initial speed.
    """
    if speed is not None:
        return lambda t: float(np.interp(t, speed.time, speed.value))
    constant = initial.speed if traction.law == "constant" else traction.set_speed
    return lambda t: constant


def _steering(top: _Section, train: spec.Train, speed_at: Callable[[float], float]) -> tuple[spec.Table, str]:
    """The steering command table and the manoeuvre's name ("" for a table)."""
    s = top.section("steering", ("table", "maneuver", "params"), required=True)
    if s.has("table") == s.has("maneuver"):
        top.fail("steering", s.raw, "a mapping with exactly one of table, maneuver")
    if s.has("table"):
        if s.has("params"):
            s.fail("params", s.values["params"], "given only with a maneuver")
        return _table(s.section("table", ("time", "angle"), ("angle",)), "angle", _steering_limit(train)), ""
    name = s.choice("maneuver", maneuvers.MANEUVERS)
    maneuver = maneuvers.MANEUVERS[name]
    p = s.section("params", maneuver.defaults, maneuver.angles)
    params = {key: p.number(key, MANEUVER_PARAM) for key in p.values}
    try:
        table = maneuvers.expand(
            name, params, speed_at=speed_at, wheelbase=train.carts[0].length, max_angle=train.actuator.max_angle
        )
    except maneuvers.ParamError as error:
        from_scene = error.param in maneuvers.SCENE_PARAMS and not p.has(error.param)
        value = p.values.get(error.param, error.value)
        p.fail(error.param, value, error.rule + (" (taken from the scene; give it in params)" if from_scene else ""))
    problem = _table_problem(table)
    if problem:
        s.fail("maneuver", name, f"expanded with these params to a table of {problem}")
    return table, name


def _table_problem(table: spec.Table) -> str:
    """'' if a table (an expanded manoeuvre's) has at most MAX_TABLE finite entries at strictly
    increasing times, else what it has instead."""
    if len(table.time) > validate.MAX_TABLE:
        return f"at most {validate.MAX_TABLE} entries (it has {len(table.time)})"
    if not all(map(math.isfinite, table.time + table.value)):
        return "finite times and values"
    if any(later <= earlier for earlier, later in zip(table.time, table.time[1:])):
        return "strictly increasing times (they collapse in floating point)"
    return ""


SCENE_FIELDS = ("name", "train", "duration", "initial", "steering", "speed", "integrator", "publish_rate",
                "fidelity", "needs")
FIDELITY_CHOICES = ("auto",) + spec.FIDELITY_LEVELS
NEEDS_FIELDS = tuple(spec.Needs.__dataclass_fields__)


def _needs(top: _Section) -> Optional[spec.Needs]:
    """What the scene needs: {OUTPUT: tolerance > 0} for outputs among spec.Needs' fields; at
    least one (an empty mapping says nothing: leave ``needs`` out instead)."""
    if not top.has("needs"):
        return None
    s = top.section("needs", NEEDS_FIELDS)
    if not s.values:
        top.fail("needs", s.raw, f"a non-empty mapping of OUTPUT: tolerance, OUTPUT one of {', '.join(NEEDS_FIELDS)}")
    return spec.Needs(**{key: s.number(key, POSITIVE) for key in s.values})


def _scene(data: dict, source: str, train: Optional[spec.Train] = None) -> spec.Scene:
    top = _Section(data, "", source, SCENE_FIELDS)
    if train is None:
        train = _scene_train(top)
    else:
        top.text("train")  # still a required field; the train itself is the one given
    initial = _initial(top, train)
    speed = _speed(top)
    publish_rate = top.number("publish_rate", validate.PUBLISH_RATE, spec.Scene.publish_rate)
    steering, maneuver = _steering(top, train, _speed_at(speed, initial, train.traction))
    integrator = _integrator(top, publish_rate)
    return spec.Scene(
        name=_name(top, source),
        train=train,
        duration=_duration(top, publish_rate, integrator.step),
        initial=initial,
        steering=steering,
        speed=speed,
        integrator=integrator,
        publish_rate=publish_rate,
        maneuver=maneuver,
        fidelity=top.choice("fidelity", FIDELITY_CHOICES, "auto"),
        needs=_needs(top),
        source=source,
        raw=data,
    )


def _duration(top: _Section, publish_rate: float, step: float) -> float:
    """The run's length, s: > 0, and a run of it finite (validate.run_size: ticks and steps)."""
    duration = top.number("duration", POSITIVE)
    problem = validate.run_size(duration, publish_rate, step)
    if problem:
        top.fail("duration", top.values["duration"], problem)
    return duration


def _scene_train(top: _Section) -> spec.Train:
    """The train named by ``train:``, a path relative to the scene file's folder."""
    relative = top.text("train")
    path = os.path.normpath(os.path.join(os.path.dirname(top.source), relative))
    if not os.path.isfile(path):
        top.fail("train", relative, f"a train file, relative to the scene's folder (not found: {path})")
    return load_train(path)


def load_scene(path: Union[str, os.PathLike]) -> spec.Scene:
    """Read and check a scene file and the train file it names (layout: config/scenes/*.yaml)."""
    return _scene(*_read(path))


def load_scene_text(text: str, source: str, train: spec.Train) -> spec.Scene:
    """Check a scene given as YAML text with its train given too (a bag records both): no file
    is opened, whatever the scene's ``train:`` names."""
    data, source = _parse(text, source)
    return _scene(data, source, train)


# --------------------------------------------------------------------------- any file


def load_file(path: Union[str, os.PathLike]) -> Union[spec.Train, spec.Scene]:
    """A train or a scene, told apart by its keys (``carts`` or ``train``)."""
    data, source = _read(path)
    if "carts" in data:
        return _train(data, source)
    if "train" in data:
        return _scene(data, source)
    _fail("file", f"keys {_show(list(data))}", "top level", source, "a train (with carts) or a scene (with train)")


def check_files(paths: Iterable[Union[str, os.PathLike]]) -> int:
    """Check each file, print ``ok: PATH`` or ``error: MESSAGE``; exit code 0, or 2 on a fault."""
    status = 0
    for path in paths:
        try:
            load_file(path)
        except SpecError as error:
            print(f"error: {error}", file=sys.stderr)
            status = 2
        else:
            print(f"ok: {path}")
    return status
