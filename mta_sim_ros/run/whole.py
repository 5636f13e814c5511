"""A whole run in one compiled call (a sweep's runs, ``batch.py``): every tick stepped as
``Simulation.advance`` steps it, and one trace row a tick of what the metrics read."""
from __future__ import annotations

import math

import numpy as np

from ..integrate.rk import advance_in, workspace
from ..jit import entry, jitable
from ..physics.kernel.base import BX, BY, FRONT_LAT, KINEMATIC, LAT, MARGIN, OUT, PHI, PULL, SCALARS, TRACTION, H
from ..physics.kernel.motion import clear, drawbar_pulls, model_rhs, outputs, switches

#: columns of a run's trace row: the scalars, then TRACE_CART per cart
TR_TRACTION, TR_SPEED, TR_MARGIN, TR_STEERING, TR_FRONT_LAT = range(5)
TRACE_HEAD = 5
TR_BX, TR_BY, TR_HEADING, TR_PHI, TR_PULL, TR_LAT = range(6)
TRACE_CART = 6


@jitable
def trace_row(P, y, command, law_input, max_rate, cart, sc, dy, row):
    """The outputs of a run's trace at state y into ``row`` (TRACE_HEAD + TRACE_CART n)."""
    n = int(P[H.n])
    outputs(P, y, command, law_input, max_rate, cart, sc, dy)
    drawbar_pulls(P, y, dy[n + 3], cart, sc)
    row[TR_TRACTION], row[TR_SPEED], row[TR_MARGIN], row[TR_STEERING] = sc[TRACTION], y[n + 3], sc[MARGIN], y[n + 2]
    row[TR_FRONT_LAT] = sc[FRONT_LAT]
    for k in range(n):
        j = TRACE_HEAD + TRACE_CART * k
        row[j + TR_BX], row[j + TR_BY], row[j + TR_HEADING] = cart[k, BX], cart[k, BY], y[2 + k]
        row[j + TR_PHI], row[j + TR_PULL], row[j + TR_LAT] = cart[k, PHI], cart[k, PULL], cart[k, LAT]


@entry
def trace_of(P_out, y, command, law_input, max_rate):
    """One trace row (``trace_row``) as a new array: a run's row 0."""
    n = int(P_out[H.n])
    row = np.empty(TRACE_HEAD + TRACE_CART * n)
    trace_row(P_out, y, command, law_input, max_rate, np.empty((n, OUT)), np.empty(SCALARS), np.empty(y.shape[0]), row)
    return row


@entry
def run(P, P_out, T, y0, commands, v_sets, max_rates, tick, max_step, split, start, trace):
    """Ticks start, start + 1, ... of a run, tick i from t = i tick holding commands[i], v_sets[i] and
    max_rates[i] (the held input: steering command, speed set-point, steering rate limit),
    as ``Simulation.advance`` runs them (the kinematic level's speed ramp set at each tick's start,
    ``kinematic.begin_tick``); after tick i the outputs of P_out into trace[i + 1] (``trace_row``;
    the kinematic level reports its inverse dynamics under V + V'). Stops after the first tick whose
    state is not ``clear`` (the caller's guards.check_state decides) or after the last. Returns
    (y, ticks done, right-hand sides evaluated, kinks split at)."""
    n = int(P[H.n])
    kinematic = int(P[H.law]) == KINEMATIC
    cart = np.empty((n, OUT))
    sc = np.empty(SCALARS)
    dy = np.empty(y0.shape[0])
    y = y0.copy()
    nfev = 0
    kinks = 0
    work = workspace(P, T, y0.shape[0])
    for i in range(start, commands.shape[0]):
        t0 = i * tick
        if kinematic:
            y[n + 4] = (v_sets[i] - y[n + 3]) / tick
        y1, used, split_at = advance_in(model_rhs, switches, P, T, y, commands[i], v_sets[i], max_rates[i], t0,
                                        t0 + tick, max_step, split, work)
        y[:] = y1
        nfev += used
        kinks += split_at
        law_input = y[n + 3] + y[n + 4] if kinematic else v_sets[i]
        trace_row(P_out, y, commands[i], law_input, max_rates[i], cart, sc, dy, trace[i + 1])
        if not clear(P, y):
            return y, i + 1, nfev, kinks
    return y, commands.shape[0], nfev, kinks


@entry
def points_apart(a, b, rows, lengths, offset):
    """The largest distance between the same point of two runs' traces a and b over their rows
    0..rows - 1, NaN where no such distance is finite (accuracy.distance): every hitch A_k = B_k + l_k
    e_k and axle centre B_k (``lengths``: l_k) and the last rear hitch B_n - a_n e_n (``offset``: a_n),
    e_k = (cos th_k, sin th_k), each distance sqrt(dx^2 + dy^2) (accuracy.points_of and numpy's norm,
    operation for operation)."""
    n = lengths.shape[0]
    best = -math.inf
    for i in range(rows):
        for k in range(n):
            j = TRACE_HEAD + TRACE_CART * k
            pa = (a[i, j + TR_BX], a[i, j + TR_BY], math.cos(a[i, j + TR_HEADING]), math.sin(a[i, j + TR_HEADING]))
            pb = (b[i, j + TR_BX], b[i, j + TR_BY], math.cos(b[i, j + TR_HEADING]), math.sin(b[i, j + TR_HEADING]))
            best = farther(best, pa[0] + lengths[k] * pa[2], pa[1] + lengths[k] * pa[3],
                           pb[0] + lengths[k] * pb[2], pb[1] + lengths[k] * pb[3])  # A_k
            best = farther(best, pa[0], pa[1], pb[0], pb[1])  # B_k
            if k == n - 1:
                best = farther(best, pa[0] - offset * pa[2], pa[1] - offset * pa[3], pb[0] - offset * pb[2],
                               pb[1] - offset * pb[3])
    return best if best > -math.inf else math.nan


@jitable
def farther(best, ax, ay, bx, by):
    """The larger of ``best`` and |(ax, ay) - (bx, by)|, a distance that is not finite left out."""
    dx, dy = ax - bx, ay - by
    d = math.sqrt(dx * dx + dy * dy)
    return d if math.isfinite(d) and d > best else best
