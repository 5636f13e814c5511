"""The one stepper, compiled: any explicit Runge-Kutta tableau, with each step split at the kinks of
the right-hand side (the actuator's release in closed form, the force laws' switches located along
the step), and a tick of the train in one call (``tick``).

``advance`` takes the right-hand side ``f`` and its switching functions ``sw`` as arguments: the
train's (``physics.kernel.motion.model_rhs``, ``switches``) or, run as plain Python, any callable
(``steppers.FixedStep.advance``)."""
from __future__ import annotations

import math

import numpy as np

from ..jit import entry, jitable
from ..physics.kernel.base import FORCE_SWITCHES, HIGH, LOW, NATURAL, REC, H, no_mode, pymin
from ..physics.kernel.laws import actuator_psi, actuator_release, branches
from ..physics.kernel.motion import clear, model_rhs, switches


@jitable
def rk_step(f, P, T, t, y, command, v_set, max_rate, h, K, tmp, out, rec, mode, lag):
    """One step of length h of the explicit tableau T from y into ``out``; returns the stages.

    ``lag`` = (on, psi0, command, release, T0): when on, the steering angle psi_1 is not stepped
    but taken from the actuator's closed form (``actuator_psi``) at each stage's time, T0 + c_i h
    after the tick's start: the actuator is a first-order lag of its own (nothing feeds back into
    it), so the train is stepped under its exact steering, and the actuator's fast pole -1/tau
    limits neither the accuracy nor the stability of the step.

    T (``integrate.tableau.Tableau.packed``) holds the tableau as the classic methods are
    printed, integer numerators over a common denominator per row: row i < s is (d_i, a_i0 ..
    a_i,s-1), stage i is y + (h / d_i) sum_j a_ij k_j; row s is (d, b_0 .. b_s-1), the step
    y + (h / d) sum_j b_j k_j; row s + 1 is (0, c_0 .. c_s-1). Sums run left to right over the
    non-zero entries: for euler, heun and rk4 the arithmetic of their textbook formulas, to the
    last bit."""
    stages = T.shape[0] - 2
    size = y.shape[0]
    exact = lag[0] != 0.0
    ip = int(P[H.n]) + 2 if exact else 0
    f(P, t, y, command, v_set, max_rate, K[0], rec, mode)
    for i in range(1, stages + 1):
        scale = h / T[i, 0]
        for m in range(size):
            acc = 0.0
            first = True
            for j in range(i if i < stages else stages):
                a = T[i, 1 + j]
                if a != 0.0:
                    term = a * K[j, m]
                    acc = term if first else acc + term
                    first = False
            value = y[m] if first else y[m] + scale * acc
            if i < stages:
                tmp[m] = value
            else:
                out[m] = value
        if i < stages:
            if exact:
                tmp[ip] = actuator_psi(P, lag[1], lag[2], max_rate, lag[3], lag[4] + T[stages + 1, 1 + i] * h)
            f(P, t + T[stages + 1, 1 + i] * h, tmp, command, v_set, max_rate, K[i], rec, mode)
    if exact:
        out[ip] = actuator_psi(P, lag[1], lag[2], max_rate, lag[3], lag[4] + h)
    return stages


#: most splits in one step (a switch crossed back and forth); past it the step is taken whole
MAX_SPLITS = 16
#: a kink closer than this share of a step to either end of it is at that end (no split)
EDGE = 1e-12


@jitable
def _changed(g0, g1, m, changed):
    """Which of the first m switching functions changed sign (> 0 against not > 0); how many."""
    count = 0
    for j in range(m):
        changed[j] = (g0[j] > 0.0) != (g1[j] > 0.0)
        if changed[j]:
            count += 1
    return count


@jitable
def illinois_point(lo, hi, f_lo, f_hi):
    """The next trial of the Illinois method (regula falsi) on the bracket [lo, hi]."""
    tau = (lo * f_hi - hi * f_lo) / (f_hi - f_lo) if f_hi != f_lo else 0.5 * (lo + hi)
    return tau if lo < tau < hi else 0.5 * (lo + hi)


@jitable
def illinois_update(lo, hi, f_lo, f_hi, side, tau, f_tau, far):
    """The bracket after a trial (tau, f_tau): the end whose sign it shares moves to it, and the
    other end's value is halved when the same end moved twice running (Illinois), which keeps
    the convergence superlinear. ``far`` is the sign (> 0) of the bracket's far end. Returns
    (lo, hi, f_lo, f_hi, side), side = +1 when hi moved, -1 when lo did."""
    if (f_tau > 0.0) == far:
        if side == 1:
            f_lo *= 0.5
        return lo, tau, f_lo, f_tau, 1
    if side == -1:
        f_hi *= 0.5
    return tau, hi, f_tau, f_hi, -1


@jitable
def _locate(f, sw, P, T, t, y, command, v_set, max_rate, h, j, g_lo, g_hi, K, tmp, trial, rec, mode, lag, g):
    """The step length in (0, h] at which switching function j changes sign along this method's
    step from y with the branches ``mode`` held (the Illinois method on tau -> g_j(step(y, tau))).
    Returns (tau on the far side of the switch, right-hand sides evaluated)."""
    lo, hi = 0.0, h
    f_lo, f_hi = g_lo, g_hi
    far = f_hi > 0.0
    side = 0
    nfev = 0
    for _ in range(100):
        if hi - lo <= 4e-16 * h + 1e-300:
            break
        tau = illinois_point(lo, hi, f_lo, f_hi)
        nfev += rk_step(f, P, T, t, y, command, v_set, max_rate, tau, K, tmp, trial, rec, mode, lag)
        sw(P, trial, command, v_set, g)
        lo, hi, f_lo, f_hi, side = illinois_update(lo, hi, f_lo, f_hi, side, tau, g[j], far)
    return hi, nfev


@jitable
def advance(f, sw, P, T, y0, command, v_set, max_rate, t0, t1, max_step, split):
    """Integrate from t0 to t1 with the input (command, v_set, max_rate) held: ceil((t1 - t0) / max_step) equal steps of the
    tableau T. Returns (y1, right-hand sides evaluated, kinks split at).

    With ``split``, each step runs on one branch of every non-smooth law (``mode``: the branch at
    the step's start, held for all its stages), and a step that holds a kink is cut there and
    finished from it on the new branch: at the actuator's release (closed form,
    ``actuator_release``) and where a switching function (``sw``) changes sign (located along the
    held-branch step, ``_locate``). Each piece then integrates a smooth right-hand side, and the
    method keeps its order. A kernel model's steering angle then follows the actuator's closed
    form (``actuator_psi``, see ``rk_step``). Without ``split`` every law follows the state and
    psi_1 is stepped like the rest (the code before kink splitting, bit for bit).

    The ends (h the step): a release at most ``EDGE`` h after a step's start, or before it, is
    taken at the start (released for the whole step); one at most EDGE h before the step's end is
    taken at the end (rate-limited for the whole step, released from the next on). So a release
    within EDGE h of a tick's start leaves the actuator released for the whole tick, and one within
    EDGE h of its end rate-limited for the whole tick, as inside it (``released``, ``until`` below)."""
    return advance_in(f, sw, P, T, y0, command, v_set, max_rate, t0, t1, max_step, split,
                      workspace(P, T, y0.shape[0]))


@jitable
def workspace(P, T, size):
    """The arrays ``advance_in`` works in: (K, tmp, y, y1, rec, lag, g0, g1, g, changed, mode, trial)."""
    n = int(P[H.n]) if P.shape[0] else 0
    width = FORCE_SWITCHES + n + 1
    return (np.empty((T.shape[0] - 2, size)), np.empty(size), np.empty(size), np.empty(size), np.empty((0, REC)),
            np.zeros(5), np.empty(width), np.empty(width), np.empty(width), np.zeros(width, dtype=np.bool_),
            np.full(1 + width, NATURAL, dtype=np.int64), np.empty(size))


@jitable
def advance_in(f, sw, P, T, y0, command, v_set, max_rate, t0, t1, max_step, split, work):
    """``advance`` in the arrays of ``workspace`` (a whole run allocates them once, ``run``)."""
    K, tmp, y, y1, rec, lag, g0, g1, g, changed, mode, trial = work
    y[:] = y0
    count = max(1, math.ceil((t1 - t0) / max_step - 1e-9))
    h = (t1 - t0) / count
    nfev = 0
    lag[:] = 0.0
    if not split:
        natural = no_mode()
        for i in range(count):
            nfev += rk_step(f, P, T, t0 + i * h, y, command, v_set, max_rate, h, K, tmp, y1, rec, natural, lag)
            y, y1 = y1, y
        return y.copy(), nfev, 0
    n = int(P[H.n]) if P.shape[0] else 0
    changed[:] = False
    mode[:] = NATURAL
    kinks = 0
    release = actuator_release(P, y[n + 2], command, max_rate) if P.shape[0] else math.inf
    released = not EDGE * h < release < math.inf  # not rate-limited, or letting go at the start
    if P.shape[0]:  # a kernel model: its actuator in closed form (rk_step)
        lag[0], lag[1], lag[2], lag[3] = 1.0, y[n + 2], command, release
    m = sw(P, y, command, v_set, g0)
    branches(g0, m, mode)
    for i in range(count):
        ts = t0 + i * h
        done = 0.0  # time already stepped inside this step
        splits = 0
        while True:
            left = h - done
            length = left
            at_release = False
            if not released:
                until = release - (i * h + done)
                if until <= EDGE * h:
                    released = True
                elif until < left - EDGE * h:
                    length, at_release = until, True
            mode[0] = LOW if released else HIGH
            lag[4] = i * h + done
            nfev += rk_step(f, P, T, ts + done, y, command, v_set, max_rate, length, K, tmp, y1, rec, mode, lag)
            sw(P, y1, command, v_set, g1)
            if m and splits < MAX_SPLITS and _changed(g0, g1, m, changed):
                tau = length
                for j in range(m):
                    if changed[j]:
                        tj, used = _locate(f, sw, P, T, ts + done, y, command, v_set, max_rate, length, j, g0[j],
                                           g1[j], K, tmp, trial, rec, mode, lag, g)
                        nfev += used
                        tau = pymin(tau, tj)
                if EDGE * h < tau < length - EDGE * h:
                    nfev += rk_step(f, P, T, ts + done, y, command, v_set, max_rate, tau, K, tmp, y1, rec, mode, lag)
                    y, y1 = y1, y
                    sw(P, y, command, v_set, g0)
                    branches(g0, m, mode)
                    done += tau
                    splits += 1
                    kinks += 1
                    continue
            y, y1 = y1, y
            g0, g1 = g1, g0
            branches(g0, m, mode)
            if at_release:
                released = True
                kinks += 1
                splits += 1
                done += length
                continue
            break
    return y.copy(), nfev, kinks


@entry
def tick(P, T, y0, command, v_set, max_rate, t0, t1, max_step, split):
    """One tick of the model from t0 to t1 (``advance`` on ``rhs`` and ``switches``). Returns
    (y1, clear, right-hand sides evaluated, kinks split at); clear: see ``clear``."""
    y, nfev, kinks = advance(model_rhs, switches, P, T, y0, command, v_set, max_rate, t0, t1, max_step, split)
    return y, clear(P, y), nfev, kinks
