"""Whether the reversing loop can hold a train, known before it starts (issue 25). No ROS here.

The LQR gain (controller.design) stabilises the linear model about straight reversing, but the
train it steers has an actuator the design leaves out of its limits: the command is clipped to
max_angle and the steering turns at most max_rate. Where the loop asks for more, it is no longer
the designed one and the train can fold. ``unheld`` runs that loop before the train moves: the
train's own kinematic equations (linear.equations on numbers: the chain the linear model is the
derivative of, hitch offsets and all), the actuator psi' = clip((u - psi) / tau, +-max_rate), the
command u = gains.command(x) clipped to max_angle and held over each controller tick (the actuator
in closed form, the chain by rk4 steps that resolve its fastest hitch mode); from the nominal
starts the controller is made for, START_OFFSET m to the side of the line with the hitches bent
START_HITCH (at most half a hitch's limit) alternately either way and all one way either way
(``patterns``: the sign of the hitches matters, a train held from one can fold from another),
reversing HORIZON m from each. It cannot hold the train where a hitch angle reaches its cart's
max_hitch_angle (a jackknife) or the chain's geometry breaks (a cart's velocity angle passes 90
deg), or where after the horizon the last axle is not back within SETTLED m of the line, its
hitches straighter than START_HITCH (it does not settle).

What it leaves out: the dynamic level's inertia and forces (the speed is held), the slip level's
tyres, any start but its own (a train started farther out can fold where the check holds it).
``python -m benchmarks reversing`` holds its verdicts against the dynamic level's runs on 96
generated trains.
"""
from __future__ import annotations

import math

import numpy as np

from ...physics.chain import ChainGeometry
from ...symbolic.linear import equations

#: m, rad: the start the check runs from (the benchmark's and mta reverse's usual start: the last
#: axle some way off the line, the hitches a little bent)
START_OFFSET = 0.5
START_HITCH = math.radians(2.0)
#: m the last axle reverses in the check; m within which it must then be of the line
HORIZON = 100.0
SETTLED = 0.05
#: s: the controller's tick (mta reverse answers each 50 Hz pose)
TICK = 0.02


def unheld(train, gains, tick: float = TICK, horizon: float = HORIZON) -> str:
    """'' when the loop of ``gains`` (controller.Gains) holds ``train`` from every one of its nominal
    starts (``patterns``); else why not from the first that fails, in one clause ("from hitches
    +2.0, +2.0 deg: hitch 2 reaches 67.3 deg, past its 60.0 deg limit, after 11.2 m")."""
    for pattern in patterns(train):
        why = unheld_from(train, gains, pattern, tick, horizon)
        if why:
            return f"{described(train, pattern)}: {why}"
    return ""


def described(train, pattern: tuple) -> str:
    """A start of the check in words: "from hitches bent 2.0 deg alternately, the first +"."""
    if train.n < 2:
        return "from the start"
    bent = degrees(max(abs(phi) for phi in start(train, pattern)[2:train.n + 1]))
    first = "+" if pattern[0] > 0 else "-"
    if train.n == 2 or len(set(pattern)) == 1:
        return f"from hitches bent {first}{bent} deg" + (" all" if train.n > 2 else "")
    return f"from hitches bent {bent} deg alternately, the first {first}"


def patterns(train) -> list[tuple]:
    """The signs of the start's hitch angles the check runs from, the train START_OFFSET m to the left
    of the line (the mirror image, right with every sign turned, moves as the mirror image): bent
    alternately either way, and all one way either way (one each for a single hitch)."""
    m = train.n - 1
    alternate = tuple((-1) ** k for k in range(m))
    out = [alternate, tuple(-s for s in alternate), (1,) * m, (-1,) * m]
    return list(dict.fromkeys(out))


def unheld_from(train, gains, pattern: tuple, tick: float = TICK, horizon: float = HORIZON) -> str:
    """``unheld`` from one start: the hitches bent START_HITCH with the signs ``pattern``."""
    x = start(train, pattern)
    n, V = train.n, gains.speed
    geom = ChainGeometry.of(train)
    act = train.actuator
    limits = [cart.max_hitch_angle for cart in train.carts[1:]]
    C = gains.C
    steps = int(math.ceil(horizon / abs(V) / tick))
    # rk4 steps within a tick: at most half the time the shortest cart takes to pass its own length
    # (the fastest hitch mode, |V| / l_k); the actuator in closed form, however quick
    sub = max(1, math.ceil(tick / (0.5 * min(geom.length) / abs(V))))
    for i in range(steps):
        u = gains.command(x, act.max_angle)
        try:
            for _ in range(sub):
                x = rk4(x, u, V, act.time_constant, act.max_rate, geom, tick / sub)
        except (ValueError, ZeroDivisionError):  # math's sqrt of a negative: no chain there
            x = np.full_like(x, math.nan)
        if not np.all(np.isfinite(x)):
            return f"the chain's geometry breaks after {abs(V) * (i + 1) * tick:.3g} m"
        for k, (phi, limit) in enumerate(zip(x[2:2 + n - 1], limits), start=2):
            if abs(phi) >= limit:  # (a chain that folds within one tick: its angle said only as past 180)
                reached = degrees(abs(phi)) if abs(phi) <= math.pi else "over 180"
                return (f"hitch {k} reaches {reached} deg, past its {degrees(limit)} deg limit, after "
                        f"{abs(V) * (i + 1) * tick:.3g} m")
    offset = abs(float(C @ x))
    worst = max((abs(p) for p in x[2:2 + n - 1]), default=0.0)
    if offset > SETTLED or worst > START_HITCH:
        bent = f" and a hitch at {degrees(worst)} deg" if n > 1 else ""
        return f"after {horizon:g} m the last axle is {offset:.2f} m off the line{bent}: the loop does not settle"
    return ""


def degrees(angle: float) -> str:
    """An angle in rad as degrees for a message: 0.1 deg, or three digits below 1 deg."""
    value = math.degrees(angle)
    return f"{value:.1f}" if value >= 1.0 else f"{value:.3g}"


def run_holds(run, n: int) -> bool:
    """The check's verdict read off a run on the simulator (controller.ReverseRun of an n-cart train
    from ``start_scene``): not stopped, and at its end the last axle within SETTLED m of the line and
    every hitch straighter than START_HITCH."""
    if run.stopped or not len(run.trace):
        return False
    end = run.trace[-1]
    return abs(end[2]) <= SETTLED and all(abs(phi) <= START_HITCH for phi in end[3:3 + n - 1])


def start(train, pattern: tuple | None = None) -> np.ndarray:
    """x = (y, th_1, phi_2..phi_n, psi) of a start of the check: the whole train START_OFFSET m to the
    side, the hitches at START_HITCH with the signs ``pattern`` (default: +, -, + ... in turn), each
    at most half its limit."""
    x = np.zeros(train.n + 2)
    x[0] = START_OFFSET
    signs = pattern or patterns(train)[0]
    x[2:train.n + 1] = [sign * min(START_HITCH, 0.5 * cart.max_hitch_angle) for sign, cart in zip(signs, train.carts[1:])]
    return x


def rk4(x, u, V, tau, max_rate, geom, h) -> np.ndarray:
    """One rk4 step of the kinematic train, the command u held: the chain's states by rk4, the
    steering psi by the actuator's closed form (``steering_at``), at each stage's time."""
    psi0 = float(x[-1])

    def f(z, t):
        return np.array(equations([*z, steering_at(psi0, u, tau, max_rate, t)], u, V, tau, 1.0, geom, "straight",
                                  math)[:-1], dtype=float)

    z = x[:-1]
    k1 = f(z, 0.0)
    k2 = f(z + 0.5 * h * k1, 0.5 * h)
    k3 = f(z + 0.5 * h * k2, 0.5 * h)
    k4 = f(z + h * k3, h)
    return np.append(z + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4), steering_at(psi0, u, tau, max_rate, h))


def steering_at(psi0: float, u: float, tau: float, max_rate: float, t: float) -> float:
    """psi(t) of the actuator psi' = clip((u - psi) / tau, +-max_rate) from psi0, u held: at the rate
    limit until |u - psi| = tau max_rate, then the lag's exponential."""
    gap = u - psi0
    band = tau * max_rate  # the gap below which the lag is within the rate limit
    if abs(gap) > band:
        ramp = (abs(gap) - band) / max_rate  # s at the rate limit
        if t <= ramp:
            return psi0 + math.copysign(max_rate * t, gap)
        return u - math.copysign(band, gap) * math.exp(-(t - ramp) / tau)
    return u - gap * math.exp(-t / tau)


def start_scene(train, speed: float, duration: float = 1000.0, offset: float | None = None,
                hitch: float | None = None, pattern: tuple | None = None):
    """A scene of ``train`` at a start of the check (``start``, the hitches' signs ``pattern``),
    reversing at ``speed`` on the dynamic level, 50 Hz: what the check's verdict is held against
    (controller.reverse runs it). ``offset`` (m) and ``hitch`` (rad, every hitch bent the same way,
    at most half its limit) give another start."""
    from ...physics import loader

    x = start(train, pattern)
    if offset is not None:
        x[0] = offset
    if hitch is not None:
        x[2:train.n + 1] = [math.copysign(min(abs(hitch), 0.5 * cart.max_hitch_angle), hitch) for cart in train.carts[1:]]
    data = {"name": "backing", "train": "unused.yaml", "duration": duration,
            "initial": {"y": float(x[0]), "speed": speed, "hitch_angles": [float(v) for v in x[2:train.n + 1]]},
            "steering": {"maneuver": "straight"}, "speed": speed, "integrator": {"method": "rk4", "step": 0.01},
            "publish_rate": 50, "fidelity": "dynamic"}
    return loader.scene_from_data(data, "the check's start", train)
