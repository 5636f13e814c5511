"""Trains and scenes built in code for the physics tests (the shipped YAML files are tested in
test_loader.py). Parameters are of the size of real machines; the tests do not depend on them
beyond the closed forms they check."""
from __future__ import annotations

import math

import numpy as np

from mta_sim_ros.physics.spec import Actuator, Cart, Draft, Initial, Integrator, Rolling, Scene, Table, Traction, Train

# (length l, hitch_offset a, com_offset c, mass m, yaw_inertia J) of realistic carts
CARTS = [
    (3.0, 1.5, 1.3, 16000.0, 45000.0),  # tractor
    (5.0, 1.5, 2.0, 10000.0, 60000.0),  # air cart
    (6.0, 0.0, 2.5, 8000.0, 110000.0),  # seeder
    (4.0, -0.8, 1.0, 5000.0, 20000.0),  # trailer hitched in front of its axle
    (3.5, 1.0, 0.5, 3000.0, 9000.0),  # wagon
]

GOVERNOR = Traction("governor", set_speed=3.0, max_force=125000.0, max_power=250000.0, kp=60000.0, ki=30000.0)


def train(n: int = 3, traction: Traction = GOVERNOR, draft: bool = True, carts=None, name="test") -> Train:
    specs = carts if carts is not None else CARTS[:n]
    cs = tuple(Cart(f"cart{k + 1}", *spec) for k, spec in enumerate(specs))
    return Train(
        name=name,
        carts=cs,
        traction=traction,
        rolling=tuple(Rolling(c.name, 0.08) for c in cs),
        draft=(Draft(cs[-1].name, A=2500.0, B=40.0, C=2.0, width=12.0, depth=1.0),) if draft else (),
        actuator=Actuator(time_constant=0.2, max_rate=0.6, max_angle=math.radians(40.0)),
    )


def prescribed(speed: float) -> Traction:
    """Speed held at ``speed`` exactly when the run starts at it (V' = 0 while V = v_set)."""
    return Traction("prescribed_speed", set_speed=speed, response_time=0.5)


def scene(tr: Train, table=((0.0,), (0.0,)), duration=10.0, rate=10.0, method="rk4", step=0.01,
          rtol=1e-8, atol=1e-10, **initial) -> Scene:
    """A scene steered by ``table`` = (times, angles); ``initial`` fields as in spec.Initial."""
    init = dict(speed=tr.traction.set_speed)
    init.update(initial)
    return Scene(
        name="test",
        train=tr,
        duration=duration,
        initial=Initial(**init),
        steering=Table(tuple(table[0]), tuple(table[1])),
        integrator=Integrator(method=method, step=step, rtol=rtol, atol=atol),
        publish_rate=rate,
    )


def random_state(model, rng, spread: float = 0.4, steering: float = 0.5, slow: bool = False) -> np.ndarray:
    """A random state of a no-slip model: pose anywhere, hitch angles within +-``spread`` per joint,
    steering within +-``steering``, V in [-4, 4] m/s (with ``slow``, a third of the draws inside the
    tanh smoothing near V = 0 and a third exactly 0), a governor integral of the size of the forces."""
    L = model.layout
    y = np.zeros(L.size)
    y[L.x], y[L.y] = rng.normal(0, 10, 2)
    y[L.heading] = rng.uniform(-math.pi, math.pi) + np.cumsum(rng.uniform(-spread, spread, L.n))
    y[L.steering] = rng.uniform(-steering, steering)
    y[L.speed] = rng.choice([rng.uniform(-4, 4), rng.uniform(-0.08, 0.08), 0.0]) if slow else rng.uniform(-4, 4)
    y[L.governor] = rng.normal(0, 2e4)
    return y


def energy_balance(model, y0, command, energy, duration: float = 20.0, v_set: float = 3.0):
    """(largest |E(t) - E(0) - W(t)|, largest |E(t) - E(0)|, largest |W(t)|) along the run of
    ``model`` from y0 steered by command(t), by DOP853 at 1e-12: W the work of traction less the
    resistances' (integrated with the state), E = ``energy(y)`` (kinetic + potential)."""
    from scipy.integrate import solve_ivp

    def augmented(t, z):
        dy, tm = model.derivative(z[:-1], command(t), v_set)
        V = z[model.layout.speed]
        return np.append(dy, tm.traction * V - sum(f * kb * V for f, kb in zip(tm.resistance, tm.chain.kapB)))

    sol = solve_ivp(augmented, (0, duration), np.append(y0, 0.0), method="DOP853", rtol=1e-12, atol=1e-12,
                    t_eval=np.linspace(0, duration, 41))
    assert sol.success
    energies = np.array([energy(sol.y[:-1, i]) for i in range(len(sol.t))])
    work = sol.y[-1]
    return (float(np.max(np.abs(energies - energies[0] - work))), float(np.max(np.abs(energies - energies[0]))),
            float(np.max(np.abs(work))), sol)
