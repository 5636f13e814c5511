"""The validated description of a train and a scene: immutable data, no behaviour.

A :class:`Train` is the mechanical scheme (a list of carts) plus the lists of force elements,
exactly what the KiDiM method takes as input (MODEL.md). A :class:`Scene` says what happens to a
train: start pose, steering and speed inputs, duration and integrator. Both are frozen: the
changing state lives in a numpy array (``dynamics.StateLayout``), as MuJoCo splits model from data.

Symbols (MODEL.md):
    length        l_k  distance from the front point A_k to the rear axle centre B_k, m (> 0)
    hitch_offset  a_k  distance from B_k back to the next hitch A_{k+1}, m (< 0: in front of B_k)
    com_offset    c_k  distance from B_k forward to the centre of mass C_k, m
    mass          m_k  kg;  yaw_inertia  J_k  about C_k, kg m^2

These classes are built by ``loader.py`` from YAML, every field read through its declaration in
``schema.py``; that is where every rule is checked.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

from .terrain import HeightGrid, Plane

GRAVITY = 9.80665  # m/s^2, standard gravity


@dataclass(frozen=True)
class Cart:
    """One rigid body of the train. Cart 1 is the tractor; A_1 is its steered front axle centre."""

    name: str
    length: float  # l_k, m
    hitch_offset: float  # a_k, m
    com_offset: float  # c_k, m
    mass: float  # m_k, kg
    yaw_inertia: float  # J_k, kg m^2
    # Largest |hitch angle| th_{k-1} - th_k the coupling in front of this cart allows, rad.
    # Past it the run stops (jackknife). Unused for the tractor.
    max_hitch_angle: float = math.radians(90.0)
    # Lateral tyre cornering stiffness C_alpha of each axle of this cart, N/rad: the slip level's
    # lateral force F = -C_alpha * slip angle (the tractor has two axles, A_1 and B_1, each with this
    # value; a trailer one, at B_k). None = the estimate of ``model/slip.py``: CORNERING_COEFFICIENT
    # (per rad) times the static load on that axle. The kinematic and dynamic levels ignore it.
    cornering_stiffness: Optional[float] = None
    # The wheels' track (centre to centre across the axle) and the centre of mass's height over the
    # ground, m: the static rollover margin on a slope (terrain.rollover_margin). None: not reported.
    track_width: Optional[float] = None
    com_height: Optional[float] = None
    # The height over the ground of the hitch A_{k+1} behind this cart, m: the drawbar pull's line
    # of action. The tractor's sets its longitudinal tip margin (terrain.tip_margin). None: not given.
    hitch_height: Optional[float] = None


@dataclass(frozen=True)
class Traction:
    """Traction force F_A1 at the tractor's front point A_1, along v_A1 (MODEL.md, force laws).

    law = "constant":          F_A1 = force.
    law = "governor":          PI speed governor on V towards the set speed, saturated by
                               max_force (adhesion) and max_power / |V|; back-calculation
                               anti-windup with time constant ``windup_time``.
    law = "prescribed_speed":  V follows the set speed with a first-order lag ``response_time``
                               and acceleration limit ``max_accel``; F_A1 comes from inverse
                               dynamics (the equation of motion solved for the force).
    """

    law: str
    force: float = 0.0  # N, constant law
    set_speed: float = 0.0  # m/s, default set-point (a scene's speed overrides it)
    max_force: float = math.inf  # N
    max_power: float = math.inf  # W
    kp: float = 0.0  # N per m/s
    ki: float = 0.0  # N per m (per m/s per s)
    windup_time: float = 1.0  # s
    response_time: float = 0.5  # s, prescribed_speed
    max_accel: float = math.inf  # m/s^2, prescribed_speed


#: the traction laws that drive V to a speed command; the constant law holds F_A1 = force whatever the
#: speed, so a speed it is given would be ignored (``unfollowed_speed``)
SPEED_LAWS = ("governor", "prescribed_speed")


def unfollowed_speed(traction: Traction) -> str:
    """'' when ``traction`` follows a speed command (a scene's speed table, a speed topic, a
    controller's speed: SPEED_LAWS); else what it does instead, for the one line that refuses or
    reports such a command (docs/formats.md, "Traction")."""
    if traction.law in SPEED_LAWS:
        return ""
    return f"traction law {traction.law} holds F_A1 = {traction.force:g} N whatever the speed"


def require_speed_law(train: Train, commander: str) -> None:
    """Refuse (validate.InputError, one line) ``train`` for ``commander`` (a controller that commands
    a speed: "mta reverse", "the implement controller") where its traction law would ignore that speed."""
    from ..validate import fail, show

    ignored = unfollowed_speed(train.traction)
    if ignored:
        fail("forces.traction.law", show(train.traction.law), f"{' or '.join(SPEED_LAWS)}: {commander} commands a "
             f"speed, and its {ignored}", source=train.source or train.name)


@dataclass(frozen=True)
class Rolling:
    """Rolling resistance f m g at the rear axle B_k of one cart, against v_Bk."""

    cart: str
    coefficient: float  # f, dimensionless


@dataclass(frozen=True)
class Draft:
    """Implement draft at B_k of one cart, ASABE D497: D = F_i (A + B S + C S^2) W T.

    S is the forward speed in km/h, W the width (m, or number of rows/tools), T the depth in cm
    (1 for seeding tools), F_i the dimensionless soil texture factor. A, B, C in N per unit width
    per unit depth (per (km/h) and (km/h)^2 for B and C).
    """

    cart: str
    A: float
    B: float = 0.0
    C: float = 0.0
    soil_factor: float = 1.0
    width: float = 1.0
    depth: float = 1.0


@dataclass(frozen=True)
class Actuator:
    """Steering actuator: psi_1' = clip((clip(cmd, +-max_angle) - psi_1) / time_constant, +-max_rate)."""

    time_constant: float  # s
    max_rate: float  # rad/s
    max_angle: float  # rad


@dataclass(frozen=True)
class Implement:
    """The working tool a field plan is made for: a point of one cart that must stay on its swath,
    and the width of ground it works there (the field room's plans and coverage)."""

    cart: str  # the cart carrying it
    width: float  # m, working width
    offset: float = 0.0  # m, the working point from the cart's axle B_k forward along its axis


@dataclass(frozen=True)
class Fuel:
    """Fuel burnt for traction: specific_consumption (g/kWh, of the engine) x traction power /
    efficiency (the drive train's, engine to wheels), integrated over positive power."""

    specific_consumption: float  # g/kWh
    efficiency: float = 1.0  # traction power / engine power


@dataclass(frozen=True)
class Train:
    name: str
    carts: tuple[Cart, ...]
    traction: Traction
    rolling: tuple[Rolling, ...] = ()
    draft: tuple[Draft, ...] = ()
    actuator: Actuator = Actuator(time_constant=0.2, max_rate=0.6, max_angle=math.radians(40.0))
    gravity: float = GRAVITY
    # Resistances are smoothed through V = 0 with tanh(v / smoothing_speed), m/s.
    smoothing_speed: float = 0.05
    # mu of the tyres' lateral friction on the soil: the grip margin of each no-slip axle
    # (loads.grip_margins). None: not given, no grip margin.
    lateral_friction: Optional[float] = None
    implement: Optional[Implement] = None  # the working tool of field operations (None: no field work)
    fuel: Optional[Fuel] = None  # fuel per traction energy (None: fuel not reported)
    source: str = ""  # the file it came from, for messages
    # the plane the train moves in (a scene's terrain; None: the level): x, y are along it
    terrain: Optional[Plane] = None
    # the height grid the train moves on (a scene's terrain; None: none): x, y are horizontal
    relief: Optional[HeightGrid] = None

    @property
    def n(self) -> int:
        return len(self.carts)

    def cart_index(self, name: str) -> int:
        for i, cart in enumerate(self.carts):
            if cart.name == name:
                return i
        raise KeyError(name)


@dataclass(frozen=True)
class Table:
    """A piecewise-linear function of time, held constant outside [time[0], time[-1]]."""

    time: tuple[float, ...]
    value: tuple[float, ...]


@dataclass(frozen=True)
class Initial:
    x: float = 0.0  # m, A_1
    y: float = 0.0  # m, A_1
    heading: float = 0.0  # rad, tractor heading th_1
    speed: float = 0.0  # m/s, V (signed speed of A_1)
    steering: float = 0.0  # rad, psi_1
    hitch_angles: tuple[float, ...] = ()  # rad, th_{k-1} - th_k for k = 2..n; empty = straight


#: every integrator a scene may name: the fixed-step tableaux of integrate/tableau.py, then scipy's
INTEGRATOR_METHODS = ("euler", "heun", "ralston", "kutta3", "rk4", "rk38", "RK45", "DOP853", "LSODA", "Radau", "BDF")


@dataclass(frozen=True)
class Integrator:
    method: str = "rk4"  # one of INTEGRATOR_METHODS
    # s, fixed-step methods (the largest step for adaptive ones); None: a fixed-step method takes
    # the fewest equal steps per tick that meet ``tolerance``, an adaptive one steps up to the tick
    step: Optional[float] = None
    rtol: float = 1e-8  # adaptive methods
    atol: float = 1e-10  # adaptive methods
    # split steps where the right-hand side has a kink (the steering rate limit letting go, a force
    # limit engaging): each method keeps its order there (integrate/steppers.py)
    split_kinks: bool = True
    # m: the largest position error the run may have (run/accuracy.py); every run states its own
    # estimate against it, and a fixed-step run given no step takes the fewest steps that meet it
    tolerance: float = 1e-6


FIDELITY_LEVELS = ("kinematic", "dynamic", "slip")  # cheapest first; see fidelity.py


@dataclass(frozen=True)
class Needs:
    """What a scene needs from the simulator: the outputs it uses and the error it tolerates in
    each, against the highest fidelity level (slip). None = that output is not needed.

    poses         m: largest distance between the same axle centre B_k (or A_1) over the run
    speed         m/s: largest error in V
    power         relative: RMS error in traction power N = F_A1 V over the RMS of N
    hitch_angles  rad: largest error in a hitch angle
    """

    poses: Optional[float] = None
    speed: Optional[float] = None
    power: Optional[float] = None
    hitch_angles: Optional[float] = None

    def asked(self) -> dict:
        """{output: tolerance} of the outputs needed."""
        return {k: v for k, v in self.__dict__.items() if v is not None}


@dataclass(frozen=True)
class Scene:
    name: str
    train: Train
    duration: float  # s
    initial: Initial
    steering: Table  # rad against s (named manoeuvres are expanded into a table when loaded)
    speed: Optional[Table] = None  # m/s against s; None = the traction law's set_speed
    integrator: Integrator = Integrator()
    publish_rate: float = 50.0  # Hz: the command is sampled and outputs written at this rate
    maneuver: str = ""  # name of the manoeuvre the steering table came from, if any
    fidelity: str = "auto"  # auto | kinematic | dynamic | slip (fidelity.py chooses for auto)
    needs: Optional[Needs] = None  # None: not stated (auto then keeps the article's dynamic model)
    source: str = ""  # the file it came from
    raw: dict = field(default_factory=dict, compare=False, hash=False)  # the YAML as read

    def input_files(self) -> tuple[str, ...]:
        """The files a run of this scene reads: the scene's, its train's and a height grid's (what no
        output of the run may overwrite)."""
        relief = self.train.relief
        files = (self.source, self.train.source, relief.file if relief is not None else "")
        return tuple(f for f in files if f)
