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

import numpy as np

from .. import jit, validate
from ..integrate import IntegrationError, make_stepper
from ..integrate import rk
from ..integrate.stability import UnstableStepError, resolved_step, stable_step
from ..integrate.steppers import FIXED_METHODS, FixedStep, Held
from ..physics import kernel
from ..physics.dynamics import Model
from ..physics.guards import ModelValidityError, check_state, fast_modes
from ..physics.levels import Level, lifted, make_level
from ..physics.outputs import Outputs
from ..physics.spec import Scene, Table
from .fidelity import Choice, choose

NO_JIT_ENV = jit.NO_JIT_ENV  # set to 1: Simulation(compiled=None) runs the kernels as plain Python

__all__ = ["Outputs", "Simulation", "run_scene", "initial_state", "start_state",
           "speed_setpoint", "speed_setpoints", "table_value", "table_values"]


def kernel_path(model, compiled: bool | None) -> tuple[bool | None, str]:
    """(True: the compiled kernels, False: the kernels as plain Python, None: no kernel for this
    model (the slip level, algorithm 1: their own Python), note saying why).

    ``compiled``: None = compiled when numba runs and MTA_SIM_NO_JIT is not set; True = required
    (ImportError if numba cannot run); False = plain Python."""
    if not model.has_kernel:
        return None, "Python model (no kernel for this level and algorithm)"
    if compiled is False:
        return False, "kernels as plain Python (compiled=False)"
    if compiled is None and os.environ.get(NO_JIT_ENV, "").strip() not in ("", "0"):
        return False, f"kernels as plain Python ({NO_JIT_ENV}={os.environ[NO_JIT_ENV]})"
    if not jit.ENABLED:
        if compiled:
            raise ImportError(f"compiled=True: {jit.NOTE}")
        return False, f"kernels as plain Python ({jit.NOTE})"
    return True, f"compiled kernels ({jit.NOTE})"


def table_value(table: Table, t: float) -> float:
    """Piecewise-linear interpolation, held constant outside the table."""
    return float(table_values(table, t))


def table_values(table: Table, t):
    """``table_value`` at every time of the array ``t`` (np.interp: the same numbers point by point)."""
    return np.interp(t, table.time, table.value)


def initial_state(scene: Scene, model: Model) -> np.ndarray:
    """The state at t = 0: the scene's pose and speed, the train straight unless hitch angles
    are given, and the governor's integral set so the train starts in equilibrium at its speed
    (integral = the traction that balances the resistances, the grade's on a slope included,
    Terms.balance; past the governor's limit min(max_force, max_power / V) the force is clipped there
    from the start and the train leaves its speed, while the anti-windup brings the integral back to
    the limit within about windup_time)."""
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
        # past the limit the force is clipped from the start; the integral is not: held at the limit
        # it would put u on the clip's switching surface, where the first step takes the unclipped side
        y[L.governor] = tm.balance - scene.train.traction.kp * (v_set - ini.speed)
    return y


def start_state(scene: Scene, model: Level) -> np.ndarray:
    """The state at t = 0 for a model of any fidelity level: the dynamic level's initial_state,
    converted by the level's from_dynamic_state (kinematic: V' = 0; slip: u = G V, no slip yet)."""
    return model.from_dynamic_state(initial_state(scene, model.dynamic))


def speed_setpoint(scene: Scene, t: float) -> float:
    """The scene's speed set-point at t, or the traction law's default."""
    return float(speed_setpoints(scene, t))


def speed_setpoints(scene: Scene, t):
    """``speed_setpoint`` at every time of the array ``t``."""
    if scene.speed is None:
        return np.full(np.shape(t), scene.train.traction.set_speed)
    return table_values(scene.speed, t)


class Simulation:
    """One train in one scene, advanced tick by tick with held inputs."""

    def __init__(self, scene: Scene, method: str | None = None, step: float | None = None,
                 rate: float | None = None, algorithm: int = 2, substep: bool = True,
                 fidelity: str | None = None, compiled: bool | None = None, split_kinks: bool | None = None,
                 tolerances: tuple[float, float] | None = None):
        """``compiled``: run the kernels (model/kernel.py: the dynamic and kinematic levels with
        algorithm 2) compiled by numba, or as plain Python: None (default) = compiled when numba
        runs and the environment does not set MTA_SIM_NO_JIT=1, True = required, False = Python;
        the same numbers either way. ``self.compiled`` says which runs (None: a level without
        kernels), ``compiled_note`` why, ``compile_time`` the seconds the first compilation (or
        load from numba's disk cache) took here.

        ``split_kinks``: split each step where the right-hand side is not smooth (the actuator's
        rate limit letting go, a force limit engaging; integrate/steppers.py); None = the scene's
        ``integrator.split_kinks`` (default true). ``tolerances``: (rtol, atol) of an adaptive
        method in place of the scene's (the slip level's own; a run's companion, run/accuracy.py).

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
        self.model: Level = make_level(self.level, scene.train, algorithm)
        # the implement lowered (the train as given) or lifted (its draft off): two constant levels,
        # each built once, the one held chosen per tick (set_lowered), as the rate limit is held
        self._algorithm = algorithm
        self.levels = {True: self.model}  # the lifted level is built when first held (set_lowered)
        self.lowered = True
        integ = scene.integrator
        self.rtol, self.atol = integ.rtol, integ.atol
        if self.level == "slip":  # the scene's method and tolerances are for the no-slip levels
            from ..physics import slip

            self.rtol, self.atol = slip.DEFAULT_RTOL, slip.DEFAULT_ATOL
            if method is None:
                method, step = slip.DEFAULT_METHOD, step or 1.0 / (rate or scene.publish_rate)
        if tolerances is not None:  # an adaptive method's rtol, atol in place of the scene's (or slip's)
            self.rtol, self.atol = (float(t) for t in tolerances)
        self.method = method or integ.method
        self.split_kinks = integ.split_kinks if split_kinks is None else bool(split_kinks)
        self.tick = 1.0 / (rate or scene.publish_rate)
        self.compiled, self.compiled_note = kernel_path(self.model, compiled)
        self.step = step or integ.step or self._step_for_tolerance(rate, algorithm, compiled)
        make_stepper(self.method, self.step, self.rtol, self.atol)  # a bad method fails here, not at reset
        # with kinks split, a kernel model's fixed-step tick takes the actuator in closed form
        # (rk.rk_step): its fast mode then limits neither stability nor accuracy, but the step
        # must resolve its time constant (stability.resolved_step)
        self.exact_actuator = self.split_kinks and self.compiled is not None and self.method in FIXED_METHODS
        self.stepper_step, self.stability_note = stable_step(
            self.method, self.step, self.tick, fast_modes(scene.train, actuator=not self.exact_actuator))
        unstable = self.stability_note
        if unstable and not substep:
            raise UnstableStepError(unstable.replace(
                "; sub-stepping at", "; refusing to run it (substep=True would sub-step at") + ")")
        if self.exact_actuator:
            self.stepper_step, resolution = resolved_step(self.stepper_step, self.tick,
                                                          scene.train.actuator.time_constant)
            if resolution:
                self.stability_note = "; ".join(filter(None, (self.stability_note, resolution)))
        self._check_steps_per_tick()  # before the warning: a refused run says one thing
        if unstable:
            warnings.warn(unstable, RuntimeWarning, stacklevel=2)
        self._rhs = self._rhs_of(self.model)
        self.compile_time = 0.0
        self.reset()
        if self.compiled:  # compile (or load from numba's cache) now, not in the first tick
            t_c = time.perf_counter()
            self._warm_up()
            self.compile_time = time.perf_counter() - t_c
            self.compiled_note += f", first call {self.compile_time:.3g} s"

    def _step_for_tolerance(self, rate, algorithm, compiled) -> float:
        """A scene that gives no step: for a fixed-step method on a kernel model, the step that meets
        its tolerance (accuracy.chosen_step: a few whole runs of the scene's own inputs); else the
        tick (an adaptive method's largest step)."""
        if self.method not in FIXED_METHODS or self.compiled is None:
            return self.tick
        from .accuracy import chosen_step

        return chosen_step(self.scene, method=self.method, rate=rate, algorithm=algorithm, fidelity=self.level,
                           compiled=compiled, split_kinks=self.split_kinks)

    def _rhs_of(self, model: Level):
        """The right-hand side of the adaptive methods and of the slip level, for ``model``."""
        if self.compiled is False:
            P = model.P
            return lambda t, y, c, v, r: kernel.rhs_of.py_func(P, np.asarray(y, dtype=np.float64), float(c), float(v),
                                                               r)
        return model.rhs

    def _check_steps_per_tick(self) -> None:
        """Refuse a tick of more than validate.MAX_STEPS_PER_TICK steps (a step given that short,
        or cut that short for stability by a stiff train): such a tick would not end."""
        n = validate.steps_per_tick(self.tick, self.stepper_step)
        if n > validate.MAX_STEPS_PER_TICK:
            why = f" ({self.stability_note})" if self.stability_note else ""
            raise validate.InputError(
                f"integrator step: {self.stepper_step:.4g} s{why} must be at least tick / "
                f"{validate.MAX_STEPS_PER_TICK} = {self.tick / validate.MAX_STEPS_PER_TICK:.4g} s: it takes {n:.4g} "
                f"steps per {self.tick:g} s tick")

    def _warm_up(self) -> None:
        y = np.ascontiguousarray(self.y, dtype=np.float64)
        P, rate = self.model.P, self.max_rate
        rk.tick(P, FixedStep("rk4", 1.0).tableau.packed, y, 0.0, 0.0, rate, 0.0, 1e-3, 1e-3, True)
        kernel.rhs_of(P, y, 0.0, 0.0, rate)
        kernel.outputs_of(self.model.P_outputs, y, 0.0, 0.0, rate)
        kernel.pulls_of(self.model.P_outputs, y, 0.0, 0.0, rate)  # the margins' constraint forces (run/margins.py)
        kernel.margin_of(P, y)
        kernel.switches_of(P, y, 0.0, 0.0)
        kernel.release_of(P, 0.0, 0.0, rate)

    def reset(self) -> None:
        """Back to the scene's start, with a fresh stepper (an adaptive one forgets its last step,
        so a run after a reset is the same as the first)."""
        self.stepper = make_stepper(self.method, self.stepper_step, self.rtol, self.atol, self.split_kinks)
        self._kernel_ticks = self.compiled is not None and isinstance(self.stepper, FixedStep)
        self.ticks = 0
        self.set_lowered(True)
        self.y = start_state(self.scene, self.model)
        self.command = self.scene.initial.steering
        self.v_set = speed_setpoint(self.scene, 0.0)
        self.rate_limit: float | None = None

    def set_lowered(self, lowered: bool) -> None:
        """Hold the implement lowered (True: the train as given, the scene's start) or lifted
        (False: its draft off, physics.levels.lifted) from the next tick on: an input beside the
        command, the set-point and the rate limit. The run switches between two levels built once;
        neither is changed. A train without an implement has one level for both."""
        lowered = bool(lowered)
        if lowered == self.lowered and self.model is self.levels[lowered]:
            return  # held as it was: nothing to do on the tick's path
        if lowered not in self.levels:
            lift = lifted(self.scene.train)
            self.levels[False] = self.levels[True] if lift is self.scene.train else make_level(
                self.level, lift, self._algorithm)
        self.lowered = lowered
        self.model = self.levels[lowered]
        self._rhs = self._rhs_of(self.model)

    @property
    def t(self) -> float:
        return self.ticks * self.tick

    @property
    def kernel_ticks(self) -> bool:
        """Whether a tick is one kernel call (a kernel model on a fixed-step method): what a whole
        run in one call (batch.run_trace) takes too."""
        return self._kernel_ticks

    def set_rate_limit(self, rate: float | None) -> None:
        """Hold the steering actuator's rate limit ``rate`` (rad/s; None: the train's own max_rate)
        from the next tick on, an input beside the command and the set-point: psi_1' =
        clip((clip(command, +-max_angle) - psi_1) / time_constant, +-rate), the actuator law of
        docs/model.md with ``rate`` in place of max_rate (ackermann_cmd's steering_angle_velocity,
        commands.ackermann_setting). The stability and step limits of the run depend on the time
        constant only, so they hold. The model is not changed."""
        self.rate_limit = None if rate is None else float(rate)

    @property
    def max_rate(self) -> float:
        """The steering rate limit held now, rad/s (``set_rate_limit``)."""
        return kernel.max_rate_of(self.model.P, self.rate_limit)

    @property
    def kinks(self) -> int:
        """Kinks the stepper split at so far (since the last reset)."""
        return self.stepper.kinks

    def scheduled_inputs(self, t: float) -> tuple[float, float]:
        """The scene's own steering command and speed set-point at t."""
        return table_value(self.scene.steering, t), speed_setpoint(self.scene, t)

    def advance(self, command: float, v_set: float) -> np.ndarray:
        """Advance one tick holding (command, v_set); raise ModelValidityError past the model's
        validity (the state before the failing tick is kept)."""
        t0 = self.t
        t1 = t0 + self.tick
        model, rate = self.model, self.max_rate
        y0 = model.begin_tick(self.y, v_set, self.tick)
        if self._kernel_ticks:  # one kernel call a tick
            y1, clear = self.stepper.tick(model.P, y0, t0, t1, command, v_set, rate, self.compiled)
            if not clear:  # non-finite or near a jackknife limit: the Python check decides and says why
                check_state(model, t1, y1)
        else:
            rhs = self._rhs

            def f(t, y):
                return rhs(t, y, command, v_set, rate)

            if isinstance(self.stepper, FixedStep):
                y1 = self.stepper.advance(f, t0, y0, t1)
            else:
                held = None if self.compiled is None else Held(model.P, command, v_set, rate, self.compiled)
                y1 = self.stepper.tick(f, t0, y0, t1, release=self._release(y0, command), held=held)
            check_state(model, t1, y1)
        self.y = y1
        self.ticks += 1
        self.command, self.v_set = command, v_set
        return y1

    def _release(self, y, command: float) -> float:
        """When the actuator's rate limit lets go in this tick, from its start (s; inf: it does not)."""
        return float(kernel.release_of(self.model.P, float(y[self.model.layout.steering]), float(command),
                                       self.max_rate))

    def outputs(self) -> Outputs:
        """What the run reports now: the level's outputs under the input held over the last tick."""
        return self.model.outputs(self.t, self.y, self.command, self.v_set, self.rate_limit,
                                  compiled=self.compiled is not False)


def run_scene(scene: Scene, on_output=None, on_state=None, **options) -> tuple[Simulation, Exception | None]:
    """Run the scene to its end with its own inputs, calling on_output(Outputs) at t = 0 and
    after every tick, then on_state(the Simulation) (what else a caller reads of the state: its
    margins, run/margins.py). Returns the simulation and the error that stopped it early, if any
    (the outputs already passed on stay valid)."""
    sim = Simulation(scene, **options)

    def report() -> None:
        if on_output:
            on_output(sim.outputs())
        if on_state:
            on_state(sim)

    report()
    ticks = int(math.floor(scene.duration / sim.tick + 1e-9))
    while sim.ticks < ticks:
        command, v_set = sim.scheduled_inputs(sim.t)
        try:
            sim.advance(command, v_set)
        except (ModelValidityError, IntegrationError) as err:
            return sim, err
        report()
    return sim, None
