"""Every field of a train and a scene file, declared once: its key, kind, unit, rule, default and
meaning, one :class:`Schema` per mapping of the file. The loader (loader.py) reads each field
through its declaration here, and ``python -m mta_sim_ros.tools.formats`` writes docs/formats.md
from the same tables, so the reference cannot drift from the rules the loader applies.

Units are SI. Angles are in radians, or in degrees under the same key with ``_deg`` appended
(``max_angle_deg: 40``); giving both forms is a fault. Numbers may be ints or floats and must be
finite. Rules that depend on the rest of the file (a step against the publish rate, a steering
angle against the actuator's max_angle) are set where the loader reads the field, and said in
words here (``rule_text``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional

from .. import validate
from ..validate import ANY, POSITIVE, Rule
from . import maneuvers, spec, terrain
from .reader import REQUIRED

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
#: an adaptive run's companion takes a thousandth of rtol (run/accuracy.py), and scipy's solvers no rtol
#: under 100 machine epsilons (2.2e-14): below 1e-10 the companion would not be tighter than the run
RELATIVE_TOLERANCE = _span(1e-10, 1.0, "(its accuracy companion runs at a thousandth of it)")
MANEUVER_PARAM = _magnitude(validate.MAX_DURATION, "")  # s, rad, m/s, m: each manoeuvre checks its own
GRADE = _magnitude(round(100.0 * math.tan(math.radians(terrain.MAX_SLOPE_DEG)), 1), "%")
HITCH_ANGLE = Rule("in (0, pi]", lambda x: 0 < x <= math.pi)
ROLLING_COEFFICIENT = Rule("in [0, 1)", lambda x: 0 <= x < 1)
MAX_STEER = Rule("in (0, pi/2)", lambda x: 0 < x < math.pi / 2)

#: characters of a train's or scene's name (it names the bag of a run: never a path)
NAME_CHARS = 100
TRACTION_LAWS = ("constant", "governor", "prescribed_speed")
FIDELITY_CHOICES = ("auto",) + spec.FIDELITY_LEVELS

# --------------------------------------------------------------------------- fields

NUMBER, NUMBERS, TEXT, FLAG, CHOICE = "number", "list of numbers", "string", "true or false", "choice"
MAPPING, MAPPINGS, SPEED_COMMAND = "mapping", "list of mappings", "number or mapping"
_UNSET = object()


@dataclass(frozen=True)
class Field:
    """One key of a mapping: how it is read (``kind``, ``rule``, ``default``) and what it means.

    ``rule`` is the rule of a number (or of each number of a list); where the rule depends on the
    rest of the file, it is given where the field is read and ``rule_text`` says it in words.
    ``default`` is REQUIRED for a field that must be given; ``default_text`` says a default the
    loader works out. ``also`` says further rules, checked where the field is read. ``schema`` is
    the mapping a MAPPING or MAPPINGS field holds (for the reference).
    """

    key: str
    kind: str
    meaning: str
    unit: str = ""
    rule: Optional[Rule] = None
    default: Any = REQUIRED
    angle: bool = False
    choices: tuple = ()
    rule_text: str = ""
    default_text: str = ""
    also: str = ""
    schema: Optional["Schema"] = None

    def read(self, s, rule: Optional[Rule] = None, default: Any = _UNSET) -> Any:
        """The field's value from the reader.Section ``s``, checked (``rule`` and ``default``
        given here override the declared ones)."""
        rule = rule or self.rule or ANY
        default = self.default if default is _UNSET else default
        if self.kind == NUMBER:
            return s.number(self.key, rule, default)
        if self.kind == NUMBERS:
            return s.numbers(self.key, rule, default)
        if self.kind == TEXT:
            return s.text(self.key, default)
        if self.kind == FLAG:
            return s.flag(self.key, default)
        if self.kind == CHOICE:
            return s.choice(self.key, self.choices, default)
        raise TypeError(f"{self.key}: a {self.kind} is read by the loader's own code")


@dataclass(frozen=True)
class Schema:
    """The fields of one mapping of a file, in the order a fault message lists them."""

    title: str  # what the mapping is (a heading of the reference)
    where: str  # where it sits in the file
    meaning: str
    fields: tuple[Field, ...]
    notes: tuple[str, ...] = ()  # rules across its fields, in words

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(f.key for f in self.fields)

    @property
    def angles(self) -> tuple[str, ...]:
        """The keys that may be given in degrees, as KEY_deg."""
        return tuple(f.key for f in self.fields if f.angle)

    def __getitem__(self, key: str) -> Field:
        return next(f for f in self.fields if f.key == key)

    def read(self, s, *keys: str) -> dict:
        """{key: value} of the fields ``keys`` (default: every field), read in that order."""
        return {key: self[key].read(s) for key in keys or self.keys}


def _rad_deg(angle: float) -> str:
    return f"{angle:.6g} rad ({math.degrees(angle):.6g} deg)"


# --------------------------------------------------------------------------- trains

CART = Schema("A cart", "carts[k]", "One rigid body of the train (docs/model.md, Geometry). Cart 1, the first, is "
              "the tractor; its front point A_1 is the steered front axle's centre.", (
    Field("name", TEXT, "the cart's name: force elements name it, and it names the cart's frames", also="unique "
          "in the train"),
    Field("length", NUMBER, "l_k: the front point A_k (the tractor's steered axle, or the hitch to the cart ahead) "
          "to the rear axle's centre B_k", "m", LENGTH),
    Field("hitch_offset", NUMBER, "a_k: B_k back to the next cart's hitch A_{k+1} (< 0: in front of B_k)", "m",
          OFFSET),
    Field("com_offset", NUMBER, "c_k: B_k forward to the centre of mass C_k", "m", OFFSET),
    Field("mass", NUMBER, "m_k", "kg", MASS),
    Field("yaw_inertia", NUMBER, "J_k, about C_k", "kg m^2", YAW_INERTIA),
    Field("max_hitch_angle", NUMBER, "the largest |hitch angle| th_{k-1} - th_k the coupling in front of this cart "
          "allows; past it the run stops (jackknife); unused for the tractor", "rad", HITCH_ANGLE,
          spec.Cart.max_hitch_angle, angle=True, default_text=_rad_deg(spec.Cart.max_hitch_angle)),
    Field("cornering_stiffness", NUMBER, "C_alpha of each axle of this cart (the tractor's two take it each): the "
          "slip level's lateral force -C_alpha x slip angle; the other levels ignore it", "N/rad", STIFFNESS, None,
          default_text="an estimate: physics/slip.py's CORNERING_COEFFICIENT (per rad) x the static load on the axle"),
    Field("track_width", NUMBER, "the wheels' track, centre to centre across the axle: the rollover margin on a "
          "slope (docs/terrain.md)", "m", LENGTH, None, default_text="not given: no rollover margin"),
    Field("com_height", NUMBER, "the centre of mass's height over the ground", "m", LENGTH, None,
          default_text="not given: no rollover margin", also="given with track_width, or neither"),
    Field("hitch_height", NUMBER, "the height over the ground of the hitch A_{k+1} behind this cart, the drawbar "
          "pull's line of action: the tractor's sets its longitudinal tip margin (docs/terrain.md)", "m", LENGTH, None,
          default_text="not given: no tip margin for a tractor that tows", also="not on the last cart"),
))

LAW = Field("law", CHOICE, "the traction law", choices=TRACTION_LAWS)
TRACTION = {
    "constant": Schema("Traction: law constant", "forces.traction", "F_A1 = force, whatever the speed: "
                       "a scene's speed and the speed controllers command (mta reverse, mta follow and mta field run) "
                       "are refused with it; the node says once that it ignores a speed command.", (
        LAW,
        Field("force", NUMBER, "F_A1, the traction force along v_A1", "N", FORCE),
    )),
    "governor": Schema("Traction: law governor", "forces.traction", "A PI speed governor on V towards the set speed, "
                       "saturated by max_force (adhesion) and max_power / |V|; back-calculation anti-windup.", (
        LAW,
        Field("set_speed", NUMBER, "the speed V is driven to (a scene's speed command overrides it)", "m/s", SPEED),
        Field("max_force", NUMBER, "the largest traction force (adhesion)", "N", MAX_FORCE),
        Field("max_power", NUMBER, "the largest traction power: F_A1 at most max_power / |V|", "W", MAX_POWER),
        Field("kp", NUMBER, "proportional gain", "N per m/s", GAIN),
        Field("ki", NUMBER, "integral gain", "N per m", INTEGRAL_GAIN),
        Field("windup_time", NUMBER, "time constant of the anti-windup", "s", TIME_CONSTANT,
              spec.Traction.windup_time),
    )),
    "prescribed_speed": Schema("Traction: law prescribed_speed", "forces.traction", "V follows the set speed with a "
                               "first-order lag and an acceleration limit; F_A1 comes from inverse dynamics (the "
                               "equation of motion solved for the force).", (
        LAW,
        Field("set_speed", NUMBER, "the speed V follows (a scene's speed command overrides it)", "m/s", SPEED,
              spec.Traction.set_speed),
        Field("response_time", NUMBER, "time constant of the lag", "s", TIME_CONSTANT),
        Field("max_accel", NUMBER, "the largest |V'|", "m/s^2", ACCELERATION, spec.Traction.max_accel),
    )),
}
_CART_NAME = Field("cart", TEXT, "the cart it acts on, at its rear axle B_k", rule_text="the name of a cart of this "
                   "train")
ROLLING = Schema("Rolling resistance", "forces.rolling[i]", "f m_k g at the rear axle B_k of one cart, against its "
                 "motion (smoothed through standstill, smoothing_speed).", (
    _CART_NAME,
    Field("coefficient", NUMBER, "f, dimensionless", "", ROLLING_COEFFICIENT),
))
DRAFT = Schema("Implement draft", "forces.draft[i]", "ASABE D497 draft D = F_i (A + B S + C S^2) W T at B_k of one "
               "cart, against its motion; S is the forward speed in km/h.", (
    _CART_NAME,
    Field("A", NUMBER, "per unit width W and unit depth T", "N per unit", DRAFT_COEFFICIENT),
    Field("B", NUMBER, "the same per km/h", "N per unit per km/h", DRAFT_COEFFICIENT, 0.0),
    Field("C", NUMBER, "the same per (km/h)^2", "N per unit per (km/h)^2", DRAFT_COEFFICIENT, 0.0),
    Field("soil_factor", NUMBER, "F_i, the soil texture factor, dimensionless", "", DRAFT_SIZE, 1.0),
    Field("width", NUMBER, "W: m, or the number of rows or tools", "m", DRAFT_SIZE, 1.0),
    Field("depth", NUMBER, "T: cm (1 for seeding tools)", "cm", DRAFT_SIZE, 1.0),
))
FORCES = Schema("Force elements", "forces", "The force elements of the train, each at a point of a cart.", (
    Field("traction", MAPPING, "traction F_A1 at the tractor's front point A_1, along v_A1", also="its fields "
          "depend on its law: constant, governor or prescribed_speed"),
    Field("rolling", MAPPINGS, "rolling resistances", default=(), default_text="none", schema=ROLLING),
    Field("draft", MAPPINGS, "implement drafts", default=(), default_text="none", schema=DRAFT),
))
_ACTUATOR = spec.Train.actuator
ACTUATOR = Schema("Steering actuator", "steering_actuator", "The tractor's steering angle psi_1 follows the command "
                  "through a first-order lag with rate and angle limits: psi_1' = clip((clip(cmd, +-max_angle) - "
                  "psi_1) / time_constant, +-max_rate). Given, it gives all three fields.", (
    Field("time_constant", NUMBER, "the lag's time constant tau", "s", TIME_CONSTANT),
    Field("max_rate", NUMBER, "the largest |psi_1'|", "rad/s", STEER_RATE, angle=True),
    Field("max_angle", NUMBER, "the largest |psi_1|", "rad", MAX_STEER, angle=True),
))
IMPLEMENT = Schema("Implement", "implement", "The working tool a field plan is made for (mta field): the point "
                   "of one cart that must stay on its swath, and the width of ground it works there.", (
    Field("cart", TEXT, "the cart carrying it", rule_text="the name of a cart of this train"),
    Field("width", NUMBER, "its working width: the swaths' spacing, before overlap", "m", Rule(
        "> 0 and <= 100 m", lambda x: 0 < x <= 100.0)),
    Field("offset", NUMBER, "the working point, from the cart's axle B_k forward along its axis", "m", OFFSET,
          spec.Implement.offset),
))
FUEL = Schema("Fuel", "fuel", "Fuel burnt for traction: specific_consumption x traction power / efficiency, "
              "integrated where the power is positive.", (
    Field("specific_consumption", NUMBER, "the engine's brake specific fuel consumption", "g/kWh", Rule(
        "> 0 and <= 2000 g/kWh", lambda x: 0 < x <= 2000.0)),
    Field("efficiency", NUMBER, "the drive train's, engine to wheels: traction power / engine power", "", Rule(
        "in (0, 1]", lambda x: 0 < x <= 1.0), spec.Fuel.efficiency),
))
TRAIN = Schema("Train file", "top level", "The mechanical scheme (a list of carts) and its force elements: what the "
               "KiDiM method takes as input (config/trains/*.yaml).", (
    Field("name", TEXT, "the train's name", default_text="the file's stem", also=f"at most {NAME_CHARS} printable "
          "characters without / or \\"),
    Field("carts", MAPPINGS, "the carts, tractor first", also="not empty", schema=CART),
    Field("forces", MAPPING, "the force elements", schema=FORCES),
    Field("steering_actuator", MAPPING, "the tractor's steering actuator", default=_ACTUATOR, schema=ACTUATOR,
          default_text=f"time_constant {_ACTUATOR.time_constant:g} s, max_rate {_ACTUATOR.max_rate:g} rad/s, "
                       f"max_angle {_rad_deg(_ACTUATOR.max_angle)}"),
    Field("smoothing_speed", NUMBER, "resistances are smoothed through V = 0 with tanh(v / smoothing_speed)", "m/s",
          SMOOTHING, spec.Train.smoothing_speed),
    Field("gravity", NUMBER, "g", "m/s^2", GRAVITY, spec.GRAVITY),
    Field("lateral_friction", NUMBER, "mu, the tyres' lateral friction on the field's soil: the most lateral "
          "force an axle takes per newton of its normal load (the grip margin, docs/terrain.md)", "", Rule(
              "in (0, 2]", lambda x: 0 < x <= 2.0), None, default_text="not given: no grip margin"),
    Field("implement", MAPPING, "the working tool of field operations", default=None, schema=IMPLEMENT,
          default_text="none: the train plans and works no field"),
    Field("fuel", MAPPING, "fuel per traction energy", default=None, schema=FUEL,
          default_text="none: no fuel is reported"),
))

# --------------------------------------------------------------------------- scenes

STEERING_LIMIT = "within +-max_angle of the train's steering actuator"
INITIAL = Schema("Start pose", "initial", "The train's state at t = 0.", (
    Field("x", NUMBER, "A_1's position", "m", POSITION, 0.0),
    Field("y", NUMBER, "A_1's position", "m", POSITION, 0.0),
    Field("heading", NUMBER, "the tractor's heading th_1 (0: along x, positive: to the left)", "rad", HEADING, 0.0,
          angle=True),
    Field("speed", NUMBER, "V, the signed speed of A_1 (< 0: reversing)", "m/s", SPEED, 0.0),
    Field("steering", NUMBER, "psi_1 (positive: left)", "rad", None, 0.0, angle=True, rule_text=STEERING_LIMIT),
    Field("hitch_angles", NUMBERS, "th_{k-1} - th_k for k = 2..n", "rad", ANY, (), angle=True,
          default_text="straight", also="n - 1 entries (one per hitch) or none; each smaller in size than its cart's "
                                        "max_hitch_angle"),
))
STEERING_TABLE = Schema("Steering table", "steering.table", "The steering command psi_cmd against time, "
                        "piecewise linear, held before the first and after the last entry.", (
    Field("time", NUMBERS, "times", "s", TIME, also="not empty, strictly increasing"),
    Field("angle", NUMBERS, "the steering command at each time (positive: left)", "rad", None, angle=True,
          rule_text=STEERING_LIMIT, also="as many as times"),
))
MANEUVER_PARAMS = Schema("Manoeuvre parameters", "steering.params", "The named manoeuvre's parameters, each with "
                         "a default (see the table of manoeuvres below); its angles may be given in degrees.", (
    Field("PARAM", NUMBER, "a parameter of the manoeuvre", "s, rad, m/s or m", MANEUVER_PARAM,
          default_text="the manoeuvre's", also="the manoeuvre's own rules; speed and wheelbase, left out, are the "
                                               "scene's speed command at t0 and the tractor's length"),
))
STEERING = Schema("Steering", "steering", "The steering command: a table, or a named manoeuvre expanded into one "
                  "when the scene loads.", (
    Field("table", MAPPING, "time and angle lists", schema=STEERING_TABLE, default=None,
          default_text="(this or maneuver)"),
    Field("maneuver", CHOICE, "a named manoeuvre", choices=tuple(maneuvers.MANEUVERS), default=None,
          default_text="(this or table)"),
    Field("params", MAPPING, "the manoeuvre's parameters", default={}, default_text="the manoeuvre's defaults",
          schema=MANEUVER_PARAMS, also="only with maneuver"),
), notes=("exactly one of table and maneuver",
          f"a manoeuvre expands to a table of at most {validate.MAX_TABLE} entries at strictly increasing times"))
SPEED_TABLE = Schema("Speed table", "speed.table", "The speed command against time, piecewise linear, held "
                     "before the first and after the last entry.", (
    Field("time", NUMBERS, "times", "s", TIME, also="not empty, strictly increasing"),
    Field("speed", NUMBERS, "the speed command at each time", "m/s", SPEED, also="as many as times"),
))
SPEED_COMMAND_TABLE = Schema("Speed command", "speed", "Given as a mapping, the speed command holds one field.", (
    Field("table", MAPPING, "time and speed lists", schema=SPEED_TABLE),
))
_INTEGRATOR = spec.Integrator()
INTEGRATOR = Schema("Integrator", "integrator", "How the equations of motion are stepped (docs/accuracy.md).", (
    Field("method", CHOICE, "the fixed-step tableaux of integrate/tableau.py, then scipy's adaptive ones",
          choices=spec.INTEGRATOR_METHODS, default=_INTEGRATOR.method),
    Field("step", NUMBER, "the step of a fixed-step method (the largest step of an adaptive one)", "s", None,
          _INTEGRATOR.step, rule_text=f"in [1/publish_rate / {validate.MAX_STEPS_PER_TICK}, 1/publish_rate] s",
          default_text="a fixed-step method takes the fewest equal steps per tick that meet tolerance; an adaptive "
                       "one steps up to the tick"),
    Field("tolerance", NUMBER, "the largest position error the run may have (every A_k, B_k and the last rear "
          "hitch, against the exact solution): a run states its estimate against it (docs/accuracy.md)", "m",
          POSITIVE, _INTEGRATOR.tolerance),
    Field("rtol", NUMBER, "relative tolerance of the adaptive methods", "", RELATIVE_TOLERANCE, _INTEGRATOR.rtol),
    Field("atol", NUMBER, "absolute tolerance of the adaptive methods", "", TOLERANCE, _INTEGRATOR.atol),
    Field("split_kinks", FLAG, "split the steps where the right-hand side has a kink (the steering rate limit "
          "letting go, a force limit engaging), so each method keeps its order there", default=_INTEGRATOR.split_kinks),
))
_NEED = {"poses": ("the largest distance between the same axle centre (B_k or A_1) over the run", "m"),
         "speed": ("the largest error in V", "m/s"),
         "power": ("the RMS error in traction power N = F_A1 V over the RMS of N", "relative"),
         "hitch_angles": ("the largest error in a hitch angle", "rad")}
NEEDS = Schema("Needs", "needs", "What the scene needs from the simulator: the outputs it uses and the error it "
               "tolerates in each, against the highest fidelity level (slip); fidelity auto takes the cheapest "
               "level predicted to meet them.", tuple(
    Field(key, NUMBER, _NEED[key][0], _NEED[key][1], POSITIVE, None, default_text="not needed")
    for key in spec.Needs.__dataclass_fields__), notes=("at least one field",))
TERRAIN = Schema("Terrain", "terrain", "The ground the train moves on: a plane (its rise per 100 m along the world's x "
                 "and y axes) or a height grid (a .csv or .npy file of heights, or a GeoTIFF). On a plane the scene's positions "
                 "(initial, and every x, y of the run) are measured along the ground, in the plane's own frame; on a "
                 "height grid they are horizontal. The outputs' 3D poses place them in the world (docs/terrain.md).", (
    Field("grade_percent", NUMBER, "a plane's rise per 100 m horizontally along the world's x axis (> 0: uphill to "
          "+x)", "%", GRADE, 0.0),
    Field("cross_slope_percent", NUMBER, "a plane's rise per 100 m horizontally along the world's y axis", "%", GRADE,
          0.0),
    Field("heights", TEXT, "a height grid's file, relative to the scene's folder: .npy, or .csv with one row of "
          "heights (m) a line, rows along +y, columns along +x, or a GeoTIFF in a projected CRS in metres (its "
          "own placement: no origin, spacing)", default=None, default_text="a plane",
          rule_text=f"a grid of finite numbers, at least {terrain.MIN_NODES} x {terrain.MIN_NODES} and at most "
          f"{terrain.MAX_NODES} nodes, at most {terrain.MAX_FILE_BYTES // 2**20} MiB"),
    Field("origin", NUMBERS, "the world (x, y) of the grid's first node (first row, first column)", "m", POSITION,
          (0.0, 0.0), also="two numbers"),
    Field("spacing", NUMBER, "the distance between neighbouring nodes of the grid, along x and y", "m",
          _span(terrain.MIN_SPACING, terrain.MAX_SPACING, "m"), None, default_text="required with heights"),
), notes=(f"the slope at most {terrain.MAX_SLOPE_DEG:g} deg (a grid's between any two neighbouring nodes)",
          "heights with origin and spacing, or grade_percent and cross_slope_percent: not both",
          "on a height grid the train stays on the grid (a run stops where a cart's centre of mass leaves it)"))
SCENE = Schema("Scene file", "top level", "What happens to a train: start pose, steering and speed commands, "
               "duration, integrator (config/scenes/*.yaml).", (
    Field("name", TEXT, "the scene's name: it names the bag of a run (bags/<name>.mcap)",
          default_text="the file's stem", also=f"at most {NAME_CHARS} printable characters without / or \\"),
    Field("train", TEXT, "the train file, relative to the scene file's folder", rule_text="a train file that loads"),
    Field("duration", NUMBER, "the run's length", "s", POSITIVE, also=f"a run of at most {validate.MAX_TICKS:.0e} "
          f"ticks (duration x publish_rate) and {validate.MAX_RUN_STEPS:.0e} integrator steps"),
    Field("initial", MAPPING, "the start pose", default={}, default_text="all 0, hitches straight", schema=INITIAL),
    Field("steering", MAPPING, "the steering command", schema=STEERING),
    Field("speed", SPEED_COMMAND, "the speed command: a number held from t = 0, or {table: {time, speed}}", "m/s",
          SPEED, None, default_text="the traction law's set_speed", schema=SPEED_COMMAND_TABLE,
          also=f"given only for a train whose traction law follows a speed ({' or '.join(spec.SPEED_LAWS)})"),
    Field("integrator", MAPPING, "the integrator", default={}, default_text="rk4, 0.01 s", schema=INTEGRATOR),
    Field("publish_rate", NUMBER, "the rate of ticks: the commands are sampled and the outputs written at this "
          "rate", "Hz", validate.PUBLISH_RATE, spec.Scene.publish_rate),
    Field("fidelity", CHOICE, "the model level: auto takes the cheapest that meets needs (docs/accuracy.md)",
          choices=FIDELITY_CHOICES, default=spec.Scene.fidelity, also="not kinematic for a train whose traction "
          "law is constant (the kinematic level prescribes the speed)"),
    Field("needs", MAPPING, "the outputs the scene needs and their tolerances", default=None,
          default_text="not stated (auto keeps the dynamic level)", schema=NEEDS),
    Field("terrain", MAPPING, "the ground the train moves on: a plane or a height grid", default=None,
          default_text="level ground",
          schema=TERRAIN),
))

#: every mapping of a train file and of a scene file, in the order of the reference
TRAIN_SCHEMAS = (TRAIN, CART, FORCES, *TRACTION.values(), ROLLING, DRAFT, ACTUATOR, IMPLEMENT, FUEL)
SCENE_SCHEMAS = (SCENE, INITIAL, STEERING, STEERING_TABLE, MANEUVER_PARAMS, SPEED_COMMAND_TABLE, SPEED_TABLE,
                 INTEGRATOR, NEEDS, TERRAIN)
