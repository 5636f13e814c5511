"""Steppers: ``advance(fun, t0, y0, t1) -> y1`` integrates y' = fun(t, y) from t0 to t1.

A run calls ``advance`` once per tick with the input held (zero-order hold), exactly as the node
does, so an offline run and the node agree for the same command sequence. ``nfev`` counts the
right-hand-side evaluations, the cost measure that does not depend on the machine.

Fixed-step methods split the interval into equal steps no longer than ``step``. Adaptive methods
are scipy's OdeSolver classes, restarted at every tick (the input changes there, so the right-hand
side is only smooth between ticks); the step size the solver proposed last seeds the next tick's.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

Fun = Callable[[float, np.ndarray], np.ndarray]

FIXED_METHODS = ("euler", "heun", "rk4")
ADAPTIVE_METHODS = ("RK45", "DOP853", "LSODA", "Radau", "BDF")
METHODS = FIXED_METHODS + ADAPTIVE_METHODS


class IntegrationError(RuntimeError):
    """The integrator could not advance (an adaptive solver failed)."""


class FixedStep:
    """Explicit Runge-Kutta with a fixed step: Euler (order 1), Heun (2), classic RK4 (4).

    ``attach(compiled)`` (a ``model.compiled.CompiledModel``) adds ``advance_held``: a whole tick
    of the same method in compiled code, for a model with a compiled form and a held input;
    ``compiled`` is then set and ``compiled_ticks`` counts the ticks it ran. ``advance`` is
    unchanged either way (the Python reference)."""

    STAGES = {"euler": 1, "heun": 2, "rk4": 4}

    def __init__(self, method: str, step: float):
        if method not in FIXED_METHODS:
            raise ValueError(f"method: {method!r} is not one of {FIXED_METHODS}")
        if not step > 0.0:
            raise ValueError(f"step: {step} must be > 0")
        self.method = method
        self.step = step
        self.nfev = 0
        self._one_step = getattr(self, "_" + method)
        self.compiled = None
        self.compiled_ticks = 0

    def attach(self, compiled) -> None:
        """Run ticks through ``compiled`` (a model.compiled.CompiledModel) in ``advance_held``."""
        from ..model.compiled import METHOD_CODES

        self.compiled = compiled
        self._code = METHOD_CODES[self.method]

    def advance_held(self, t0: float, y0: np.ndarray, t1: float, command: float, v_set: float):
        """``advance`` of the attached compiled model's y' = rhs(y, command, v_set) from t0 to t1,
        with the same steps; returns (y1, clear), clear = y1 is finite and clearly inside the
        jackknife limits (``model.compiled._clear``; otherwise run ``guards.check_state``)."""
        count = max(1, math.ceil((t1 - t0) / self.step - 1e-9))
        self.nfev += self.STAGES[self.method] * count
        self.compiled_ticks += 1
        return self.compiled.tick(self._code, y0, command, v_set, (t1 - t0) / count, count)

    def advance(self, fun: Fun, t0: float, y0: np.ndarray, t1: float) -> np.ndarray:
        count = max(1, math.ceil((t1 - t0) / self.step - 1e-9))
        h = (t1 - t0) / count
        y = np.asarray(y0, dtype=float)
        for i in range(count):
            y = self._one_step(fun, t0 + i * h, y, h)
        return y

    def _euler(self, f, t, y, h):
        self.nfev += 1
        return y + h * f(t, y)

    def _heun(self, f, t, y, h):
        self.nfev += 2
        k1 = f(t, y)
        k2 = f(t + h, y + h * k1)
        return y + 0.5 * h * (k1 + k2)

    def _rk4(self, f, t, y, h):
        self.nfev += 4
        k1 = f(t, y)
        k2 = f(t + 0.5 * h, y + 0.5 * h * k1)
        k3 = f(t + 0.5 * h, y + 0.5 * h * k2)
        k4 = f(t + h, y + h * k3)
        return y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


class Adaptive:
    """scipy.integrate's OdeSolver ``method`` with tolerances rtol, atol and step <= max_step."""

    def __init__(self, method: str, rtol: float, atol: float, max_step: float = math.inf):
        if method not in ADAPTIVE_METHODS:
            raise ValueError(f"method: {method!r} is not one of {ADAPTIVE_METHODS}")
        self.method = method
        self.rtol, self.atol, self.max_step = rtol, atol, max_step
        self.nfev = 0
        # imported here, not at module level: scipy.integrate is ~50 MB resident that a run with a
        # fixed-step method never needs (docs/benchmarks/scaling.md, the 1-hour run's memory)
        from scipy import integrate as sp

        self._solver_class = getattr(sp, method)
        self._last_step: float | None = None

    def advance(self, fun: Fun, t0: float, y0: np.ndarray, t1: float) -> np.ndarray:
        first = None if self._last_step is None else min(self._last_step, t1 - t0)
        solver = self._solver_class(
            fun, t0, np.asarray(y0, dtype=float), t1,
            rtol=self.rtol, atol=self.atol, max_step=self.max_step, first_step=first,
        )
        while solver.status == "running":
            message = solver.step()
            if solver.status == "failed":
                self.nfev += solver.nfev
                raise IntegrationError(f"{self.method} failed at t = {solver.t:.6g} s: {message}")
        # The solver's own proposal for its next step (h_abs), not the last step, which was cut
        # short to land on t1. LSODA keeps no h_abs; its last step serves.
        self._last_step = getattr(solver, "h_abs", None) or solver.step_size
        self.nfev += solver.nfev
        return solver.y.copy()


def make_stepper(method: str, step: float = 0.01, rtol: float = 1e-8, atol: float = 1e-10):
    """A stepper by name (``METHODS``): fixed ones use ``step``, adaptive ones rtol/atol with
    ``step`` as their largest step."""
    if method in FIXED_METHODS:
        return FixedStep(method, step)
    return Adaptive(method, rtol, atol, max_step=step)
