"""How tightly the train turns and how far it reaches into the headland: what every turn of a plan
is sized from (the model's own steady circles and a simulated turn, not a guessed radius).

The working point P is the implement's: cart m = ``train.implement.cart``, ``d`` = its offset from
the axle B_m forward along the cart's axis. On a steady circle at a held steering psi_1 every point
of a cart turns about the common centre, so P's radius is sqrt(R_Bm^2 + d^2) (R_Bm from
``physics.steady.steady_circle``).

The smallest usable radius is P's at the largest steering psi_1 that

- is at most STEERING_SHARE of the actuator's max_angle (the rest is the tracking controller's
  room to correct), and
- has a steady circle in which every hitch keeps HITCH_MARGIN to both of its jackknife limits
  (the cart's max_hitch_angle, and psi_k = 90 deg: guards.jackknife_margin's two limits).

Both conditions only tighten as psi_1 grows (every radius shrinks with it), so that steering is
found by bisection.

The reach is measured, not estimated: a kinematic run of the train (``run.simulation``) drives
straight with P on the swath's end line at t = 0, then holds that steering (the actuator's lag and
rate limit act) until cart m has turned half a circle, and the reach is the largest distance any
corner of any cart's box (``physics.outline.box_of``, what RViz draws) gets beyond P's start, along
the swath. That turn starts no earlier than a plan's U-turn (whose P leaves the swath on the arc
at once), so it estimates how much headland a turn needs; the closed-loop run measures what the
tracking controller really takes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..physics.outline import box_of
from ..physics.spec import Initial, Scene, Table
from ..physics.steady import SteadyStateError, steady_circle
from ..validate import fail
from .boundary import FieldError

#: share of the actuator's max_angle a planned turn may use
STEERING_SHARE = 0.8
#: rad: what every hitch keeps to each of its jackknife limits in a planned turn (20 deg)
HITCH_MARGIN = math.radians(20.0)
#: Hz: the simulated turn's ticks (its integrator the scene default, rk4 at 0.01 s)
REACH_RATE = 50.0
#: half turns a simulated turn may take at most before it is called a failure (a spiral that never
#: closes: the train's turn is far from steady)
REACH_TURNS = 4.0


@dataclass(frozen=True)
class Turning:
    """The train's own tightest planned turn."""

    steering: float  # psi_1 held, rad (> 0)
    radius: float  # m: the working point's radius, sqrt(R_Bm^2 + d^2)
    axle_radius: float  # m: R_Bm
    tractor_radius: float  # m: R_B1
    margin: float  # rad: the smallest jackknife margin on that circle (inf: no hitch)
    bound: str  # what limits the steering, in words
    cart: int  # m, index of the implement's cart
    offset: float  # d, m


@dataclass(frozen=True)
class Reach:
    """What a simulated U-turn of the train at Turning.steering took."""

    train: float  # m: the farthest outline corner beyond the working point's start, along the swath
    point: float  # m: the working point's own farthest
    speed: float  # m/s the run drove at


def implement_of(train) -> tuple[int, float, float]:
    """(cart index m, offset d, width) of the train's implement; FieldError if it has none."""
    if train.implement is None:
        fail("implement", "(missing)", "given: the working tool (cart, width, offset) a field plan is made for",
             "train", train.source or train.name, FieldError)
    tool = train.implement
    return train.cart_index(tool.cart), float(tool.offset), float(tool.width)


def margin_at(train, steering: float) -> float:
    """The smallest jackknife margin of the steady circle at ``steering`` (rad; inf for one cart),
    or -inf where no steady circle exists."""
    try:
        circle = steady_circle(train, steering)
    except SteadyStateError:
        return -math.inf
    margins = [min(cart.max_hitch_angle - abs(phi), math.pi / 2 - abs(psi))
               for cart, phi, psi in zip(train.carts[1:], circle.hitch_angles, circle.psi[1:])]
    return min(margins, default=math.inf)


def turning(train) -> Turning:
    """The train's tightest planned turn (module docstring)."""
    m, d, _ = implement_of(train)
    top = STEERING_SHARE * train.actuator.max_angle

    def usable(psi: float) -> bool:
        return margin_at(train, psi) >= HITCH_MARGIN

    if usable(top):
        psi, bound = top, f"{STEERING_SHARE:.0%} of the actuator's {math.degrees(train.actuator.max_angle):.4g} deg"
    else:
        low, high = 0.0, top
        if not usable(1e-6):
            fail("max_hitch_angle", "too small", f"more than {math.degrees(HITCH_MARGIN):g} deg on every hitch "
                 "(a planned turn keeps that margin to the jackknife limits)", "train", train.source or train.name,
                 FieldError)
        for _ in range(60):
            mid = 0.5 * (low + high)
            low, high = (mid, high) if usable(mid) else (low, mid)
        psi, bound = low, f"every hitch {math.degrees(HITCH_MARGIN):g} deg from its jackknife limits"
    circle = steady_circle(train, psi)
    return Turning(psi, math.hypot(circle.R_B[m], d), circle.R_B[m], circle.R_B[0], margin_at(train, psi), bound,
                   m, d)


def corners(train, axle: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """(n * 4, 2) the corners of every cart's box with axles B_k ``axle`` (n, 2), headings (n,)."""
    out = []
    for k in range(train.n):
        centre, length, width, _ = box_of(train, k)
        e = np.array([math.cos(heading[k]), math.sin(heading[k])])
        n = np.array([-e[1], e[0]])
        for along in (centre + length / 2, centre - length / 2):
            for across in (width / 2, -width / 2):
                out.append(axle[k] + along * e + across * n)
    return np.array(out)


def turn_reach(train, turn: Turning) -> Reach:
    """Simulate the train's U-turn at ``turn.steering`` (module docstring) and measure its reach."""
    from ..physics.guards import ModelValidityError
    from ..run.simulation import Simulation

    speed = train.traction.set_speed if train.traction.set_speed > 0 else 1.0
    scene = Scene(f"{train.name} headland turn", train, 1e6, Initial(speed=speed), Table((0.0,), (turn.steering,)),
                  Table((0.0,), (speed,)), publish_rate=REACH_RATE, fidelity="kinematic", source=train.source)
    # a few hundred ticks: plain Python costs less than compiling the kernels for them
    sim = Simulation(scene, compiled=False)
    m, d = turn.cart, turn.offset

    def point(out) -> np.ndarray:
        return out.axle[m] + d * np.array([math.cos(out.heading[m]), math.sin(out.heading[m])])

    out = sim.outputs()
    start, heading0 = point(out), float(out.heading[m])
    reach = reach_p = -math.inf
    limit = REACH_TURNS * math.pi * (turn.radius + sum(c.length + abs(c.hitch_offset) for c in train.carts)) / speed
    while True:
        reach = max(reach, float(corners(train, out.axle, out.heading)[:, 0].max() - start[0]))
        reach_p = max(reach_p, float(point(out)[0] - start[0]))
        if out.heading[m] - heading0 >= math.pi:
            return Reach(reach, reach_p, speed)
        if sim.t > limit:
            break
        try:
            sim.advance(turn.steering, speed)
        except ModelValidityError as err:
            fail("train", train.name, f"able to turn at its planned steering {math.degrees(turn.steering):.3g} deg "
                 f"({err})", "", train.source, FieldError)
        out = sim.outputs()
    fail("train", train.name, f"turning half a circle at its planned steering {math.degrees(turn.steering):.3g} deg "
         f"within {limit:.0f} s", "", train.source, FieldError)
