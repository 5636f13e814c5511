"""Fidelity levels and the ``auto`` choice between them. No ROS here.

Levels, cheapest first (spec.FIDELITY_LEVELS):
    kinematic  speed prescribed, q' = G V(t); traction and power by inverse dynamics
    dynamic    the article's one-degree-of-freedom model with traction and resistance laws
    slip       lateral tyre compliance in place of the no-side-slip constraints
(physics/levels.py builds them.)

A scene says what it needs (``needs: {poses: m, speed: m/s, power: relative, hitch_angles: rad}``,
errors against the highest level, slip) and ``fidelity: auto`` (the default) takes the cheapest
level whose predicted error meets every tolerance. The predictions are read off the scene's own
input tables, no simulation: see ``estimate`` for each formula and docs/fidelity.md for the
measurements they were checked against (``python -m benchmarks fidelity``).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..physics.spec import FIDELITY_LEVELS, Scene, Train

LEVELS = FIDELITY_LEVELS
#: the outputs a scene's needs name (spec.Needs), each level's prediction per output
OUTPUTS = ("poses", "speed", "power", "hitch_angles")

# Constants of the predicted errors (estimate()), fitted as upper envelopes of the measured ratio
# error / predictor on the shipped forward scenes (docs/fidelity.md, ``python -m benchmarks fidelity``; the
# reversing scene is left out: its hitch angles grow, the no-slip error there is the instability).
# Poses: measured / slip_drift was 1.1 (tight_turn) .. 18 (headland_turn): a heading error that an
# open-loop scene never corrects turns into offset over the rest of the run, which the inputs
# alone predict only to this factor. Conservative on purpose.
SLIP_POSE_FACTOR = 20.0
# Hitch angles: measured / max slip angle was 0.7 .. 2.7.
SLIP_HITCH_FACTOR = 3.0
# Speed: the no-slip levels' |dV| / (V max slip angle) was <= 0.5; the kinematic level's <= 1.1.
SLIP_SPEED_FACTOR = 1.0
KINEMATIC_SPEED_FACTOR = 2.0
# Power: the no-slip levels' RMS relative error / max slip angle was <= 0.61; the kinematic level's
# at a constant set speed <= 0.9.
SLIP_POWER_FACTOR = 0.8
KINEMATIC_POWER_FACTOR = 1.2
# Speed ramps: the PI loop's closed-form lag (a M / kp in speed, a M / ki in distance) times this.
GOVERNOR_MARGIN = 1.5


@dataclass(frozen=True)
class Choice:
    """The level a run uses and why (one line for logs, diagnostics and bag metadata)."""

    level: str
    reason: str
    estimates: dict = field(default_factory=dict, compare=False)  # predicted errors per level and output


# -- what the scene's inputs say -----------------------------------------------------------------

@dataclass(frozen=True)
class SceneInputs:
    """Quantities of a scene read from its input tables (no simulation)."""

    max_lateral_accel: float  # m/s^2, V^2 tan|psi| / l_1 (the tractor's rear axle on the no-slip path)
    max_accel: float  # m/s^2, largest |dV_set/dt|
    max_speed_step: float  # m/s, jump of the set-point at t = 0 from the initial speed
    max_slip_angle: float  # rad, largest slip angle of an axle, quasi-steady (see slip_angles)
    slip_drift: float  # m, the offset a heading error built up by side slip gives: see scene_inputs()
    speed_commanded: bool  # the traction law follows a set speed (governor, prescribed_speed)


def slip_angles(scene: Scene, dt: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(t, V, alpha, alpha_0): the largest slip angle over the axles, alpha = lambda / C_alpha, of the
    no-slip constraint forces lambda (slip.no_slip_tyre_forces) on the quasi-steady state of the
    scene's inputs at each t (the steady circle of the steering command, MODEL.md, at the speed
    set-point, the governor balancing the resistances); alpha_0 the same at the scene's own
    initial state (hitch angles that are not steady). On a tilted plane each state is taken along
    the plane's contour, both ways, where gravity pushes the axles sideways the most."""
    from ..physics import kernel
    from ..physics.slip import SlipModel, no_slip_tyre_forces

    tr = scene.train
    model = SlipModel(tr)
    dyn = model.dynamic
    L = dyn.layout
    ts = np.arange(0.0, scene.duration + dt / 2, dt)
    vs, alphas = [], []

    def at_heading(y, command, v_set):
        if tr.traction.law == "governor":
            tm = dyn.terms(y, command, v_set)
            y[L.governor] = tm.balance
        front, rear = no_slip_tyre_forces(model, y, command, v_set)
        return max([abs(front) / model.front_stiffness] + list(np.abs(rear) / model.stiffness))

    def largest(y, command, v_set):
        """On a tilted plane, the worst of the two headings along its contour (gravity all across)."""
        if dyn.P[kernel.H.slope] == 0.0:
            return at_heading(y, command, v_set)
        contour = math.atan2(dyn.P[kernel.H.gravity_y], dyn.P[kernel.H.gravity_x]) + 0.5 * math.pi
        out = 0.0
        for turn in (contour, contour + math.pi):
            z = y.copy()
            z[L.heading] += turn
            out = max(out, at_heading(z, command, v_set))
        return out

    psis = np.clip(np.interp(ts, scene.steering.time, scene.steering.value), -tr.actuator.max_angle,
                   tr.actuator.max_angle)
    speeds = _speeds_at(scene, ts)
    seen: dict = {}  # (psi, V) -> alpha: a scene holds its inputs for long stretches
    for psi, v in zip(psis.tolist(), speeds.tolist()):
        vs.append(v)
        if (psi, v) not in seen:
            y = steady_state(tr, L, psi, v)
            seen[psi, v] = math.inf if y is None else largest(y, psi, v)
        alphas.append(seen[psi, v])
    ini = scene.initial
    y = np.zeros(L.size)
    y[L.steering], y[L.speed] = ini.steering, ini.speed
    y[L.heading] = np.concatenate(([0.0], -np.cumsum(ini.hitch_angles or (0.0,) * (tr.n - 1))))
    alpha0 = largest(y, ini.steering, _speed_at(scene, 0.0))
    return ts, np.array(vs), np.array(alphas), alpha0


def steady_state(tr: Train, L, psi: float, v: float):
    """The state of ``tr`` (layout L) on the steady circle of the steering psi at speed v, heading 0
    (straight below STRAIGHT), or None where there is no steady circle."""
    from ..physics.steady import STRAIGHT, SteadyStateError, steady_circle

    y = np.zeros(L.size)
    y[L.steering], y[L.speed] = psi, v
    try:
        hitch = steady_circle(tr, psi).hitch_angles if abs(psi) > STRAIGHT else (0.0,) * (tr.n - 1)
    except SteadyStateError:
        return None
    y[L.heading] = np.concatenate(([0.0], -np.cumsum(hitch)))
    return y


def unheld_speed(scene: Scene, dt: float = 0.5) -> str:
    """'' where the traction can hold every speed set-point of the scene; else why not, for a governor
    whose force limit, min(max_force, max_power / abs(V)), is below the steady force a set-point needs
    (the resistances, drafts and grade of the quasi-steady state of ``slip_angles``; on a tilted plane
    along its fall line, uphill). There the dynamic and slip levels run slower than the set speed
    and the kinematic level, which prescribes it, is off by what the inputs do not say."""
    from ..physics import kernel
    from ..physics.dynamics import Model

    tr = scene.train
    law = tr.traction
    if law.law != "governor" or tr.relief is not None:
        return ""
    dyn = Model(tr)
    L = dyn.layout
    ts = np.arange(0.0, scene.duration + dt / 2, dt)
    psis = np.clip(np.interp(ts, scene.steering.time, scene.steering.value), -tr.actuator.max_angle,
                   tr.actuator.max_angle)
    uphill = math.atan2(-dyn.P[kernel.H.gravity_y], -dyn.P[kernel.H.gravity_x]) if dyn.P[kernel.H.slope] else 0.0
    for psi, v in sorted(set(zip(psis.tolist(), _speeds_at(scene, ts).tolist()))):
        y = steady_state(tr, L, psi, v)
        if y is None or v == 0.0:
            continue
        y[L.heading] += uphill if v > 0.0 else uphill + math.pi
        tm = dyn.terms(y, psi, v)
        needed = tm.balance
        limit = kernel.limit_of(law.max_force, law.max_power, v, kernel.NATURAL, kernel.NATURAL)
        if abs(needed) > limit:
            where = " up the plane's fall line" if dyn.P[kernel.H.slope] else ""
            return (f"the governor cannot hold {v:g} m/s{where}: the steady force it needs, {abs(needed):.4g} N, is "
                    f"over its limit min(max_force, max_power / abs(V)) = {limit:.4g} N")
    return ""


def _speed_at(scene: Scene, t: float) -> float:
    return float(_speeds_at(scene, np.array([t]))[0])


def _speeds_at(scene: Scene, t: np.ndarray) -> np.ndarray:
    """The speed set-point at the times t (the scene's table, else the traction law's speed)."""
    if scene.speed is not None:
        return np.interp(t, scene.speed.time, scene.speed.value)
    if scene.train.traction.law == "constant":
        return np.full(t.shape, scene.initial.speed)
    return np.full(t.shape, scene.train.traction.set_speed)


def scene_inputs(scene: Scene) -> SceneInputs:
    tr = scene.train
    t, v, alpha, alpha0 = slip_angles(scene)
    dt = t[1] - t[0] if len(t) > 1 else scene.duration
    psi = np.clip(np.interp(t, scene.steering.time, scene.steering.value), -tr.actuator.max_angle, tr.actuator.max_angle)
    a_lat = v * v * np.abs(np.tan(psi)) / tr.carts[0].length
    fine = np.arange(0.0, scene.duration + 0.005, 0.01)
    v_fine = _speeds_at(scene, fine)
    accel = np.abs(np.diff(v_fine)) / 0.01 if len(fine) > 1 else np.zeros(1)
    train_length = sum(c.length + max(c.hitch_offset, 0.0) for c in tr.carts)
    # The steady slip angle over the distance run, plus the start's bent hitches straightening over
    # the train length: a heading error an open-loop scene never corrects grows with both.
    drift = float(np.sum(np.abs(v) * alpha) * dt + alpha0 * train_length)
    return SceneInputs(
        max_lateral_accel=float(a_lat.max()),
        max_accel=float(accel.max()) if accel.size else 0.0,
        max_speed_step=abs(_speed_at(scene, 0.0) - scene.initial.speed),
        max_slip_angle=float(max(alpha.max(), alpha0)),
        slip_drift=drift,
        speed_commanded=tr.traction.law in ("governor", "prescribed_speed"),
    )


# -- predicted errors -----------------------------------------------------------------------------

def unbounded(scene: Scene) -> str:
    """'' where ``estimate``'s predictions bound the lower levels' errors; else why they cannot. A
    constant traction force: the speed is whatever force and resistances make of it, not an input
    (a force the resistances do not balance accelerates the train without end). A train with towed
    carts that reverses (a speed set-point or the start's speed below 0): about straight motion its
    hitch modes are -V / l_k (linear.straight_closed_form), backwards they grow, and so does any
    difference between two levels, from the slip the no-slip levels leave out to rounding; no
    reading of the inputs bounds that (docs/fidelity.md's reversing scene: 0.9 rad of hitch angle
    measured where the inputs gave 0.03)."""
    tr = scene.train
    if tr.traction.law == "constant":
        return ("traction law constant sets a force, not a speed: the speed every prediction reads is not in the "
                "scene's inputs")
    if tr.n < 2:
        return ""
    t = np.arange(0.0, scene.duration + 0.005, 0.01)
    if scene.initial.speed >= 0.0 and float(np.min(_speeds_at(scene, t))) >= 0.0:
        return ""
    return ("the scene reverses a towed train, whose hitch modes grow at |V| / l_k: no prediction from its inputs "
            "bounds a lower level's error")


def estimate(scene: Scene) -> dict[str, dict[str, float]]:
    """Predicted error of each level against slip, per output (the units of spec.Needs), from the
    scene's inputs (scene_inputs) and the constants above.

    dynamic: the side slip the no-slip constraints ignore. With alpha the largest quasi-steady slip
    angle (slip_angles): poses SLIP_POSE_FACTOR x slip_drift, hitch angles SLIP_HITCH_FACTOR x alpha,
    speed SLIP_SPEED_FACTOR x V alpha, power SLIP_POWER_FACTOR x alpha.

    kinematic: the same, plus prescribing the speed instead of the governor's response. For the
    PI loop M V' = kp e + ki int e (M = sum m_k) a set-point ramp of slope a lags by a M / kp in
    speed and a M / ki in distance (closed forms, times GOVERNOR_MARGIN); the power lacks M a
    against the resistances (M a / (sum f m g)); in turns at a constant set speed the governor's
    own speed dips make KINEMATIC_* x the slip terms. Only where the traction law commands a
    speed (governor or prescribed_speed); else the kinematic level is not available (inf).

    Where the errors grow without a bound the inputs give (``unbounded``: a towed train reversing),
    both no-slip levels' predictions are inf; where the governor cannot hold a set speed
    (``unheld_speed``), the kinematic level's are.
    """
    if unbounded(scene):
        return {"slip": dict.fromkeys(OUTPUTS, 0.0), "dynamic": dict.fromkeys(OUTPUTS, math.inf),
                "kinematic": dict.fromkeys(OUTPUTS, math.inf)}
    inp = scene_inputs(scene)
    tr = scene.train
    alpha = inp.max_slip_angle
    v_max = max(abs(scene.initial.speed), abs(_speed_at(scene, 0.0)),
                max(abs(v) for v in scene.speed.value) if scene.speed is not None else 0.0)
    no_slip = {
        "poses": SLIP_POSE_FACTOR * inp.slip_drift,
        "hitch_angles": SLIP_HITCH_FACTOR * alpha,
        "speed": SLIP_SPEED_FACTOR * v_max * alpha,
        "power": SLIP_POWER_FACTOR * alpha,
    }
    out = {"slip": {k: 0.0 for k in no_slip}, "dynamic": dict(no_slip)}
    if not inp.speed_commanded or unheld_speed(scene):
        out["kinematic"] = {k: math.inf for k in no_slip}
        return out
    mass = sum(c.mass for c in tr.carts)
    law = tr.traction
    if law.law == "governor":
        speed_lag = inp.max_accel * mass / law.kp + inp.max_speed_step
        dist_lag = (inp.max_accel * mass / law.ki if law.ki > 0 else math.inf) + inp.max_speed_step * mass / law.kp
    else:  # prescribed_speed: the law's first-order lag
        speed_lag = inp.max_accel * law.response_time + inp.max_speed_step
        dist_lag = (inp.max_accel * law.response_time + inp.max_speed_step) * law.response_time
    rolling = sum(r.coefficient * tr.carts[tr.cart_index(r.cart)].mass for r in tr.rolling) * tr.gravity
    out["kinematic"] = {
        "poses": no_slip["poses"] + GOVERNOR_MARGIN * dist_lag,
        "hitch_angles": no_slip["hitch_angles"],
        "speed": KINEMATIC_SPEED_FACTOR * v_max * alpha + GOVERNOR_MARGIN * speed_lag,
        "power": KINEMATIC_POWER_FACTOR * alpha + GOVERNOR_MARGIN * mass * inp.max_accel / max(rolling, 1.0),
    }
    return out


def choose(scene: Scene, forced: str | None = None) -> Choice:
    """The level for this run and the reason, in this order: a level forced by the caller (node
    parameter, --fidelity), the scene's ``fidelity`` if not auto, the article's model (dynamic) if
    the scene states no needs, else the cheapest level whose predicted errors meet every need."""
    if forced not in (None, "", "auto"):
        if forced not in LEVELS:
            raise ValueError(f"fidelity: {forced!r} must be one of auto, {', '.join(LEVELS)}")
        return Choice(forced, f"{forced}: forced by the user")
    if scene.fidelity != "auto":
        return Choice(scene.fidelity, f"{scene.fidelity}: the scene states fidelity: {scene.fidelity}")
    if scene.needs is None:
        return Choice("dynamic", "dynamic: auto, and the scene states no needs: the article's model")
    if scene.train.relief is not None:  # the slip level takes a plane only, and no prediction reads a grid
        return Choice("dynamic", "dynamic: auto on a height grid, the highest level that runs on one (the "
                                 "predictions read no grid)")
    needs = scene.needs.asked()
    est = _estimate_cached(scene)
    why = unbounded(scene)
    if why:
        return Choice("slip", f"slip: auto, the highest level: {why}", est)
    for level in LEVELS:
        over = [f"{k} {est[level][k]:.3g} > {tol:g}" for k, tol in needs.items() if not est[level][k] <= tol]
        if not over:
            met = ", ".join(f"{k} {est[level][k]:.3g} <= {tol:g}" for k, tol in needs.items())
            cheaper = [lv for lv in LEVELS[: LEVELS.index(level)]]
            why_not = "; ".join(f"{lv} misses ({_misses(est[lv], needs)})" for lv in cheaper)
            unheld = unheld_speed(scene) if "kinematic" in cheaper else ""
            why_not += f" ({unheld})" if unheld else ""
            return Choice(level, f"{level}: auto, predicted errors {met}" + (f"; {why_not}" if why_not else ""), est)
    return Choice("slip", "slip: auto, the highest level (no level's predicted error meets every need)", est)


#: estimates kept per train and scene (a reset, a resumed sweep, the same scheme on another core)
_ESTIMATES: dict[str, dict] = {}
_ESTIMATES_KEPT = 256


def _estimate_cached(scene: Scene) -> dict:
    """``estimate`` of a scene, kept by the scene's full text (its train, tables and raw fields: two
    scenes with the same text have the same estimates); the oldest dropped past _ESTIMATES_KEPT."""
    key = repr(dataclasses.replace(scene, source=""))
    if key not in _ESTIMATES:
        if len(_ESTIMATES) >= _ESTIMATES_KEPT:
            _ESTIMATES.pop(next(iter(_ESTIMATES)))
        _ESTIMATES[key] = estimate(scene)
    return _ESTIMATES[key]


def forget_estimates() -> None:
    """Empty the estimates' cache (a benchmark timing the estimate of a new scheme)."""
    _ESTIMATES.clear()


def _misses(est: dict, needs: dict) -> str:
    return ", ".join(f"{k} {est[k]:.3g} > {tol:g}" for k, tol in needs.items() if not est[k] <= tol)
