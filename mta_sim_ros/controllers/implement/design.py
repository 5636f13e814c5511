"""The implement-tracking controller: what it is designed from, and its numbers. No ROS.

The working point W is the point ``offset`` m ahead of the implement cart m's axle B_m on its axis
(train.implement). The controller steers the tractor so that W follows the plan's route:

    u = psi_ref(s + lead) - K_g (x - x_ref(s)),   clipped to the actuator's max_angle

- x = (y, th_1 - h_r, phi_2..phi_n, psi): the straight model's state (symbolic/linear.py) in the
  frame of the route at W's projection, h_r the route's heading there (plus pi on a reversed
  stretch: the frame turns with the carts, which point against the travel). Its first entry is
  not measured but made consistent with W's lateral error e: y = e - C[1:] (x - x_ref)[1:], C the
  output row of W's lateral offset (linear.point_row), so that C (x - x_ref) = e.
- K_g: LQR gains from the linear model about straight motion (linear.linearize, exact forward-mode
  derivatives), Q = q_offset C'C + q_heading D_m'D_m + q_hitch sum phi_k^2, R = r (D_m the implement
  cart's heading row): one at the working speed (swaths and headland passes), one at the turn
  speed, one reversing. Reversing, every hitch mode grows (V / l_k): the same design stabilises it
  (controllers/reversing).
- x_ref and psi_ref: the train's pose that keeps W exactly on the route (loop.reference_path):
  the kinematic chain inverted along the whole route before the run, each cart's heading from the
  path of the point it carries (W on the implement cart, its front hitch on the cart ahead, up to
  the tractor, whose front axle's path gives the steering), every heading against W's tangent.
  This is the preview: the tractor turns before the implement gets to a turn, as far ahead as the
  chain puts it, and on a steady arc the pose is the steady circle's (physics/steady.py). The
  feedforward psi_ref is read ``lead`` s of travel ahead of W (the actuator's lag and the held
  tick: tau + tick / 2 by default).
- The error the gain sees is clipped to ``max_error`` (a large offset would ask for more than the
  actuator's angle, and a saturated loop is not the one designed).
- Forward, the command is clipped to the steering whose steady circle keeps every hitch
  ``hitch_margin`` from its jackknife limits (``guarded_steering``): held there, a forward train
  settles on that circle, so no command folds it. Where the route asks for more (a turn tighter
  than the train follows, a change of side at its tightest radius) the working point leaves the
  line for a while and comes back. Reversing, the actuator's max_angle (the gain holds the hitches).

Speeds (the traction law holds them; Settings): the working speed on working stretches (default
the traction law's set speed), ``turn_speed`` in turns and transits, ``reverse_speed`` backwards;
a lower speed ahead is set as far early as the train is long (A_1 to W), and the speed falls to a
cusp as creep + sqrt(2 decel distance) so the train can stop there and change direction. The
feedforward asks psi' = V d psi_ref / ds of the actuator: a tighter turn or a faster one meets its
rate limit sooner.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...field.turning import GUARD_MARGIN, TURN_SPEED, guarded_steering, implement_of
from ...physics.spec import require_speed_law
from ...symbolic.linear import heading_row, linearize, point_row
from ...validate import fail, show


@dataclass(frozen=True)
class Settings:
    """How a field is driven: speeds, the controller's weights and lead, the guards, the steps."""

    work_speed: float | None = None  # m/s on working stretches; None: the traction law's set speed
    turn_speed: float = TURN_SPEED  # m/s in turns and transits (7.2 km/h: the speed the plan's turns are sized for)
    reverse_speed: float = 1.0  # m/s backwards (its size)
    lead: float | None = None  # s of travel ahead of W the feedforward is read; None: tau + tick / 2
    q_offset: float = 1.0  # 1/m^2: W's lateral offset
    q_heading: float = 10.0  # 1/rad^2: the implement cart's heading
    q_hitch: float = 0.1  # 1/rad^2: each hitch angle
    r: float = 1.0  # 1/rad^2: the steering command
    max_error: float = 1.0  # m of W's lateral error the gain sees at most
    hitch_margin: float = GUARD_MARGIN  # rad (10 deg): forward, the steering held at most to the steady circle this
    #                               far from every jackknife limit
    off_route: float = 30.0  # m: W farther than this from the route stops the run (a turn the train
    #                          cannot follow takes W some metres off; past this the run is lost)
    decel: float = 0.5  # m/s^2: the speed a cusp is approached with, creep + sqrt(2 decel distance)
    creep: float = 0.3  # m/s
    tick: float = 0.1  # s: the controller's period (the command is held over it)
    step: float = 0.05  # s: rk4's step (through V = 0 at a cusp the resistances' smoothing is stiff)

    def speeds(self, train) -> tuple[float, float, float]:
        """(working, turn, reversing) speeds, m/s, the last < 0; refused in one line (InputError) where
        the working or turn speed is not > 0 or the reversing speed is 0."""
        work = train.traction.set_speed if self.work_speed is None else self.work_speed
        if not work > 0.0:
            field = "work_speed" if self.work_speed is not None else f"set_speed of train '{train.name}'"
            fail(field, show(work), "> 0 m/s: the working passes are driven forward at it" +
                 (" (the working speed where work_speed is not given)" if self.work_speed is None else ""))
        if not self.turn_speed > 0.0:
            fail("turn_speed", show(self.turn_speed), "> 0 m/s: turns and transits are driven forward at it")
        if not abs(self.reverse_speed) > 0.0:
            fail("reverse_speed", show(self.reverse_speed), "not 0 m/s: the cusps of a turn are backed at it")
        return float(work), float(self.turn_speed), -abs(float(self.reverse_speed))

    def lead_time(self, train) -> float:
        """s: ``lead``, or the actuator's time constant plus half a tick."""
        return train.actuator.time_constant + 0.5 * self.tick if self.lead is None else float(self.lead)


def working_point_reach(train) -> float:
    """m from A_1 back to the working point along the straight train."""
    m, d, _ = implement_of(train)
    carts = train.carts
    return sum(c.length + c.hitch_offset for c in carts[:m]) + carts[m].length - d


# -- the gains --------------------------------------------------------------------------------------


@dataclass
class Gains:
    """u = psi_ref - K (x - x_ref) for one speed; C the working point's row."""

    speed: float
    K: np.ndarray  # (n + 2,)
    closed_loop: np.ndarray  # eigenvalues of A - B K


def design(train, speed: float, settings: Settings = Settings()) -> Gains:
    """The LQR gain about straight motion at ``speed`` (module docstring)."""
    from scipy.linalg import solve_continuous_are

    m, d, _ = implement_of(train)
    model = linearize(train, "straight", speed, exact="dual")
    C, D = point_row(train, m, d), heading_row(train, m)
    Q = settings.q_offset * np.outer(C, C) + settings.q_heading * np.outer(D, D)
    for k in range(2, train.n + 1):
        Q[k, k] += settings.q_hitch
    Q += 1e-9 * np.eye(len(Q))  # the steering angle's own weight: Q positive definite
    R = np.array([[settings.r]])
    P = solve_continuous_are(model.A, model.B, Q, R)
    K = np.linalg.solve(R, model.B.T @ P)[0]
    return Gains(speed, K, np.linalg.eigvals(model.A - model.B @ K[None, :]))


@dataclass
class Controller:
    """Everything the compiled loop reads of the controller (``loop.py``)."""

    settings: Settings
    speeds: tuple  # (working, turn, reversing) m/s
    gains: tuple  # Gains per speed, in that order
    row: np.ndarray  # C: W's lateral offset, (n + 2,)
    lead: float  # s
    forward_angle: float  # rad: the largest steering forward (``hitch_margin``)
    early: float  # m: a lower speed ahead is set this far before it (A_1 to W along the train)
    cart: int
    offset: float
    width: float

    @property
    def K(self) -> np.ndarray:
        """(3, n + 2): the gains' rows."""
        return np.array([g.K for g in self.gains])


def controller(train, settings: Settings = Settings()) -> Controller:
    """The controller of ``train``'s implement under ``settings``; a train that cannot follow its
    speeds (spec.require_speed_law) is refused."""
    m, d, width = implement_of(train)
    require_speed_law(train, "the implement controller")
    speeds = settings.speeds(train)
    gains = tuple(design(train, v, settings) for v in speeds)
    return Controller(settings, speeds, gains, point_row(train, m, d), settings.lead_time(train),
                      guarded_steering(train, settings.hitch_margin), working_point_reach(train), m, d, width)
