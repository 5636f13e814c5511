"""Backing a train up a straight line: a state-feedback gain from the linear model, and the closed
loop run on the simulator. No ROS (reverse_node.py runs the same controller, :class:`Reverser`, as
the ROS node of ``mta reverse``).

Reversing, every hitch angle grows at V / l_k (linear.py: the open loop is unstable). The
controller steers the tractor so that the last cart's axle B_n follows the line y = 0 (the train
pointing along +x, driving towards -x): with x = (y, th_1, phi_2..phi_n, psi) the linear model's
state about straight motion at the speed V < 0 and u the steering command,

    u = -K x,   K = R^-1 B^T P,   P solving A^T P + P A - P B R^-1 B^T P + Q = 0   (LQR, scipy)

with Q = q_offset C^T C + q_hitch sum phi_k^2 + q_heading th_n^2, C x = y_Bn the last axle's lateral
offset to first order (y_Bn = y - sum of each segment's length times its heading: A_1 to B_1, B_k
to A_{k+1}, A_k to B_k), R = r. The gain sees the last axle at most MAX_ERROR from the line (the
line moved towards the train by the rest), and the command is clipped to the actuator's
max_angle; where the steering the loop asks for still passes the actuator's angle or rate limit
the train folds (python -m benchmarks reversing says where). ``design`` refuses, in one line with
the reason, a train and speed whose loop with those limits folds or does not settle
(envelope.unheld) from a start from which the dynamic level's run fails too (unheld_on_both);
``held_design`` tries gentler weights next (LADDER: the steering's rate
weighed in the cost as well, r u^2 + rate psi'^2), the first the check holds and the dynamic level
holds from the same start, which is what ``mta reverse`` takes when it is given no weight.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...physics.spec import require_speed_law
from ...symbolic.linear import heading_row as cart_heading_row
from ...symbolic.linear import linearize, point_row

#: m: the largest lateral error of the last axle the gain is shown (farther away, the line is
#: moved towards the train by the difference): the linear gain's steering for a large offset would
#: pass the actuator's angle, and the train fold
MAX_ERROR = 0.5


@dataclass
class Gains:
    speed: float
    K: np.ndarray  # 1 x (n + 2): u = -K x
    states: list
    closed_loop: np.ndarray  # eigenvalues of A - B K
    weights: dict
    C: np.ndarray  # the last axle's lateral offset, C x
    max_error: float = MAX_ERROR

    def command(self, x: np.ndarray, max_angle: float) -> float:
        """u = -K x clipped to the actuator's max_angle, x taken with the last axle at most
        ``max_error`` from the line (x's lateral offset moved so)."""
        offset = float(self.C @ x)
        if abs(offset) > self.max_error:
            x = x.copy()
            x[0] -= offset - math.copysign(self.max_error, offset)
        return float(np.clip(-(self.K @ x)[0], -max_angle, max_angle))


def last_axle_row(train) -> np.ndarray:
    """C with C x = the last axle's lateral offset to first order, x = (y, th_1, phi_2..phi_n, psi)."""
    return point_row(train, train.n - 1)


def heading_row(train) -> np.ndarray:
    """D with D x = th_n, the last cart's heading."""
    return cart_heading_row(train, train.n - 1)


def design(train, speed: float = -1.0, q_offset: float = 1.0, q_hitch: float = 10.0, q_heading: float = 10.0,
           r: float = 1.0, rate: float = 0.0, check: bool = True) -> Gains:
    """The LQR gain for backing ``train`` along a straight line at ``speed`` (< 0); ``rate`` > 0 weighs
    the steering's rate too, psi' = (u - psi) / tau (the actuator's, unsaturated): the cost's
    r u^2 + rate psi'^2, a cross term of u and psi. Refused (validate.InputError, one line): a train
    whose traction law ignores the speed (spec.require_speed_law), and with ``check`` one whose loop
    with the actuator's limits folds or does not settle from a start the controller is made for, on
    the kinematic check and the dynamic level both (unheld_on_both)."""
    from scipy.linalg import solve_continuous_are

    require_speed_law(train, "the reversing controller")
    if not (math.isfinite(speed) and speed < 0.0):
        from ...validate import fail, show

        fail("speed", show(speed), "a number < 0 m/s: the reversing controller backs the train up")

    model = linearize(train, "straight", speed)
    C, D = last_axle_row(train), heading_row(train)
    Q = q_offset * np.outer(C, C) + q_heading * np.outer(D, D)
    for k in range(2, train.n + 1):
        Q[k, k] += q_hitch
    Q += 1e-9 * np.eye(len(Q))  # the steering angle's own weight: Q positive definite
    R = np.array([[r]])
    if rate > 0.0:
        w = rate / train.actuator.time_constant ** 2
        Q[-1, -1] += w
        R += w
        N = np.zeros((len(Q), 1))
        N[-1, 0] = -w
        P = solve_continuous_are(model.A, model.B, Q, R, s=N)
        K = np.linalg.solve(R, model.B.T @ P + N.T)
    else:
        P = solve_continuous_are(model.A, model.B, Q, R)
        K = np.linalg.solve(R, model.B.T @ P)
    closed = np.linalg.eigvals(model.A - model.B @ K)
    weights = {"q_offset": q_offset, "q_hitch": q_hitch, "q_heading": q_heading, "r": r}
    gains = Gains(speed, K, model.states, closed, weights | ({"rate": rate} if rate > 0.0 else {}), C)
    if check:
        refuse(train, gains, unheld_on_both(train, gains))
    return gains


#: the weights ``held_design`` tries after the default ones, in order: (q_hitch = q_heading, r, rate), a
#: gentler command each step (the steering's rate weighed, the hitches less). A search against the
#: saturated loop, which the linear design does not see, not a design that has the limits in it
#: (benchmarks/reversing.md, the envelope)
LADDER = tuple((q, 1e-3, rate) for rate in (0.01, 0.1, 1.0, 10.0) for q in (10.0, 1.0, 0.1))


def held_design(train, speed: float = -1.0) -> Gains:
    """The first gain that holds ``train`` at ``speed``: the default weights where they are not refused
    (unheld_on_both), else the first of LADDER's that it holds and that hold on the dynamic level
    from the same start as well (``holds_on_dynamic``: gentle gains near the edge of what they
    hold can fold there); refused in one line with the default's reason when none does."""
    from .envelope import unheld

    first = design(train, speed, check=False)
    why = unheld_on_both(train, first)
    if not why:
        return first
    for q, r, rate in LADDER:
        gains = design(train, speed, q_hitch=q, q_heading=q, r=r, rate=rate, check=False)
        if not unheld(train, gains) and holds_on_dynamic(train, gains):
            return gains
    refuse(train, first, why, f" (nor with any of the {len(LADDER)} gentler weights tried)")
    return first  # not reached


def unheld_on_both(train, gains: Gains) -> str:
    """'' when the loop of ``gains`` holds ``train``; else why not, from the first of the check's starts
    (envelope.patterns) where the kinematic check fails (envelope.unheld_from) and the dynamic level's
    run from the same start, envelope.HORIZON m back, fails as well (envelope.run_holds): a refusal is
    a case the loop, run on the dynamic level, really cannot hold. The check alone is cautious at
    the edge (benchmarks/reversing.md: a 3-cart train whose kinematic loop folds after 30 m, held by
    the dynamic level); the dynamic run costs a fraction of a second and runs only where the check
    fails."""
    from .envelope import HORIZON, described, patterns, run_holds, start_scene, unheld_from

    for pattern in patterns(train):
        why = unheld_from(train, gains, pattern)
        if why:
            run = reverse(start_scene(train, gains.speed, pattern=pattern), gains, HORIZON)
            if not run_holds(run, train.n):
                return f"{described(train, pattern)}: {why}; on the dynamic level {failure(run)}"
    return ""


def failure(run: ReverseRun) -> str:
    """How a run that envelope.run_holds does not hold ended, in a clause."""
    from .envelope import degrees

    if run.stopped:  # (a train that went forward first has reversed nothing)
        return f"it stops after {max(run.distance, 0.0):.3g} m: {run.stopped.split(';')[0]}"  # the guard's first clause
    end = run.trace[-1] if len(run.trace) else np.zeros(4)
    hitches = end[3:-1]
    bent = f", a hitch at {degrees(max(abs(phi) for phi in hitches))} deg" if len(hitches) else ""
    return f"it ends {abs(end[2]):.2f} m off the line{bent}"


def holds_on_dynamic(train, gains: Gains) -> bool:
    """The loop of ``gains`` run on the dynamic level from each of the check's starts
    (envelope.start_scene), envelope.HORIZON m back, held as the check holds its own loop (envelope.run_holds): what
    held_design asks of gentler weights besides the check (near the edge of what they hold, the
    dynamic level's inertia and speed can fold a train the kinematic loop keeps:
    benchmarks/reversing.md)."""
    from .envelope import HORIZON, patterns, run_holds, start_scene

    return all(run_holds(reverse(start_scene(train, gains.speed, pattern=p), gains, HORIZON), train.n)
               for p in patterns(train))


def refuse(train, gains: Gains, why: str, more: str = "") -> None:
    """Refuse (validate.InputError), in one line with ``why`` (unheld_on_both's reason; nothing when
    it is '') and ``more``, a train and speed the loop of ``gains`` cannot hold from one of the
    check's nominal starts."""
    from ...validate import fail, show
    from .envelope import START_OFFSET

    if why:
        of = f" ({train.source})" if train.source else ""
        fail("speed", show(gains.speed), f"one the reversing loop holds for train '{train.name}'{of} (its kinematic "
             f"loop with the actuator's angle and rate limits, then the dynamic level, from its nominal starts "
             f"{START_OFFSET:g} m off the line) {why}{more}")


def state_of(out) -> np.ndarray:
    """x = (y, th_1, phi_2..phi_n, psi) of an Outputs sample: A_1's y, the headings, the hitch
    angles, the applied steering angle."""
    return np.array([out.front[0][1], out.heading[0], *out.hitch_angle, out.steering])


@dataclass
class ReverseRun:
    distance: float  # m reversed by the last axle (along -x)
    max_error: float  # m, largest |y_Bn| after the settling distance
    rms_error: float
    max_hitch_deg: float
    max_steering_deg: float
    stopped: str  # "" or why the run stopped (jackknife)
    saturated: float  # share of ticks the command hit max_angle
    trace: np.ndarray  # t, x_Bn, y_Bn, hitch angles..., steering


def _run(distance: float, rows: list, errors: list, stopped: str, saturated: int, n: int) -> ReverseRun:
    """A ReverseRun of a closed loop's trace rows (t, B_n x, y, hitch angles, steering) and errors."""
    trace = np.array(rows) if rows else np.zeros((0, 3 + n))
    e = np.abs(np.array(errors)) if errors else np.array([math.nan])
    return ReverseRun(
        distance=distance, max_error=float(e.max()), rms_error=float(np.sqrt(np.mean(e ** 2))),
        max_hitch_deg=math.degrees(float(np.max(np.abs(trace[:, 3:3 + n - 1])))) if len(trace) and n > 1 else 0.0,
        max_steering_deg=math.degrees(float(np.max(np.abs(trace[:, -1])))) if len(trace) else 0.0,
        stopped=stopped, saturated=saturated / max(len(rows), 1), trace=trace)


def reverse(scene, gains: Gains, distance: float, settle: float = 0.0, offset: float = 0.0) -> ReverseRun:
    """Back the scene's train along y = 0 from its start (``offset`` m to the side) until its last
    axle has reversed ``distance`` m, the gain steering each tick on the state after the last."""
    def shift(sim):
        sim.y[sim.model.layout.y] += offset

    return drive(scene, gains, state_of, lambda before, after: before.axle[-1][0] - after.axle[-1][0],
                 lambda out: out.axle[-1][1], distance, settle, shift)


def drive(scene, gains, state, progress, error, distance: float, settle: float, setup=None) -> ReverseRun:
    """The closed loop on the simulator: each tick steers ``gains.command(state(outputs))`` at
    ``gains.speed``; ``progress(before, after)`` is the distance a tick adds (m), ``error(outputs)`` the
    last axle's error, kept after ``settle`` m; until ``distance`` m, a guard stops the run (its reason
    kept), or the train makes no headway."""
    from ...integrate import IntegrationError
    from ...physics.guards import ModelValidityError
    from ...run.simulation import Simulation

    sim = Simulation(scene)
    if setup is not None:
        setup(sim)
    max_angle = scene.train.actuator.max_angle
    out = sim.outputs()
    travelled, rows, errors, stopped, saturated = 0.0, [], [], "", 0
    while travelled < distance:
        command = gains.command(state(out), max_angle)
        saturated += abs(command) >= max_angle
        try:
            sim.advance(command, gains.speed)
        except (ModelValidityError, IntegrationError) as err:
            stopped = str(err)
            break
        before, out = out, sim.outputs()
        travelled += float(progress(before, out))
        rows.append([out.t, out.axle[-1][0], out.axle[-1][1], *out.hitch_angle, out.steering])
        if travelled >= settle:
            errors.append(error(out))
        if out.t > 10.0 * distance / abs(gains.speed) + 60.0:
            stopped = "the train did not reverse the distance (it stood or went forward)"
            break
    return _run(travelled, rows, errors, stopped, saturated, scene.train.n)


# -- along a gentle curve -----------------------------------------------------------------------------

def steering_for(train, radius: float) -> float:
    """The steering angle psi_0 > 0 whose steady circles put the last axle on ``radius`` (m, a left
    turn; negate it for a right one): R_Bn falls as psi grows, found by bisection on the closed form."""
    from ...physics.steady import SteadyStateError, steady_circle

    lo, hi = 1e-6, train.actuator.max_angle
    try:
        if steady_circle(train, hi).R_B[-1] > radius:
            raise ValueError(f"radius: {radius:g} m is tighter than the steady turn at max_angle allows")
    except SteadyStateError:
        pass  # no steady turn at max_angle: the root lies below it
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        try:
            r = steady_circle(train, mid).R_B[-1]
        except SteadyStateError:
            hi = mid
            continue
        lo, hi = (mid, hi) if r > radius else (lo, mid)
    return 0.5 * (lo + hi)


@dataclass
class CurveGains:
    """u = psi_0 - K (x - x_0), x = (rho, eta, phi_2..phi_n, psi) about the steady reversing turn."""

    speed: float
    steering: float  # psi_0
    K: np.ndarray
    point: np.ndarray  # x_0
    closed_loop: np.ndarray
    R_A1: float  # the tractor's steered axle's circle
    radius: float  # the last axle's

    def command(self, x: np.ndarray, max_angle: float) -> float:
        return float(np.clip(self.steering - (self.K @ (x - self.point))[0], -max_angle, max_angle))


def design_curve(train, speed: float, radius: float, side: float = 1.0, q_offset: float = 1.0,
                 q_hitch: float = 10.0, q_heading: float = 10.0, r: float = 1.0) -> CurveGains:
    """LQR about the steady turn that puts the last axle on a circle of ``radius`` (``side`` +1
    left, -1 right), reversing at ``speed`` < 0: the linear model about that turn (linear.py),
    weights on the tractor's radial offset and heading and on each hitch angle's deviation; refused
    (ValueError): a train whose traction law ignores the speed (spec.require_speed_law), a circle
    tighter than the steering allows, and one whose steady turn bends a hitch past its limit."""
    from scipy.linalg import solve_continuous_are

    require_speed_law(train, "the reversing controller")

    from ...physics.steady import steady_circle
    from .envelope import degrees

    psi0 = math.copysign(steering_for(train, radius), side)
    for k, (phi, cart) in enumerate(zip(steady_circle(train, psi0).hitch_angles, train.carts[1:]), start=2):
        if abs(phi) >= cart.max_hitch_angle:
            raise ValueError(f"radius: {radius:g} m bends hitch {k} to {degrees(abs(phi))} deg on its steady turn, "
                             f"past its {degrees(cart.max_hitch_angle)} deg limit")
    model = linearize(train, "turn", speed, psi0)
    size = train.n + 2
    Q = np.zeros((size, size))
    Q[0, 0], Q[1, 1] = q_offset, q_heading
    for k in range(2, train.n + 1):
        Q[k, k] = q_hitch
    Q += 1e-9 * np.eye(size)
    R = np.array([[r]])
    P = solve_continuous_are(model.A, model.B, Q, R)
    K = np.linalg.solve(R, model.B.T @ P)
    return CurveGains(speed, psi0, K, model.point, np.linalg.eigvals(model.A - model.B @ K),
                      steady_circle(train, psi0).R_A[0], radius)


def curve_state(out, gains: CurveGains, centre) -> np.ndarray:
    """x = (rho, eta, phi..., psi) of an Outputs sample about the circle of centre ``centre``."""
    ax, ay = out.front[0][0] - centre[0], out.front[0][1] - centre[1]
    alpha = math.atan2(ay, ax)
    eta = out.heading[0] - alpha
    eta = gains.point[1] + math.remainder(eta - gains.point[1], 2 * math.pi)
    return np.array([math.hypot(ax, ay) - gains.R_A1, eta, *out.hitch_angle, out.steering])


def reverse_curve(scene, gains: CurveGains, centre, distance: float, settle: float = 0.0) -> ReverseRun:
    """Back the scene's train around the circle of ``centre`` until its last axle has travelled
    ``distance`` m of arc; the error is the last axle's radial offset from ``gains.radius``."""
    return drive(scene, gains, lambda out: curve_state(out, gains, centre),
                 lambda before, after: math.hypot(after.axle[-1][0] - before.axle[-1][0],
                                                  after.axle[-1][1] - before.axle[-1][1]),
                 lambda out: math.hypot(out.axle[-1][0] - centre[0], out.axle[-1][1] - centre[1]) - gains.radius,
                 distance, settle)


# -- fed pose by pose (mta reverse's node, reverse_node.py) ---------------------------------------------

class Reverser:
    """The controller as a node runs it, one hitch_poses message at a time: the state from the
    hitch points A_k and headings th_k it is given and the applied steering ``psi`` (last heard),
    the command of ``gains`` (the line y = 0) or of ``curve`` (the circle, placed at the first pose:
    the train is taken to start on its steady circle), the speed; the last axle B_n's error kept once
    it has reversed ``settle`` m, and the train stopped (speed 0, ``done``) once ``distance`` m."""

    def __init__(self, train, gains: Gains, curve: CurveGains | None, distance: float, settle: float,
                 side: str = "left"):
        self.train, self.gains, self.curve = train, gains, curve
        self.distance, self.settle, self.side = distance, settle, side
        self.psi = 0.0
        self.start_x = None
        self.errors: list[float] = []
        self.centre = self.last_bn = None
        self.hitch, self.steer, self.reversed = 0.0, 0.0, 0.0
        self.done = False

    def answer(self, points, th) -> tuple[float, float]:
        """(steering command, speed) answering one pose: ``points`` the A_k as (x, y), ``th`` the
        headings th_k, both of every cart in order."""
        train, curve = self.train, self.curve
        max_angle = train.actuator.max_angle
        phis = [math.atan2(math.sin(th[k - 1] - th[k]), math.cos(th[k - 1] - th[k])) for k in range(1, train.n)]
        bn = np.array(points[-1]) - train.carts[-1].length * np.array([math.cos(th[-1]), math.sin(th[-1])])
        a1 = np.array(points[0])
        if self.start_x is None:
            self.start_x, self.last_bn = bn[0], bn
            if curve is not None:  # the steady circle through the first pose: alpha = th_1 - eta_0
                alpha = th[0] - curve.point[1]
                self.centre = a1 - curve.R_A1 * np.array([math.cos(alpha), math.sin(alpha)])
        if curve is None:
            self.reversed = self.start_x - bn[0]
            x = np.array([a1[1], th[0], *phis, self.psi])
            command = self.gains.command(x, max_angle)
            error = float(bn[1])
        else:
            self.reversed += float(np.hypot(*(bn - self.last_bn)))
            self.last_bn = bn
            r = a1 - self.centre
            alpha = math.atan2(r[1], r[0])
            eta = curve.point[1] + math.remainder(th[0] - alpha - curve.point[1], 2 * math.pi)
            x = np.array([math.hypot(*r) - curve.R_A1, eta, *phis, self.psi])
            command = curve.command(x, max_angle)
            error = float(np.hypot(*(bn - self.centre)) - curve.radius)
        self.hitch = max([self.hitch, *map(abs, phis)])
        self.steer = max(self.steer, abs(self.psi))
        if self.reversed >= self.settle:
            self.errors.append(error)
        self.done = self.reversed >= self.distance
        return command, 0.0 if self.done else self.gains.speed * math.cos(command)  # the rear axle's speed

    def figures(self) -> dict:
        """What the run measured (``mta reverse --report``)."""
        gains, curve = self.gains, self.curve
        e = np.abs(np.array(self.errors)) if self.errors else np.array([math.nan])
        return {"path": "straight" if curve is None else f"circle of {curve.radius:g} m, {self.side}",
                "centre": None if self.centre is None else self.centre.tolist(),
                "reversed_m": self.reversed, "samples": len(self.errors), "max_m": float(e.max()),
                "rms_m": float(np.sqrt(np.mean(e ** 2))), "max_hitch_deg": math.degrees(self.hitch),
                "max_steering_deg": math.degrees(self.steer), "speed_m_s": gains.speed,
                "gain": (curve or gains).K.ravel().tolist(),
                "closed_loop": [str(complex(v)) for v in (curve or gains).closed_loop]}

    def summary(self) -> str:
        """What the run measured, in a log line."""
        figures = self.figures()
        return (f"reversed {self.reversed:.1f} m at {self.gains.speed:g} m/s: lateral error of "
                f"'{self.train.carts[-1].name}' after {self.settle:g} m: max {figures['max_m']:.3f} m, RMS "
                f"{figures['rms_m']:.3f} m; largest hitch angle {figures['max_hitch_deg']:.1f} deg")
