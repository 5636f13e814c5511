"""Steppers: integrate y' = f(y, held input) over one tick, with the input held (zero-order hold).

A run advances once per tick with the input held, exactly as the node does, so an offline run and
the node agree for the same command sequence. ``nfev`` counts the right-hand-side evaluations,
the cost measure that does not depend on the machine; ``kinks`` counts the points where a step
was split because the right-hand side is not smooth there.

Fixed-step methods are tableaux (``tableau.py``) stepped by one routine, ``model.kernel.advance``:
for a model with a kernel (``tick``: the dynamic and kinematic levels) the whole tick runs in one
call, compiled, or as plain Python on request; for any other right-hand side (``advance(fun, ...)``:
the slip level, a benchmark's time-dependent input) the same routine runs as Python around the
callable. Adaptive methods are scipy's OdeSolver classes, restarted at every tick (the input
changes there) and at every kink.

Kinks (``split_kinks``): where the steering actuator's rate limit lets go the steering rate has
a corner, and so do the force laws where a limit engages (``model.kernel.switches``). A method
stepping straight across one keeps only first-order accuracy in that step, and an adaptive
method's error control can accept such a step; splitting the step there keeps each method's
order. The actuator's release is known in closed form at the start of a tick; the force-law
switches are located along the step.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ..model import kernel
from ..model.spec import INTEGRATOR_METHODS
from .tableau import TABLEAUX

Fun = Callable[[float, np.ndarray], np.ndarray]

FIXED_METHODS = tuple(TABLEAUX)
ADAPTIVE_METHODS = ("RK45", "DOP853", "LSODA", "Radau", "BDF")
METHODS = FIXED_METHODS + ADAPTIVE_METHODS
assert set(METHODS) == set(INTEGRATOR_METHODS), "spec.INTEGRATOR_METHODS names every method of integrate/"

_NO_PARAMS = np.zeros(0)


class IntegrationError(RuntimeError):
    """The integrator could not advance (an adaptive solver failed)."""


def _callable_rhs(fun: Fun):
    """``fun(t, y)`` in the stepping routine's form f(P, t, y, command, v_set, dy, rec)."""
    def f(P, t, y, command, v_set, dy, rec):
        dy[:] = fun(t, y)
    return f


class FixedStep:
    """A fixed-step explicit Runge-Kutta method given by its tableau. The tick is split into
    ceil(tick / step) equal steps no longer than ``step``."""

    def __init__(self, method: str, step: float, split_kinks: bool = True):
        if method not in TABLEAUX:
            raise ValueError(f"method: {method!r} is not one of {FIXED_METHODS}")
        if not step > 0.0:
            raise ValueError(f"step: {step} must be > 0")
        self.method = method
        self.tableau = TABLEAUX[method]
        self.step = float(step)
        self.split_kinks = split_kinks
        self._T = self.tableau.packed
        self.nfev = 0
        self.kinks = 0

    def tick(self, P: np.ndarray, y0: np.ndarray, t0: float, t1: float, command: float, v_set: float,
             compiled: bool = True) -> tuple[np.ndarray, bool]:
        """The model with packed constants P (``model.kernel.pack``) from t0 to t1 with (command,
        v_set) held, in one call: (y1, clear), clear = y1 is finite and clearly inside the jackknife
        limits (``model.kernel.clear``; otherwise the caller runs ``guards.check_state``).
        ``compiled`` = False runs the kernel as plain Python (the same numbers)."""
        run = kernel.tick if compiled else kernel.tick.py_func
        y1, clear, nfev, kinks = run(P, self._T, np.ascontiguousarray(y0, dtype=np.float64), float(command),
                                     float(v_set), float(t0), float(t1), self.step, self.split_kinks)
        self.nfev += nfev
        self.kinks += kinks
        return y1, bool(clear)

    def advance(self, fun: Fun, t0: float, y0: np.ndarray, t1: float) -> np.ndarray:
        """y' = fun(t, y) from t0 to t1 (any callable; no kink information: none are split)."""
        y, nfev, _ = kernel.advance(_callable_rhs(fun), kernel.no_switches, _NO_PARAMS, self._T,
                                    np.array(y0, dtype=float), 0.0, 0.0, float(t0), float(t1), float(self.step),
                                    False)
        self.nfev += nfev
        return y


class Adaptive:
    """scipy.integrate's OdeSolver ``method`` with tolerances rtol, atol and step <= max_step.

    ``tick`` splits at kinks: at the actuator's release (closed form), and where a force-law
    switching function changes sign between two accepted steps it is located on the step (dense
    output, then refined by re-integrating from the last point before it), the solver is stopped
    there and restarted, so no accepted step crosses a kink."""

    def __init__(self, method: str, rtol: float, atol: float, max_step: float = math.inf, split_kinks: bool = True):
        if method not in ADAPTIVE_METHODS:
            raise ValueError(f"method: {method!r} is not one of {ADAPTIVE_METHODS}")
        self.method = method
        self.rtol, self.atol, self.max_step = rtol, atol, max_step
        self.split_kinks = split_kinks
        self.nfev = 0
        self.kinks = 0
        # imported here, not at module level: scipy.integrate is ~50 MB resident that a run with a
        # fixed-step method never needs (docs/benchmarks/scaling.md, the 1-hour run's memory)
        from scipy import integrate as sp

        self._solver_class = getattr(sp, method)
        self._last_step: float | None = None

    def _solver(self, fun: Fun, t0: float, y0: np.ndarray, t1: float):
        first = None if self._last_step is None else min(self._last_step, t1 - t0)
        return self._solver_class(fun, t0, np.asarray(y0, dtype=float), t1, rtol=self.rtol, atol=self.atol,
                                  max_step=self.max_step, first_step=first)

    def _run(self, solver, switch=None):
        """Step ``solver`` to its t_bound; with ``switch`` (y -> switching function values), stop
        at the first step after which one changed sign: (t_before, y_before, t_after) of that step,
        else None."""
        g_before = None if switch is None else switch(solver.y)
        while solver.status == "running":
            t_before, y_before = solver.t, solver.y.copy()
            message = solver.step()
            if solver.status == "failed":
                self.nfev += solver.nfev
                raise IntegrationError(f"{self.method} failed at t = {solver.t:.6g} s: {message}")
            if switch is not None:
                g_after = switch(solver.y)
                if np.any((g_before > 0.0) != (g_after > 0.0)):
                    return t_before, y_before, solver
                g_before = g_after
        # The solver's own proposal for its next step (h_abs), not the last step, which was cut
        # short to land on t1. LSODA keeps no h_abs; its last step serves.
        self._last_step = getattr(solver, "h_abs", None) or solver.step_size
        self.nfev += solver.nfev
        return None

    def advance(self, fun: Fun, t0: float, y0: np.ndarray, t1: float) -> np.ndarray:
        """y' = fun(t, y) from t0 to t1, no kinks split."""
        solver = self._solver(fun, t0, y0, t1)
        self._run(solver)
        return solver.y.copy()

    def tick(self, fun: Fun, t0: float, y0: np.ndarray, t1: float, switch=None, release: float = math.inf):
        """One tick of a model: ``fun`` with the input held, ``switch(y)`` its switching functions
        (or None), ``release`` the actuator's release time from t0 (s, inf for none)."""
        if not self.split_kinks:
            return self.advance(fun, t0, y0, t1)
        bounds = [t0, t1]
        if 1e-12 * (t1 - t0) < release < (1.0 - 1e-12) * (t1 - t0):
            bounds.insert(1, t0 + release)
            self.kinks += 1
        y = np.asarray(y0, dtype=float)
        for a, b in zip(bounds[:-1], bounds[1:]):
            y = self._piece(fun, a, y, b, switch)
        return y

    def _piece(self, fun: Fun, t0: float, y0: np.ndarray, t1: float, switch) -> np.ndarray:
        """From t0 to t1 (no actuator release inside), stopping and restarting at each switch."""
        t, y = t0, np.asarray(y0, dtype=float)
        for _ in range(64):  # at most this many switches in one piece
            solver = self._solver(fun, t, y, t1)
            crossed = self._run(solver, switch)
            if crossed is None:
                return solver.y.copy()
            t_before, y_before, stepped = crossed
            self.nfev += stepped.nfev
            t, y = self._to_switch(fun, t_before, y_before, stepped, switch)
            self.kinks += 1
            if t >= t1 - 1e-12 * (t1 - t0):
                return y
        return self.advance(fun, t, y, t1)

    def _to_switch(self, fun: Fun, t_before: float, y_before: np.ndarray, stepped, switch):
        """(t*, y(t*)) just past the first sign change of a switching function in the step
        (t_before, stepped.t], integrated from (t_before, y_before) so that no step crosses it."""
        from scipy.optimize import brentq

        g0 = switch(y_before)
        g1 = switch(stepped.y)
        dense = stepped.dense_output()
        j = int(np.argmax((g0 > 0.0) != (g1 > 0.0)))

        def along(t):
            return self._integrate(fun, t_before, y_before, t) if t > t_before else y_before

        def g_dense(t):
            return float(switch(dense(t))[j])

        # first estimate from the dense output (inaccurate across the kink), then refine with
        # integrations from y_before that stop at the trial time, which cross no kink before t*
        t_est = brentq(g_dense, t_before, stepped.t, xtol=1e-14, rtol=1e-15) if g_dense(t_before) * g_dense(
            stepped.t) < 0 else 0.5 * (t_before + stepped.t)
        lo, hi = t_before, stepped.t
        far = g1[j] > 0.0
        f_lo, f_hi = g0[j], g1[j]
        t = t_est
        side = 0
        y_hi = stepped.y.copy()
        for _ in range(60):
            if hi - lo <= 4e-16 * max(abs(hi), 1.0):
                break
            if not lo < t < hi:
                t = 0.5 * (lo + hi)
            y_t = along(t)
            lo, hi, f_lo, f_hi, side = kernel.illinois_update(lo, hi, f_lo, f_hi, side, t, float(switch(y_t)[j]), far)
            if hi == t:
                y_hi = y_t
            t = kernel.illinois_point(lo, hi, f_lo, f_hi)
        return hi, y_hi

    def _integrate(self, fun: Fun, t0: float, y0: np.ndarray, t1: float) -> np.ndarray:
        solver = self._solver_class(fun, t0, np.asarray(y0, dtype=float), t1, rtol=self.rtol, atol=self.atol,
                                    max_step=self.max_step)
        while solver.status == "running":
            message = solver.step()
            if solver.status == "failed":
                raise IntegrationError(f"{self.method} failed at t = {solver.t:.6g} s: {message}")
        self.nfev += solver.nfev
        return solver.y.copy()


def make_stepper(method: str, step: float = 0.01, rtol: float = 1e-8, atol: float = 1e-10, split_kinks: bool = True):
    """A stepper by name (``METHODS``): fixed ones use ``step``, adaptive ones rtol/atol with
    ``step`` as their largest step."""
    if method in FIXED_METHODS:
        return FixedStep(method, step, split_kinks)
    return Adaptive(method, rtol, atol, max_step=step, split_kinks=split_kinks)
