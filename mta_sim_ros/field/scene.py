"""A field scene: a field and how it is to be worked, in one YAML file (config/fieldwork/). What
``mta field run`` takes in place of a bare field, and what a sweep's ``scenes:`` may list beside the
manoeuvre scenes (a field is a scene kind: the sweep varies its plan's options as factors,
``scene.plan.angle_deg``, beside the train's fields)::

    name: irregular_seeding             # default: the file's stem
    field: ../fields/irregular.yaml     # a field file (GeoJSON or YAML), relative to this file
    plan:                               # the plan's options (PlanOptions); every one optional
      angle_deg: 0                      # the swaths' direction (angle in rad); left out: the angle
                                        # that minimises turns
      overlap: 0.0                      # share of the width neighbouring swaths overlap
      headlands: 3                      # headland rings; left out: the field's own
      route: auto                       # auto | boustrophedon | skip
      turn: auto                        # auto | u | bulb | fishtail
      work_headlands: true              # the headland rings are worked, after the swaths
    drive:                              # how it is driven (controllers/implement Settings)
      work_speed: 3.0                   # m/s on working passes; left out: the train's set speed
      turn_speed: 2.0                   # m/s in turns and transits

The train is not named here: ``mta field run`` takes it with --train, a sweep from its scheme, and
the swaths' width is its implement's. Every field is read through its declaration (FIELD_SCENE,
PLAN, DRIVE: the schema of docs/formats.md) and a fault is one line (FieldError, exit code 2).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

from .. import validate
from ..physics.reader import Section, SpecError
from ..physics.schema import CHOICE, FLAG, MAPPING, NUMBER, TEXT, Field, Schema
from ..validate import Rule
from .boundary import MAX_HEADLANDS, Field as FieldShape, FieldError, load_field
from .types import ROUTES, TURNS, PlanOptions

SPEED = Rule("in (0, 20] m/s", lambda v: 0.0 < v <= 20.0)
OVERLAP = Rule("in [0, 0.5)", lambda v: 0.0 <= v < 0.5)
ANGLE = Rule("within +-2 pi rad (+-360 deg)", lambda v: abs(v) <= 2.0 * math.pi)
HEADLANDS = Rule(f"a whole number in [0, {MAX_HEADLANDS}]", lambda v: v == int(v) and 0 <= v <= MAX_HEADLANDS)

PLAN = Schema("Field scene: plan", "plan", "How the field is planned (mta field plan's options); every field "
              "optional.", (
    Field("angle", NUMBER, "the swaths' direction, counterclockwise from east (+x)", "rad", ANGLE, None, angle=True,
          default_text="the angle that minimises the turns"),
    Field("overlap", NUMBER, "share of the working width neighbouring swaths overlap", "", OVERLAP,
          PlanOptions.overlap),
    Field("headlands", NUMBER, "headland rings along the boundary and round each obstacle", "", HEADLANDS, None,
          default_text="the field's own (its file's headlands), more where the turns need them"),
    Field("route", CHOICE, "the order of the swaths", choices=ROUTES, default=PlanOptions.route),
    Field("turn", CHOICE, "the kind of a headland turn between swaths closer than the narrowest U (a U "
          "wherever one fits; auto: a bulb there, u: a U tighter than the train follows)", choices=TURNS,
          default=PlanOptions.turn),
    Field("work_headlands", FLAG, "the headland rings are worked, after the swaths", default=PlanOptions.work_headlands),
))
DRIVE = Schema("Field scene: drive", "drive", "How the field is driven (the implement-tracking controller's "
               "speeds); every field optional.", (
    Field("work_speed", NUMBER, "speed on working passes", "m/s", SPEED, None,
          default_text="the traction law's set speed"),
    Field("turn_speed", NUMBER, "speed in turns and transits", "m/s", SPEED, 2.0),
))
FIELD_SCENE = Schema("Field scene file", "top level", "A field and how it is to be worked (config/fieldwork/*.yaml): "
                     "what mta field run takes in place of a field, and what a sweep's scenes may list.", (
    Field("name", TEXT, "the scene's name", default_text="the file's stem", also="at most 100 printable characters "
          "without / or \\, not . or .."),
    Field("field", TEXT, "the field file (GeoJSON in WGS84, or YAML in local metres), relative to this file"),
    Field("plan", MAPPING, "how the field is planned", default=None, schema=PLAN, default_text="every option's default"),
    Field("drive", MAPPING, "how it is driven", default=None, schema=DRIVE, default_text="every setting's default"),
))


@dataclass(frozen=True)
class FieldScene:
    """A field with how it is to be worked; the width comes from the train's implement."""

    name: str
    field: FieldShape
    plan: dict = field(default_factory=dict)  # PlanOptions' fields but width
    drive: dict = field(default_factory=dict)  # Settings' work_speed, turn_speed
    source: str = ""

    def options(self, train) -> PlanOptions:
        """The plan's options for ``train`` (its implement's width)."""
        return PlanOptions(width=train.implement.width, **self.plan)


def is_field_scene(data: object) -> bool:
    """Whether a scene file's mapping is a field scene (it names a ``field``)."""
    return isinstance(data, dict) and "field" in data


def load_field_scene(path) -> FieldScene:
    """The field scene of a YAML file, checked (with its field file)."""
    return field_scene_from_data(validate.read_mapping(path, FieldError), str(path))


def load_field_or_scene(path) -> FieldScene:
    """A field scene file, or a bare field file as a scene of default options (named after it)."""
    source = str(path)
    if os.path.splitext(source)[1].lower() in (".yaml", ".yml"):
        data = validate.read_mapping(path, FieldError)
        if is_field_scene(data):
            return field_scene_from_data(data, source)
    field = load_field(path)
    return FieldScene(field.name, field, {}, {}, source)


def field_scene_from_data(data: dict, source: str) -> FieldScene:
    """A field scene given as the mapping its file reads to (a sweep's scheme: the base file with
    fields changed); ``source`` names it in messages and is the folder ``field`` is relative to."""
    try:
        top = Section(data, "", source, FIELD_SCENE.keys)
        name = FIELD_SCENE["name"].read(top, default=os.path.splitext(os.path.basename(source))[0])
        if len(name) > 100 or not name.isprintable() or any(c in name for c in "/\\") or name in (".", ".."):
            top.fail("name", name, "a name of at most 100 printable characters without / or \\, not . or ..")
        relative = FIELD_SCENE["field"].read(top)
        plan = _read(top, "plan", PLAN)
        drive = _read(top, "drive", DRIVE)
    except SpecError as err:
        raise FieldError(str(err)) from None
    if "headlands" in plan and plan["headlands"] is not None:
        plan["headlands"] = int(plan["headlands"])
    path = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(source)), relative))
    if not os.path.isfile(path):
        validate.fail("field", validate.show(relative), f"a field file, relative to the scene's folder (not found: "
                      f"{path})", "top level", source, FieldError)
    return FieldScene(name, load_field(path), plan, drive, source)


def _read(top: Section, key: str, schema: Schema) -> dict:
    """The fields of the ``key`` mapping that are given (the others keep their defaults downstream)."""
    if not top.has(key):
        return {}
    s = top.section(key, schema.keys, schema.angles)
    return {f.key: f.read(s) for f in schema.fields if s.has(f.key)}

