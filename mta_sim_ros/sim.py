"""A run: model + stepper + held inputs, one tick at a time. No ROS here.

The ROS node and the offline ``mta run`` both drive a :class:`Simulation` the same way: at each
tick the latest steering command and speed set-point are held (zero-order hold) while the state
advances by one tick of simulated time, then the outputs are read. So the two agree for the same
command sequence, and a run is deterministic.
"""
from __future__ import annotations

import math
import os
import time
import warnings
from dataclasses import dataclass

import numpy as np

from .fidelity import Choice, choose, make_model
from .integrate import IntegrationError, make_stepper
from .integrate.stability import UnstableStepError, stable_step
from .model.dynamics import Model
from .model.geometry import cart_points, hitch_angles
from .model.guards import ModelValidityError, check_state, fast_modes, margin_of
from .model.spec import Scene, Table


NO_JIT_ENV = "MTA_SIM_NO_JIT"  # set to 1: Simulation(compiled=None) keeps the Python path


def compiled_model(model, method: str, compiled: bool | None):
    """(model.compiled.CompiledModel or None, note saying why). ``compiled``: None = when the model
    and method have a compiled form, numba is importable and MTA_SIM_NO_JIT is not set; True =
    required (ValueError/ImportError if impossible); False = never."""
    if compiled is False:
        return None, "Python right-hand side (compiled=False)"
    if compiled is None and os.environ.get(NO_JIT_ENV, "").strip() not in ("", "0"):
        return None, f"Python right-hand side ({NO_JIT_ENV}={os.environ[NO_JIT_ENV]})"
    from .integrate.steppers import FIXED_METHODS

    try:
        from .model import compiled as jit
    except (ImportError, OSError) as err:  # OSError: llvmlite's shared library failed to load
        if compiled:
            raise
        return None, f"Python right-hand side (numba not importable: {err})"
    if method not in FIXED_METHODS or not jit.supports(model):
        if compiled:
            raise ValueError(f"compiled=True: no compiled path for method {method!r} with this model (it covers "
                             f"{', '.join(FIXED_METHODS)} on the dynamic level, algorithm 2)")
        return None, "Python right-hand side (no compiled form for this method and model)"
    return jit.CompiledModel(model), f"compiled {method} tick (numba {jit.numba_version()})"


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


def start_state(scene: Scene, model) -> np.ndarray:
    """The state at t = 0 for a model of any fidelity level: the dynamic level's initial_state,
    converted by the level's from_dynamic_state (kinematic: V' = 0; slip: u = G V, no slip yet)."""
    convert = getattr(model, "from_dynamic_state", None)
    if convert is None:
        return initial_state(scene, model)
    return convert(initial_state(scene, model.dynamic))


def speed_setpoint(scene: Scene, t: float) -> float:
    """The scene's speed set-point at t, or the traction law's default."""
    if scene.speed is None:
        return scene.train.traction.set_speed
    return table_value(scene.speed, t)


class Simulation:
    """One train in one scene, advanced tick by tick with held inputs."""

    def __init__(self, scene: Scene, method: str | None = None, step: float | None = None,
                 rate: float | None = None, algorithm: int = 2, substep: bool = True,
                 fidelity: str | None = None, compiled: bool | None = None):
        """``compiled``: run each tick of a fixed-step method on the dynamic level (algorithm 2) in
        compiled code (model/compiled.py, numba), bit for bit the Python path's arithmetic; None
        (default) = whenever possible unless the environment sets MTA_SIM_NO_JIT=1, True = required,
        False = the Python path. ``self.compiled`` says which runs, ``compiled_note`` why, and
        ``compile_time`` the seconds the JIT warm-up took here (0 without it; ~0 when already
        compiled in this process or loaded from numba's disk cache).

        A fixed step past its method's stability limit for a fast mode of the model (e.g. rk4
        with step > 2.785 x the steering actuator's time constant) would give growing garbage:
        with ``substep`` the stepper then takes shorter steps and ``stability_note`` (also warned)
        says why; without it, UnstableStepError."""
        self.scene = scene
        # Fidelity level (fidelity.py): ``fidelity`` forces one (kinematic, dynamic, slip); None =
        # the scene's, and for ``auto`` the cheapest that meets the scene's needs. The slip level
        # integrates with slip.DEFAULT_METHOD unless a method is given here (its tyres are stiff).
        self.choice: Choice = choose(scene, forced=fidelity)
        self.level = self.choice.level
        self.model = make_model(self.level, scene.train, algorithm)
        self._begin_tick = getattr(self.model, "begin_tick", None)  # kinematic: the speed ramp of a tick
        integ = scene.integrator
        self.rtol, self.atol = integ.rtol, integ.atol
        if self.level == "slip":  # the scene's method and tolerances are for the no-slip levels
            from .model import slip

            self.rtol, self.atol = slip.DEFAULT_RTOL, slip.DEFAULT_ATOL
            if method is None:
                method, step = slip.DEFAULT_METHOD, step or 1.0 / (rate or scene.publish_rate)
        self.method = method or integ.method
        self.step = step or integ.step
        make_stepper(self.method, self.step, self.rtol, self.atol)  # a bad method fails here, not at reset
        self.tick = 1.0 / (rate or scene.publish_rate)
        self.stepper_step, self.stability_note = stable_step(self.method, self.step, self.tick,
                                                             fast_modes(scene.train))
        if self.stability_note:
            if not substep:
                raise UnstableStepError(self.stability_note.replace(
                    "; sub-stepping at", "; refusing to run it (substep=True would sub-step at") + ")")
            warnings.warn(self.stability_note, RuntimeWarning, stacklevel=2)
        self._compiled, self.compiled_note = compiled_model(self.model, self.method, compiled)
        self.compiled = self._compiled is not None
        self.compile_time = 0.0
        self.reset()
        if self._compiled is not None:  # compile now, not in the first tick
            t_c = time.perf_counter()
            self._compiled.warm_up(self.y)
            self.compile_time = time.perf_counter() - t_c
            self.compiled_note += f", JIT warm-up {self.compile_time:.3g} s"

    def reset(self) -> None:
        """Back to the scene's start, with a fresh stepper (an adaptive one forgets its last step,
        so a run after a reset is the same as the first)."""
        self.stepper = make_stepper(self.method, self.stepper_step, self.rtol, self.atol)
        if getattr(self, "_compiled", None) is not None:
            self.stepper.attach(self._compiled)
        self.ticks = 0
        self.y = start_state(self.scene, self.model)
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
        if getattr(self.stepper, "compiled", None) is not None:  # the compiled tick (model/compiled.py)
            y1, clear = self.stepper.advance_held(t0, self.y, t0 + self.tick, command, v_set)
            if not clear:  # non-finite or near a jackknife limit: the Python check decides and says why
                check_state(model, t0 + self.tick, y1)
            self.y = y1
            self.ticks += 1
            self.command, self.v_set = command, v_set
            return y1

        def f(t, y):
            return model.rhs(t, y, command, v_set)

        y0 = self.y if self._begin_tick is None else self._begin_tick(self.y, v_set, self.tick)
        y1 = self.stepper.advance(f, t0, y0, t0 + self.tick)
        check_state(model, t0 + self.tick, y1)
        self.y = y1
        self.ticks += 1
        self.command, self.v_set = command, v_set
        return y1

    def outputs(self) -> Outputs:
        if self._compiled is not None:  # the same numbers from compiled code (test_compiled.py)
            out = self._compiled.outputs(self.t, self.y, self.command, self.v_set)
            if out is not None:
                return out
        return evaluate_outputs(self.model, self.t, self.y, self.command, self.v_set)


def evaluate_outputs(model: Model, t: float, y: np.ndarray, command: float, v_set: float) -> Outputs:
    """Outputs of a no-slip state (dynamic level, or kinematic with its inverse dynamics); a level
    with its own state layout (slip) reports through its own ``outputs``."""
    own = getattr(model, "outputs", None)
    if own is not None:
        return own(t, y, command, v_set)
    L = model.layout
    tm = model.terms(y, command, v_set)
    ch = tm.chain
    V = float(y[L.speed])
    heading = y[L.heading]
    pts = cart_points(model.train, float(y[L.x]), float(y[L.y]), heading)
    axle_speed = np.array(ch.kapB) * V
    resistance = np.array(tm.resistance)
    resistance_power = float(np.dot(resistance, axle_speed))
    phis = hitch_angles(heading.tolist())
    return Outputs(
        t=t,
        front=pts["A"], axle=pts["B"], com=pts["C"], rear_hitch=pts["rear_hitch"],
        heading=np.array(heading, dtype=float),
        hitch_angle=np.array(phis),
        psi=np.array(ch.psi),
        com_speed=np.array(ch.kapC) * V,
        axle_speed=axle_speed,
        yaw_rate=np.array(ch.kapT) * V,
        speed=V,
        steering=float(y[L.steering]),
        command=command,
        speed_setpoint=v_set,
        resistance=resistance,
        traction=tm.traction,
        power=tm.traction * V,
        resistance_power=resistance_power,
        kinetic_energy=0.5 * tm.mass * V * V,
        jackknife_margin=margin_of(model.train, phis, ch.psi)[0],  # the chain's psi: no second walk
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
