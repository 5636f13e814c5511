"""Steppers: integrate y' = f(y, held input) over one tick, with the input held (zero-order hold).

A run advances once per tick with the input held, exactly as the node does, so an offline run and
the node agree for the same command sequence. ``nfev`` counts the right-hand-side evaluations,
the cost measure that does not depend on the machine; ``kinks`` counts the points where a step
was split because the right-hand side is not smooth there.

Fixed-step methods are tableaux (``tableau.py``) stepped by one routine, ``rk.advance``:
for a model with a kernel (``tick``: the dynamic and kinematic levels) the whole tick runs in one
call, compiled, or as plain Python on request; for any other right-hand side (``advance(fun, ...)``:
the slip level, a benchmark's time-dependent input) the same routine runs as Python around the
callable. Adaptive methods are scipy's OdeSolver classes, restarted at every tick (the input
changes there) and at every kink.

Kinks (``split_kinks``): where the steering actuator's rate limit lets go the steering rate has
a corner, and so do the force laws where a limit engages (``physics.kernel.switches``). A method
stepping straight across one keeps only first-order accuracy in that step, and an adaptive
method's error control can accept such a step; splitting the step there keeps each method's
order. The actuator's release is known in closed form at the start of a tick; the force-law
switches are located along the step.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ..physics import kernel
from . import rk
from ..physics.spec import INTEGRATOR_METHODS
from ..validate import MAX_STEPS_PER_TICK
from .tableau import TABLEAUX, Tableau

Fun = Callable[[float, np.ndarray], np.ndarray]

FIXED_METHODS = tuple(TABLEAUX)
ADAPTIVE_METHODS = ("RK45", "DOP853", "LSODA", "Radau", "BDF")
METHODS = FIXED_METHODS + ADAPTIVE_METHODS
assert set(METHODS) == set(INTEGRATOR_METHODS), "spec.INTEGRATOR_METHODS names every method of integrate/"

_NO_PARAMS = np.zeros(0)


class IntegrationError(RuntimeError):
    """The integrator could not advance (an adaptive solver failed)."""


def _callable_rhs(fun: Fun):
    """``fun(t, y)`` in the stepping routine's form f(P, t, y, command, v_set, max_rate, dy, rec, mode)."""
    def f(P, t, y, command, v_set, max_rate, dy, rec, mode):
        dy[:] = fun(t, y)
    return f


class FixedStep:
    """A fixed-step explicit Runge-Kutta method given by its tableau (a name of ``TABLEAUX``, or a
    ``Tableau``). The tick is split into ceil(tick / step) equal steps no longer than ``step``."""

    def __init__(self, method: str | Tableau, step: float, split_kinks: bool = True):
        if isinstance(method, Tableau):
            self.tableau = method
        elif method in TABLEAUX:
            self.tableau = TABLEAUX[method]
        else:
            raise ValueError(f"method: {method!r} is not one of {FIXED_METHODS}")
        if not step > 0.0:
            raise ValueError(f"step: {step} must be > 0")
        self.method = self.tableau.name
        self.step = float(step)
        self.split_kinks = split_kinks
        self._T = self.tableau.packed
        self.nfev = 0
        self.kinks = 0

    def tick(self, P: np.ndarray, y0: np.ndarray, t0: float, t1: float, command: float, v_set: float,
             max_rate: float, compiled: bool = True) -> tuple[np.ndarray, bool]:
        """The model with packed constants P (``physics.kernel.pack``) from t0 to t1 with the input
        (command, v_set, max_rate) held, in one call: (y1, clear), clear = y1 is finite and clearly inside the jackknife
        limits (``physics.kernel.clear``; otherwise the caller runs ``guards.check_state``).
        ``compiled`` = False runs the kernel as plain Python (the same numbers)."""
        run = rk.tick if compiled else rk.tick.py_func
        y1, clear, nfev, kinks = run(P, self._T, np.ascontiguousarray(y0, dtype=np.float64), float(command),
                                     float(v_set), float(max_rate), float(t0), float(t1), self.step,
                                     self.split_kinks)
        self.nfev += nfev
        self.kinks += kinks
        return y1, bool(clear)

    def advance(self, fun: Fun, t0: float, y0: np.ndarray, t1: float) -> np.ndarray:
        """y' = fun(t, y) from t0 to t1 (any callable; no kink information: none are split)."""
        y, nfev, _ = rk.advance(_callable_rhs(fun), kernel.no_switches, _NO_PARAMS, self._T,
                                np.array(y0, dtype=float), 0.0, 0.0, 0.0, float(t0), float(t1), float(self.step),
                                False)
        self.nfev += nfev
        return y


class Held:
    """A kernel model's right-hand side with its non-smooth laws held on one branch each (see
    ``physics.kernel.rhs``): what an adaptive solver steps between two kinks."""

    def __init__(self, P: np.ndarray, command: float, v_set: float, max_rate: float, compiled: bool = True):
        self.P, self.command, self.v_set, self.max_rate = P, float(command), float(v_set), float(max_rate)
        pick = (lambda f: f) if compiled else (lambda f: f.py_func)
        self._rhs, self._mode, self._switches = pick(kernel.held_rhs_of), pick(kernel.mode_of), pick(kernel.switches_of)

    def rhs(self, mode: np.ndarray) -> Fun:
        P, c, v, r, run = self.P, self.command, self.v_set, self.max_rate, self._rhs
        return lambda t, y: run(P, np.ascontiguousarray(y, dtype=np.float64), c, v, r, mode)

    def mode(self, y: np.ndarray, rate_limited: bool) -> np.ndarray:
        return self._mode(self.P, np.ascontiguousarray(y, dtype=np.float64), self.command, self.v_set, rate_limited)

    def switches(self, y: np.ndarray) -> np.ndarray:
        return self._switches(self.P, np.ascontiguousarray(y, dtype=np.float64), self.command, self.v_set)


class Adaptive:
    """scipy.integrate's OdeSolver ``method`` with tolerances rtol, atol and step <= max_step.

    ``tick`` splits at kinks: at the actuator's release (closed form) and, for a kernel model
    (``Held``), where a force-law switching function changes sign: each piece is integrated with
    the laws held on the branches it starts on (a smooth right-hand side), a sign change after an
    accepted step is located on the step's dense output, the piece is finished there exactly, and
    the solver restarts on the new branch. No accepted step crosses a kink."""

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

    def _run(self, solver, switches=None, high=None):
        """Step ``solver`` to its t_bound; with ``switches`` (y -> switching function values) and
        ``high`` (the held branches: which are > 0), stop after the first step that ends with one
        on the other side and return (t, y) before that step and the switching values after it;
        else None."""
        steps = 0
        while solver.status == "running":
            steps += 1
            if steps > MAX_STEPS_PER_TICK:  # a model too stiff for the method: the tick would not end
                self.nfev += solver.nfev
                raise IntegrationError(f"{self.method} took more than {MAX_STEPS_PER_TICK} steps in one tick at "
                                       f"t = {solver.t:.6g} s (last step {solver.step_size or 0:.3g} s): the model "
                                       f"is too stiff for it")
            t_before, y_before = solver.t, solver.y.copy()
            message = solver.step()
            if solver.status == "failed":
                self.nfev += solver.nfev
                raise IntegrationError(f"{self.method} failed at t = {solver.t:.6g} s: {message}")
            if switches is not None:
                g_after = switches(solver.y)
                if np.any((g_after > 0.0) != high):
                    self.nfev += solver.nfev
                    return t_before, y_before, g_after
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

    def tick(self, fun: Fun, t0: float, y0: np.ndarray, t1: float, release: float = math.inf,
             held: Held | None = None) -> np.ndarray:
        """One tick of a model: ``fun`` its right-hand side with the input held, ``release`` the
        actuator's release time from t0 (s, inf: it is not rate-limited), ``held`` its branches
        (a kernel model) or None.

        The ends, as ``rk.advance`` takes them (with the tick for its step): a release at most
        ``rk.EDGE`` (t1 - t0) after t0, or before it, is taken at t0 (released for the whole tick);
        one at most that before t1 is taken at t1 (rate-limited for the whole tick); only one
        between them is split at."""
        if not self.split_kinks:
            return self.advance(fun, t0, y0, t1)
        edge = rk.EDGE * (t1 - t0)
        pieces = [(t0, t1, edge < release < math.inf)]
        if edge < release < (t1 - t0) - edge:
            pieces = [(t0, t0 + release, True), (t0 + release, t1, False)]
            self.kinks += 1
        y = np.asarray(y0, dtype=float)
        for a, b, rate_limited in pieces:
            y = self.advance(fun, a, y, b) if held is None else self._held_piece(held, a, y, b, rate_limited)
        return y

    def _held_piece(self, held: Held, t0: float, y0: np.ndarray, t1: float, rate_limited: bool) -> np.ndarray:
        """From t0 to t1 on held branches, stopping and switching branch at each sign change."""
        from scipy.optimize import brentq

        t, y = t0, np.asarray(y0, dtype=float)
        mode = held.mode(y, rate_limited)
        for _ in range(64):  # at most this many switches in one piece; then the branches follow the state
            m = len(held.switches(y))
            high = mode[1:1 + m] == 1
            solver = self._solver(held.rhs(mode), t, y, t1)
            crossed = self._run(solver, held.switches, high)
            if crossed is None:
                return solver.y.copy()
            t_before, y_before, g_after = crossed
            dense = solver.dense_output()  # the step across the switch, on the held (smooth) branch
            j = int(np.argmax((g_after > 0.0) != high))

            def g_j(s):
                return float(held.switches(dense(s))[j])

            # the switch lies in the step; at its start the value may sit on the far side by rounding
            t_switch = brentq(g_j, t_before, solver.t, xtol=1e-15, rtol=1e-15) \
                if (g_j(t_before) > 0.0) == bool(high[j]) else t_before
            y = self._integrate(held.rhs(mode), t_before, y_before, t_switch)  # exactly to the switch
            t = t_switch
            mode = held.mode(y, rate_limited)
            mode[1 + j] = 1 if g_after[j] > 0.0 else 0  # the far side, whatever the rounding at the switch
            self.kinks += 1
            if t >= t1:
                return y
        return self.advance(held.rhs(held.mode(y, rate_limited)), t, y, t1)

    def _integrate(self, fun: Fun, t0: float, y0: np.ndarray, t1: float) -> np.ndarray:
        """y' = fun from t0 to t1 with a solver of its own (no step carried over)."""
        if not t1 > t0:
            return np.asarray(y0, dtype=float).copy()
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
