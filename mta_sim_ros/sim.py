"""A run: model + stepper + held inputs, one tick at a time. No ROS here.

The ROS node and the offline ``mta run`` both drive a :class:`Simulation` the same way: at each
tick the latest steering command and speed set-point are held (zero-order hold) while the state
advances by one tick of simulated time, then the outputs are read. So the two agree for the same
command sequence, and a run is deterministic.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .integrate import IntegrationError, make_stepper
from .model.dynamics import Model
from .model.geometry import cart_points, hitch_angles
from .model.guards import ModelValidityError, check_state, jackknife_margin
from .model.spec import Scene, Table


def table_value(table: Table, t: float) -> float:
    """Piecewise-linear interpolation, held constant outside the table."""
    return float(np.interp(t, table.time, table.value))


@dataclass
class Outputs:
    """What the simulator reports at one instant (SI units, rad)."""

    t: float  # s
    front: np.ndarray  # A_k, n x 2
    axle: np.ndarray  # B_k, n x 2
    com: np.ndarray  # C_k, n x 2
    rear_hitch: np.ndarray  # A_{n+1} (the last cart's rear hitch point), 2
    heading: np.ndarray  # th_k, n
    hitch_angle: np.ndarray  # th_{k-1} - th_k, n - 1
    psi: np.ndarray  # psi_k, n (psi_1 = applied steering angle)
    com_speed: np.ndarray  # s'_Ck, n, m/s
    axle_speed: np.ndarray  # s'_Bk, n, m/s
    yaw_rate: np.ndarray  # th'_k, n, rad/s
    speed: float  # V = s'_A1, m/s
    steering: float  # psi_1, rad
    command: float  # steering command held over the last tick, rad
    speed_setpoint: float  # m/s
    resistance: np.ndarray  # F_Bk, n, N (> 0 opposes forward motion of B_k)
    traction: float  # F_A1, N
    power: float  # N = F_A1 V, W
    resistance_power: float  # sum F_Bk s'_Bk, W
    kinetic_energy: float  # T = 1/2 M V^2, J
    jackknife_margin: float  # rad, see guards.jackknife_margin


def initial_state(scene: Scene, model: Model) -> np.ndarray:
    """The state at t = 0: the scene's pose and speed, the train straight unless hitch angles
    are given, and the governor's integral set so the train starts in equilibrium at its speed
    (integral = the traction that balances the resistances)."""
    L = model.layout
    ini = scene.initial
    y = np.zeros(L.size)
    y[L.x], y[L.y] = ini.x, ini.y
    heading = [ini.heading]
    for phi in ini.hitch_angles or (0.0,) * (L.n - 1):
        heading.append(heading[-1] - phi)
    y[L.heading] = heading
    y[L.steering] = ini.steering
    y[L.speed] = ini.speed
    if scene.train.traction.law == "governor":
        v_set = speed_setpoint(scene, 0.0)
        tm = model.terms(y, ini.steering, v_set)
        balance = sum(f * kb for f, kb in zip(tm.resistance, tm.chain.kapB)) + tm.velocity_term
        y[L.governor] = balance - scene.train.traction.kp * (v_set - ini.speed)
    return y


def speed_setpoint(scene: Scene, t: float) -> float:
    """The scene's speed set-point at t, or the traction law's default."""
    if scene.speed is None:
        return scene.train.traction.set_speed
    return table_value(scene.speed, t)


class Simulation:
    """One train in one scene, advanced tick by tick with held inputs."""

    def __init__(self, scene: Scene, method: str | None = None, step: float | None = None,
                 rate: float | None = None, algorithm: int = 2):
        self.scene = scene
        self.model = Model(scene.train, algorithm=algorithm)
        integ = scene.integrator
        self.method = method or integ.method
        self.step = step or integ.step
        make_stepper(self.method, self.step, integ.rtol, integ.atol)  # a bad method fails here, not at reset
        self.tick = 1.0 / (rate or scene.publish_rate)
        self.reset()

    def reset(self) -> None:
        """Back to the scene's start, with a fresh stepper (an adaptive one forgets its last step,
        so a run after a reset is the same as the first)."""
        integ = self.scene.integrator
        self.stepper = make_stepper(self.method, self.step, integ.rtol, integ.atol)
        self.ticks = 0
        self.y = initial_state(self.scene, self.model)
        self.command = self.scene.initial.steering
        self.v_set = speed_setpoint(self.scene, 0.0)

    @property
    def t(self) -> float:
        return self.ticks * self.tick

    def scheduled_inputs(self, t: float) -> tuple[float, float]:
        """The scene's own steering command and speed set-point at t."""
        return table_value(self.scene.steering, t), speed_setpoint(self.scene, t)

    def advance(self, command: float, v_set: float) -> np.ndarray:
        """Advance one tick holding (command, v_set); raise ModelValidityError past the model's
        validity (the state before the failing tick is kept)."""
        t0 = self.t
        model = self.model

        def f(t, y):
            return model.rhs(t, y, command, v_set)

        y1 = self.stepper.advance(f, t0, self.y, t0 + self.tick)
        check_state(model, t0 + self.tick, y1)
        self.y = y1
        self.ticks += 1
        self.command, self.v_set = command, v_set
        return y1

    def outputs(self) -> Outputs:
        return evaluate_outputs(self.model, self.t, self.y, self.command, self.v_set)


def evaluate_outputs(model: Model, t: float, y: np.ndarray, command: float, v_set: float) -> Outputs:
    L = model.layout
    tm = model.terms(y, command, v_set)
    ch = tm.chain
    V = float(y[L.speed])
    heading = y[L.heading]
    pts = cart_points(model.train, float(y[L.x]), float(y[L.y]), heading)
    axle_speed = np.array(ch.kapB) * V
    resistance_power = float(np.dot(tm.resistance, axle_speed))
    return Outputs(
        t=t,
        front=pts["A"], axle=pts["B"], com=pts["C"], rear_hitch=pts["rear_hitch"],
        heading=np.array(heading, dtype=float),
        hitch_angle=np.array(hitch_angles(list(heading))),
        psi=np.array(ch.psi),
        com_speed=np.array(ch.kapC) * V,
        axle_speed=axle_speed,
        yaw_rate=np.array(ch.kapT) * V,
        speed=V,
        steering=float(y[L.steering]),
        command=command,
        speed_setpoint=v_set,
        resistance=np.array(tm.resistance),
        traction=tm.traction,
        power=tm.traction * V,
        resistance_power=resistance_power,
        kinetic_energy=0.5 * tm.mass * V * V,
        jackknife_margin=jackknife_margin(model, y)[0],
    )


def run_scene(scene: Scene, on_output=None, **options) -> tuple[Simulation, Exception | None]:
    """Run the scene to its end with its own inputs, calling on_output(Outputs) at t = 0 and
    after every tick. Returns the simulation and the error that stopped it early, if any (the
    outputs already passed on stay valid)."""
    sim = Simulation(scene, **options)
    if on_output:
        on_output(sim.outputs())
    ticks = int(math.floor(scene.duration / sim.tick + 1e-9))
    while sim.ticks < ticks:
        command, v_set = sim.scheduled_inputs(sim.t)
        try:
            sim.advance(command, v_set)
        except (ModelValidityError, IntegrationError) as err:
            return sim, err
        if on_output:
            on_output(sim.outputs())
    return sim, None
