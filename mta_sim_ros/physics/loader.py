"""Read trains and scenes from YAML into the frozen dataclasses of ``spec.py``, checking every rule.

Every fault raises :class:`SpecError` with one line of the form

    FIELD: VALUE in LOCATION of FILE must be RULE

e.g. ``mass: -3 in carts[1] of trains/x.yaml must be > 0``. LOCATION is a path into the
document (``top level``, ``carts[1]`` with 0-based list indices, ``forces.traction``,
``steering.params``), or a line for syntax faults; FILE is the path as given.

Every field, its unit, rule, default and meaning is declared in ``schema.py`` (docs/formats.md is
written from it); this module reads each through its declaration, in the order the checks run,
and checks what spans several fields. ``reader.py`` reads one mapping field by field.

Units are SI. Angles are in radians, or in degrees under the same key with ``_deg`` appended
(``max_angle_deg: 40``); giving both forms is a fault. Numbers may be ints or floats
(``1e-8`` is read as a float, unlike plain YAML 1.1) and must be finite.
"""
from __future__ import annotations

import dataclasses
import math
import os
import sys
from typing import Callable, Iterable, Optional, Union

import numpy as np

from .. import validate
from ..validate import Rule
from . import maneuvers, spec, terrain
from .reader import REQUIRED, Section, SpecError, fail, parse, read, show
from .schema import (ACTUATOR, CART, DRAFT, FIDELITY_CHOICES, FORCES, FUEL, IMPLEMENT, INITIAL, INTEGRATOR,
                     MANEUVER_PARAMS, NAME_CHARS, NEEDS, ROLLING, SCENE, SPEED_COMMAND_TABLE, SPEED_TABLE, STEERING,
                     STEERING_TABLE, TERRAIN, TRACTION, TRACTION_LAWS, TRAIN)

INTEGRATOR_METHODS = spec.INTEGRATOR_METHODS
CART_FIELDS = CART.keys
TRAIN_FIELDS = TRAIN.keys
SCENE_FIELDS = SCENE.keys
NEEDS_FIELDS = NEEDS.keys
_TRACTION_FIELDS = {law: schema.keys for law, schema in TRACTION.items()}

__all__ = ["SpecError", "Section", "load_train", "load_train_text", "train_from_data", "load_scene",
           "load_scene_text", "scene_from_data", "load_file", "check_files", "read_yaml_mapping", "TRAIN_FIELDS",
           "CART_FIELDS", "SCENE_FIELDS", "NEEDS_FIELDS", "FIDELITY_CHOICES", "INTEGRATOR_METHODS", "TRACTION_LAWS",
           "NAME_CHARS"]


# --------------------------------------------------------------------------- trains


def _cart(s: Section) -> spec.Cart:
    """One cart: l_k > 0, a_k and c_k any finite, m_k > 0, J_k > 0 (MODEL.md, Geometry)."""
    cart = spec.Cart(**CART.read(s))
    if (cart.track_width is None) != (cart.com_height is None):
        given = "track_width" if cart.com_height is None else "com_height"
        s.fail(given, getattr(cart, given), f"given with {'com_height' if given == 'track_width' else 'track_width'} "
               "(the rollover margin needs both), or neither")
    return cart


def _carts(top: Section) -> tuple[spec.Cart, ...]:
    carts: list[spec.Cart] = []
    for s in top.sections("carts", CART.keys, CART.angles, required=True):
        cart = _cart(s)
        for j, other in enumerate(carts):
            if other.name == cart.name:
                s.fail("name", cart.name, f"unique: carts[{j}] has it too")
        carts.append(cart)
    if carts and carts[-1].hitch_height is not None:
        s.fail("hitch_height", carts[-1].hitch_height, "not given on the last cart: no hitch behind it")
    return tuple(carts)


def _traction(forces: Section) -> spec.Traction:
    """Traction at A_1; the fields allowed and required depend on the law (spec.Traction)."""
    s = forces.section("traction", None, required=True)
    law = TRACTION["constant"]["law"].read(s)
    schema = TRACTION[law]
    s.check_fields(schema.keys)
    return spec.Traction(law=law, **schema.read(s, *schema.keys[1:]))


def _cart_name(s: Section, names: tuple[str, ...]) -> str:
    """The ``cart`` field of a force element: the name of a cart of this train."""
    name = s.text("cart")
    if name not in names:
        s.fail("cart", name, f"the name of a cart: one of {', '.join(names)}")
    return name


def _rolling(s: Section, names: tuple[str, ...]) -> spec.Rolling:
    """Rolling resistance f m_k g at B_k, 0 <= f < 1."""
    return spec.Rolling(cart=_cart_name(s, names), **ROLLING.read(s, "coefficient"))


def _draft(s: Section, names: tuple[str, ...]) -> spec.Draft:
    """ASABE D497 draft F_i (A + B S + C S^2) W T at B_k: A, B, C >= 0; F_i, W, T > 0."""
    return spec.Draft(cart=_cart_name(s, names), **DRAFT.read(s, *DRAFT.keys[1:]))


def _actuator(top: Section) -> spec.Actuator:
    """Steering actuator: first-order lag with rate and angle limits (spec.Actuator)."""
    if not top.has("steering_actuator"):
        return TRAIN["steering_actuator"].default
    s = top.section("steering_actuator", ACTUATOR.keys, ACTUATOR.angles)
    return spec.Actuator(**ACTUATOR.read(s))


def _implement(top: Section, names: tuple[str, ...]) -> Optional[spec.Implement]:
    """The working tool (spec.Implement), on a cart of this train; None when not given."""
    if not top.has("implement"):
        return None
    s = top.section("implement", IMPLEMENT.keys)
    return spec.Implement(cart=_cart_name(s, names), **IMPLEMENT.read(s, "width", "offset"))


def _fuel(top: Section) -> Optional[spec.Fuel]:
    if not top.has("fuel"):
        return None
    return spec.Fuel(**FUEL.read(top.section("fuel", FUEL.keys)))


def _train(data: dict, source: str) -> spec.Train:
    top = Section(data, "", source, TRAIN.keys)
    carts = _carts(top)
    names = tuple(c.name for c in carts)
    forces = top.section("forces", FORCES.keys, required=True)
    return spec.Train(
        name=_name(top, source),
        carts=carts,
        traction=_traction(forces),
        rolling=tuple(_rolling(s, names) for s in forces.sections("rolling", ROLLING.keys)),
        draft=tuple(_draft(s, names) for s in forces.sections("draft", DRAFT.keys)),
        actuator=_actuator(top),
        **TRAIN.read(top, "gravity", "smoothing_speed", "lateral_friction"),
        implement=_implement(top, names),
        fuel=_fuel(top),
        source=source,
    )


def _name(top: Section, source: str) -> str:
    """The train's or scene's name (default: the file's stem): a plain word, for it names the
    bag of a run (bags/<scene name>.mcap), never a path."""
    name = TRAIN["name"].read(top, default=_stem(source))
    if top.has("name") and (len(name) > NAME_CHARS or not name.isprintable() or any(c in name for c in "/\\")):
        top.fail("name", name, f"a name of at most {NAME_CHARS} printable characters without / or \\")
    return name


def _stem(source: str) -> str:
    return os.path.splitext(os.path.basename(source))[0]


def load_train(path: Union[str, os.PathLike]) -> spec.Train:
    """Read and check a train file (layout: config/trains/default.yaml)."""
    return _train(*read(path))


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
    return read(path)[0]


def load_train_text(text: str, source: str) -> spec.Train:
    """Check a train given as YAML text (e.g. as a bag recorded it); ``source`` names it in
    messages."""
    return _train(*parse(text, source))


# --------------------------------------------------------------------------- scenes


def _table(s: Section, value_key: str, value_rule: Optional[Rule] = None) -> spec.Table:
    """A piecewise-linear table {time: [...], VALUE_KEY: [...]}: time strictly increasing."""
    schema = STEERING_TABLE if value_key == "angle" else SPEED_TABLE
    time = schema["time"].read(s)
    value = schema[value_key].read(s, value_rule)
    if not time:
        s.fail("time", s.values["time"], "a non-empty list of numbers")
    if any(later <= earlier for earlier, later in zip(time, time[1:])):
        s.fail("time", s.values["time"], "strictly increasing")
    if len(value) != len(time):
        s.fail(value_key, s.values[value_key], f"as long as time ({len(time)} entries)")
    return spec.Table(time=time, value=value)


def _speed(top: Section) -> Optional[spec.Table]:
    """The speed command: a number (held), a {table: {time, speed}}, or None (set_speed)."""
    if not top.has("speed"):
        return None
    value = top.values["speed"]
    if validate.is_number(value):
        return spec.Table(time=(0.0,), value=(top.number("speed", SCENE["speed"].rule),))
    if not isinstance(value, dict):
        top.fail("speed", value, "a number or {table: {time: [...], speed: [...]}}")
    outer = top.section("speed", SPEED_COMMAND_TABLE.keys)
    return _table(outer.section("table", SPEED_TABLE.keys, required=True), "speed")


def _steering_limit(train: spec.Train) -> Rule:
    """|psi_1| <= max_angle: what the steering actuator can reach."""
    limit = train.actuator.max_angle
    return Rule(f"within +-max_angle = {limit:.4g} rad of the steering actuator", lambda x: abs(x) <= limit)


def _initial(top: Section, train: spec.Train) -> spec.Initial:
    """Start pose: A_1 position, heading th_1, speed V, steering psi_1, hitch angles."""
    s = top.section("initial", INITIAL.keys, INITIAL.angles)
    hitch_angles = INITIAL["hitch_angles"].read(s)
    if hitch_angles and len(hitch_angles) != train.n - 1:
        s.fail("hitch_angles", s.values["hitch_angles"], f"a list of {train.n - 1} angles (one per hitch) or empty")
    for i, (angle, cart) in enumerate(zip(hitch_angles, train.carts[1:])):
        if abs(angle) >= cart.max_hitch_angle:
            rule = f"smaller in size than max_hitch_angle {cart.max_hitch_angle:.4g} rad of {cart.name}"
            s.fail_item("hitch_angles", i, rule)
    return spec.Initial(
        **INITIAL.read(s, "x", "y", "heading", "speed"),
        steering=INITIAL["steering"].read(s, _steering_limit(train)),
        hitch_angles=hitch_angles,
    )


def _integrator(top: Section, publish_rate: float) -> spec.Integrator:
    """Integrator method and tolerances; the step must fit in one publishing period."""
    s = top.section("integrator", INTEGRATOR.keys)
    return spec.Integrator(
        method=INTEGRATOR["method"].read(s),
        step=INTEGRATOR["step"].read(s, validate.step_rule(publish_rate)),
        **INTEGRATOR.read(s, "rtol", "atol", "split_kinks", "tolerance"),
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


def speed_at(scene: spec.Scene) -> Callable[[float], float]:
    """The speed a manoeuvre of ``scene`` reads, as the loader expands its own (``_speed_at``): for
    ``mta maneuver``, which steers a loaded scene by another manoeuvre."""
    return _speed_at(scene.speed, scene.initial, scene.train.traction)


def _steering(top: Section, train: spec.Train, speed_at: Callable[[float], float]) -> tuple[spec.Table, str]:
    """The steering command table and the manoeuvre's name ("" for a table)."""
    s = top.section("steering", STEERING.keys, required=True)
    if s.has("table") == s.has("maneuver"):
        top.fail("steering", s.raw, "a mapping with exactly one of table, maneuver")
    if s.has("table"):
        if s.has("params"):
            s.fail("params", s.values["params"], "given only with a maneuver")
        table = s.section("table", STEERING_TABLE.keys, STEERING_TABLE.angles)
        return _table(table, "angle", _steering_limit(train)), ""
    name = STEERING["maneuver"].read(s)
    return _maneuver(s, name, train, speed_at), name


def _maneuver(s: Section, name: str, train: spec.Train, speed_at: Callable[[float], float]) -> spec.Table:
    """The table the manoeuvre ``name`` expands to with the params of the steering section ``s``."""
    maneuver = maneuvers.MANEUVERS[name]
    p = s.section("params", maneuver.defaults, maneuver.angles)
    params = {key: p.number(key, MANEUVER_PARAMS["PARAM"].rule) for key in p.values}
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
    return table


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


def _needs(top: Section) -> Optional[spec.Needs]:
    """What the scene needs: {OUTPUT: tolerance > 0} for outputs among spec.Needs' fields; at
    least one (an empty mapping says nothing: leave ``needs`` out instead)."""
    if not top.has("needs"):
        return None
    s = top.section("needs", NEEDS.keys)
    if not s.values:
        top.fail("needs", s.raw, f"a non-empty mapping of OUTPUT: tolerance, OUTPUT one of {', '.join(NEEDS.keys)}")
    return spec.Needs(**{key: NEEDS[key].read(s) for key in s.values})


def _terrain(top: Section, recorded: Optional[dict] = None) -> tuple[Optional[terrain.Plane],
                                                                    Optional[terrain.HeightGrid]]:
    """(plane, height grid) of ``terrain``, at most one of them (both None: level ground), the
    slope at most terrain.MAX_SLOPE_DEG; a grid as ``recorded`` (a run's record) where given,
    else from its file."""
    if not top.has("terrain"):
        return None, None
    s = top.section("terrain", TERRAIN.keys)
    if s.has("heights"):
        for key in ("grade_percent", "cross_slope_percent"):
            if s.has(key):
                s.fail(key, s.values[key], "not given with heights (a plane or a height grid, not both)")
        return None, _height_grid(s, recorded)
    for key in ("origin", "spacing"):
        if s.has(key):
            s.fail(key, s.values[key], "given only with heights (a height grid's file)")
    values = TERRAIN.read(s, "grade_percent", "cross_slope_percent")
    plane = terrain.Plane(values["grade_percent"] / 100.0, values["cross_slope_percent"] / 100.0)
    steepest = math.degrees(math.atan(math.hypot(plane.grade, plane.cross_slope)))
    if steepest > terrain.MAX_SLOPE_DEG:
        s.fail("grade_percent", values["grade_percent"], f"with cross_slope_percent {values['cross_slope_percent']:g}"
               f" a slope of at most {terrain.MAX_SLOPE_DEG:g} deg (this is {steepest:.1f} deg)")
    return plane, None


def _start_on(grid: terrain.HeightGrid, train: spec.Train, initial: spec.Initial, top: Section) -> None:
    """Every cart's centre of mass at the start on the height grid (the run stops where one leaves it)."""
    from .geometry import cart_points

    heading = [initial.heading]
    for phi in initial.hitch_angles or (0.0,) * (train.n - 1):
        heading.append(heading[-1] - phi)
    for cart, (cx, cy) in zip(train.carts, cart_points(train, initial.x, initial.y, heading)["C"].tolist()):
        if not grid.covers(cx, cy):
            top.fail("initial", top.values.get("initial", {}), f"a start with every cart's centre of mass on the height "
                     f"grid (x in [{grid.xs[0]:g}, {grid.xs[-1]:g}], y in [{grid.ys[0]:g}, {grid.ys[-1]:g}] m; "
                     f"{cart.name}'s is at ({cx:.2f}, {cy:.2f}) m)")


def _height_grid(s: Section, recorded: Optional[dict]) -> terrain.HeightGrid:
    """The height grid of ``terrain.heights``, its file relative to the scene's folder (.csv or
    .npy with origin and spacing, or a GeoTIFF that carries its own), or as a run ``recorded`` it
    (its record's terrain_* texts: no file is opened)."""
    relative = TERRAIN["heights"].read(s)
    where = f"{s.path or 'terrain'}.heights"
    tiff = os.path.splitext(relative)[1].lower() in (".tif", ".tiff")
    for key in ("origin", "spacing"):
        if tiff and s.has(key):
            s.fail(key, s.values[key], "given only with a .csv or .npy grid (a GeoTIFF carries its own)")
    if recorded is not None:
        if not recorded.get("terrain_heights"):
            s.fail("heights", relative, "recorded with the scene (the run's terrain_heights): no file is opened")
        heights = terrain.heights_from_text(recorded["terrain_heights"], where, s.source)
        origin, spacing = _recorded_placement(recorded) if tiff else _placement(s)
        return terrain.grid_from(heights, origin, spacing, where, s.source)
    path = os.path.normpath(os.path.join(os.path.dirname(s.source), relative))
    if tiff:
        from .geotiff import read_geotiff

        if not os.path.isfile(path):
            s.fail("heights", relative, f"a GeoTIFF, relative to the scene's folder (not found: {path})")
        heights, origin, spacing = read_geotiff(path, where, s.source)
        return terrain.grid_from(heights, list(origin), spacing, where, s.source, path)
    origin, spacing = _placement(s)
    return terrain.grid_from(terrain.read_heights(path, where, s.source), origin, spacing, where, s.source, path)


def _placement(s: Section) -> tuple[list, float]:
    """(origin, spacing) of a .csv or .npy grid, as the scene gives them."""
    origin = TERRAIN["origin"].read(s)
    if len(origin) != 2:
        s.fail("origin", s.values["origin"], "two numbers [x, y], m")
    return list(origin), TERRAIN["spacing"].read(s, default=REQUIRED)


def _recorded_placement(recorded: dict) -> tuple[object, object]:
    """(origin, spacing) of a GeoTIFF's grid as a run recorded them (grid_from checks them)."""
    try:
        origin = [float(v) for v in str(recorded.get("terrain_origin", "")).split(",")]
        return origin, float(recorded.get("terrain_spacing", ""))
    except ValueError:
        return recorded.get("terrain_origin"), recorded.get("terrain_spacing")


def _scene(data: dict, source: str, train: Optional[spec.Train] = None, recorded: Optional[dict] = None) -> spec.Scene:
    top = Section(data, "", source, SCENE.keys)
    if train is None:
        train = _scene_train(top)
    else:
        SCENE["train"].read(top)  # still a required field; the train itself is the one given
    plane, grid = _terrain(top, recorded)
    if plane is not None or grid is not None:  # the train on its ground: every level packs its gravity
        train = dataclasses.replace(train, terrain=plane, relief=grid)
    initial = _initial(top, train)
    if grid is not None:
        _start_on(grid, train, initial, top)
    speed = _speed(top)
    ignored = spec.unfollowed_speed(train.traction)
    followed_by = f"(a speed is followed by law {' or '.join(spec.SPEED_LAWS)})"
    if speed is not None and ignored:
        top.fail("speed", top.values["speed"], f"left out for train '{train.name}': its {ignored} {followed_by}")
    fidelity = SCENE["fidelity"].read(top)
    if fidelity == "kinematic" and ignored:  # the kinematic level prescribes the speed (kinematic.py)
        top.fail("fidelity", fidelity, f"another level for train '{train.name}': the kinematic level prescribes "
                 f"the speed, and its {ignored} {followed_by}")
    if fidelity == "slip" and grid is not None:  # levels.make_level refuses it too, at the run
        top.fail("fidelity", fidelity, "the kinematic or dynamic level on a height grid: the slip level takes a "
                 "plane's gravity only (docs/terrain.md)")
    publish_rate = SCENE["publish_rate"].read(top)
    steering, maneuver = _steering(top, train, _speed_at(speed, initial, train.traction))
    integrator = _integrator(top, publish_rate)
    return spec.Scene(
        name=_name(top, source),
        train=train,
        duration=_duration(top, publish_rate, integrator.step or 1.0 / publish_rate),
        initial=initial,
        steering=steering,
        speed=speed,
        integrator=integrator,
        publish_rate=publish_rate,
        maneuver=maneuver,
        fidelity=fidelity,
        needs=_needs(top),
        source=source,
        raw=data,
    )


def _duration(top: Section, publish_rate: float, step: float) -> float:
    """The run's length, s: > 0, and a run of it finite (validate.run_size: ticks and steps)."""
    duration = SCENE["duration"].read(top)
    problem = validate.run_size(duration, publish_rate, step)
    if problem:
        top.fail("duration", top.values["duration"], problem)
    return duration


def _scene_train(top: Section) -> spec.Train:
    """The train named by ``train:``, a path relative to the scene file's folder."""
    relative = SCENE["train"].read(top)
    path = os.path.normpath(os.path.join(os.path.dirname(top.source), relative))
    if not os.path.isfile(path):
        found = "a folder" if os.path.isdir(path) else "not a file" if os.path.exists(path) else "not found"
        top.fail("train", relative, f"a train file, relative to the scene's folder ({found}: {path})")
    return load_train(path)


def load_scene(path: Union[str, os.PathLike]) -> spec.Scene:
    """Read and check a scene file and the train file it names (layout: config/scenes/*.yaml)."""
    return _scene(*read(path))


def load_scene_text(text: str, source: str, train: spec.Train, recorded: Optional[dict] = None) -> spec.Scene:
    """Check a scene given as YAML text with its train given too (a bag records both), and a
    height grid as ``recorded`` (the run record's terrain_heights, terrain_origin and
    terrain_spacing): no file is opened, whatever the scene's ``train:`` or ``terrain.heights`` name."""
    data, source = parse(text, source)
    return _scene(data, source, train, recorded or {})


# --------------------------------------------------------------------------- any file


def load_file(path: Union[str, os.PathLike]) -> Union[spec.Train, spec.Scene]:
    """A train or a scene, told apart by its keys (``carts`` or ``train``)."""
    data, source = read(path)
    if "carts" in data:
        return _train(data, source)
    if "train" in data:
        return _scene(data, source)
    fail("file", f"keys {show(list(data))}", "top level", source, "a train (with carts) or a scene (with train); "
         "mta check also takes fields (boundary), field scenes (field) and sweeps (vary)")


def check_files(paths: Iterable[Union[str, os.PathLike]], also: Optional[Callable] = None,
                load: Callable = load_file) -> int:
    """Check each file, print ``ok: PATH`` or ``error: MESSAGE``; exit code 0, or 2 on a fault.
    ``also(loaded)``: what else a run builds from it (the command's: the robot model's frames),
    raising InputError where it cannot, so check refuses what a run would; what it returns (lines)
    is printed after the ok as ``note: PATH: LINE`` (what a run will not do as the file asks).
    ``load``: the file's reader (the command's: trains and scenes, fields, sweeps)."""
    status = 0
    for path in paths:
        try:
            loaded = load(path)
            notes = also(loaded) if also is not None else None
        except validate.InputError as error:
            print(f"error: {error}", file=sys.stderr)
            status = 2
        else:
            print(f"ok: {path}")
            for note in notes or ():
                print(f"note: {path}: {note}")
    return status
