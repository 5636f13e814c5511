"""A whole run of a batch of schemes in one compiled call, one scheme per SIMD lane (issue 24,
docs/lanes.md): ``whole.run`` for schemes of one shape (physics/kernel/batched.py), the same method,
tick and step.

Each tick is stepped for every lane at once (``rk_step_lanes``, the branches each lane is on held
for the step, the actuator in closed form), and each lane watches its own kinks: a lane whose
actuator lets go of its rate limit inside a step, or one of whose switching functions changes sign
across a step, has that tick redone alone by the scalar ``advance_in`` from the tick's start, which
splits it exactly as ``whole.run`` does. A lane whose state is not ``clear`` after a tick stops
there (its ``done``): the caller's guard decides, as for ``whole.run``, and continues it alone if
the guard lets it go on. The trace rows are ``whole.trace_row``'s, every lane at once
(trace_lanes.py).

Arrays: P and P_out (len, L) the stacked constants of the model and of its outputs
(packing.stack), P_rows (L, len) each lane's P in a row (the scalar calls read it), y (size, L),
commands, v_sets, max_rates (ticks, L), traces (L, ticks + 1, width): each lane's trace as
``whole.run`` writes it (a tick's rows are made across lanes in a (width, L) buffer and copied in).
``runner_with`` binds the batch's stepper, switching functions and trace: with the C library's math
(``run_lanes_libm``) every lane's trace is ``whole.run``'s bit for bit (test/test_whole_lanes.py),
with vmath's (``run_lanes``) within the issue's bound."""
from __future__ import annotations

import math

import numpy as np

from ..integrate.rk import EDGE, advance_in, workspace
from ..integrate.rk_lanes import arrays, rk_step_lanes, rk_step_lanes_libm
from ..jit import jitable, lanes
from ..physics.kernel.base import FORCE_SWITCHES, HIGH, KINEMATIC, LOW, NATURAL, H
from ..physics.kernel.batched import WORK_ROWS, switches_lanes, switches_lanes_libm
from ..physics.kernel.laws import actuator_release
from ..physics.kernel.motion import GUARD_SLACK, model_rhs, switches
from ..physics.kernel.relief import off_relief
from .trace_lanes import trace_arrays, trace_lanes, trace_lanes_libm
from .whole import TR_MARGIN


@jitable
def lane_arrays(P_rows, T, y0, split):
    """What a batch run works in besides the step's and the trace's arrays: (start, last, g0, g1, mode,
    lag, release, released, alone, active, counts, scratch, lane_y); ``counts`` (3, L): right-hand
    sides, kinks split at and ticks redone alone per lane."""
    size, L = y0.shape[0], y0.shape[1]
    n = int(P_rows[0, H.n])
    width = FORCE_SWITCHES + n + 1
    mode = np.full((1 + width, L), NATURAL, dtype=np.int64) if split else np.empty((0, L), dtype=np.int64)
    return (y0.copy(), np.empty_like(y0), np.empty((width, L)), np.empty((width, L)), mode, np.zeros((5, L)),
            np.empty(L), np.zeros(L, dtype=np.bool_), np.zeros(L, dtype=np.bool_), np.ones(L, dtype=np.bool_),
            np.zeros((3, L), dtype=np.int64), workspace(P_rows[0], T, size), np.empty(size))


@jitable
def begin_tick(P_rows, y, start, command, v_set, max_rate, tick, h, split, lag, release, released, alone):
    """Each lane at a tick's start, as ``whole.run`` and ``advance_in`` begin one: the kinematic
    level's speed ramp, the state kept (a lane redone alone starts from it), the actuator's release
    and closed form."""
    size, L = y.shape[0], y.shape[1]
    n = int(P_rows[0, H.n])
    kinematic = int(P_rows[0, H.law]) == KINEMATIC
    for j in range(L):
        if kinematic:
            y[n + 4, j] = (v_set[j] - y[n + 3, j]) / tick
        for m in range(size):
            start[m, j] = y[m, j]
        alone[j] = False
        if split:
            release[j] = actuator_release(P_rows[j], y[n + 2, j], command[j], max_rate[j])
            released[j] = not EDGE * h < release[j] < math.inf
            lag[0, j], lag[1, j], lag[2, j], lag[3, j] = 1.0, y[n + 2, j], command[j], release[j]


@jitable
def hold_branches(step, h, mode, lag, release, released, alone):
    """Before step ``step`` of a tick: each lane's actuator branch (a lane whose actuator lets go
    inside the step is redone alone) and the closed form's time."""
    for j in range(mode.shape[1]):
        if not released[j]:
            until = release[j] - step * h
            if until <= EDGE * h:
                released[j] = True
            elif until < h - EDGE * h:
                alone[j] = True  # the actuator lets go inside this step
        mode[0, j] = LOW if released[j] else HIGH
        lag[4, j] = step * h


@jitable
def redo_alone(P_rows, T, y, t0, t1, count, command, v_set, max_rate, max_step, split, lane):
    """Each running lane that met a kink inside the tick: the tick again from its start, alone
    (``advance_in``, split as ``whole.run`` splits it)."""
    start, _, _, _, _, _, _, _, alone, active, counts, scratch, lane_y = lane
    size, L = y.shape[0], y.shape[1]
    stages = T.shape[0] - 2
    for j in range(L):
        if not (active[j] and alone[j]):
            continue
        for m in range(size):
            lane_y[m] = start[m, j]
        out, used, split_at = advance_in(model_rhs, switches, P_rows[j], T, lane_y, command[j], v_set[j],
                                         max_rate[j], t0, t1, max_step, split, scratch)
        for m in range(size):
            y[m, j] = out[m]
        counts[0, j] += used - stages * count
        counts[1, j] += split_at
        counts[2, j] += 1


@jitable
def stop_lanes(P_rows, y, i, done, lane, rows):
    """Each running lane whose state after tick i is not ``clear`` stops there (its ``done``, its
    state kept in ``last``). Returns whether a lane is still running.

    ``clear`` across lanes: the jackknife margin is the one the tick's trace row has just computed
    (rows[TR_MARGIN]: ``outputs``' smallest hitch margin, from the same hitch angles and chain angles
    psi_k as ``motion.margin``, in the same order, so with the C library's math the same bits), not
    walked again lane by lane; a height grid (never batched: packing.stack) is asked lane by lane."""
    _, last, _, _, _, _, _, _, _, active, _, _, lane_y = lane
    size, L = y.shape[0], y.shape[1]
    relief = P_rows[0, H.relief] != 0.0
    running = False
    for j in range(L):
        if not active[j]:
            continue
        ok = rows[TR_MARGIN, j] > GUARD_SLACK
        for m in range(size):
            ok &= math.isfinite(y[m, j])
        if ok and relief:
            for m in range(size):
                lane_y[m] = y[m, j]
            ok = off_relief(P_rows[j], lane_y) < 0
        if ok:
            running = True
        else:
            active[j] = False
            done[j] = i + 1
            for m in range(size):
                last[m, j] = y[m, j]
    return running


def runner_with(step_lanes, switches_of, trace_of):
    """``run_lanes`` stepping with ``step_lanes``, watching ``switches_of`` and tracing with ``trace_of``
    (their math bound)."""

    @jitable
    def step_tick(P, T, y, y1, command, v_set, max_rate, count, h, split, step_arrays, lane):
        """The tick's ``count`` steps of every lane, each lane on its own held branches; a lane whose
        switching functions change sign across a step is marked to be redone alone. Returns the
        arrays holding the state after the tick and the other one."""
        K, tmp, _, rec, work, acc = step_arrays
        _, _, g0, g1, mode, lag, release, released, alone, active, counts, _, _ = lane
        L = y.shape[1]
        stages = T.shape[0] - 2
        m_sw = switches_of(P, y, v_set, g0, work) if split else 0
        for j in range(L):
            for s in range(m_sw):
                mode[1 + s, j] = HIGH if g0[s, j] > 0.0 else LOW
        for step in range(count):
            if split:
                hold_branches(step, h, mode, lag, release, released, alone)
            step_lanes(P, T, y, command, v_set, max_rate, h, K, tmp, y1, rec, mode, lag, work, acc)
            for j in range(L):
                counts[0, j] += stages if active[j] else 0
            y, y1 = y1, y
            if m_sw:
                switches_of(P, y, v_set, g1, work)
                for j in range(L):
                    for s in range(m_sw):
                        high = g1[s, j] > 0.0
                        alone[j] |= high != (g0[s, j] > 0.0)
                        mode[1 + s, j] = HIGH if high else LOW
                g0, g1 = g1, g0
        return y, y1

    @jitable
    def run_lanes(P, P_rows, P_out, T, y0, commands, v_sets, max_rates, tick, max_step, split, traces, done):
        """Ticks 0, 1, ... of every lane (module docstring); ``done`` (L,) gets the ticks each lane
        ran (it stops after its first tick whose state is not ``clear``). Returns (y (size, L) at each
        lane's last tick, counts (3, L): right-hand sides evaluated, kinks split at and ticks redone
        alone, per lane)."""
        step_arrays = arrays(T, y0)
        lane = lane_arrays(P_rows, T, y0, split)
        start, last, _, _, _, lag, release, released, alone, active, counts, _, _ = lane
        dy, rec, no_mode, work, frame = trace_arrays(P_out, y0)
        n = int(P[H.n, 0])
        kinematic = int(P[H.law, 0]) == KINEMATIC
        law_inputs = np.empty(y0.shape[1])
        rows = np.empty((traces.shape[2], y0.shape[1]))
        y, y1 = y0.copy(), step_arrays[2]
        done[:] = commands.shape[0]
        for i in range(commands.shape[0]):
            t0 = i * tick
            t1 = t0 + tick
            count = max(1, math.ceil((t1 - t0) / max_step - 1e-9))  # as advance_in: t1 - t0 is not always tick
            h = (t1 - t0) / count
            begin_tick(P_rows, y, start, commands[i], v_sets[i], max_rates[i], tick, h, split, lag, release, released,
                       alone)
            y, y1 = step_tick(P, T, y, y1, commands[i], v_sets[i], max_rates[i], count, h, split, step_arrays, lane)
            redo_alone(P_rows, T, y, t0, t1, count, commands[i], v_sets[i], max_rates[i], max_step, split, lane)
            for j in range(y.shape[1]):  # what the outputs' traction law sees (as whole.run)
                law_inputs[j] = y[n + 3, j] + y[n + 4, j] if kinematic else v_sets[i, j]
            trace_of(P_out, y, commands[i], law_inputs, max_rates[i], dy, rec, no_mode, work, frame, rows)
            for j in range(y.shape[1]):
                if active[j]:  # a lane that has stopped keeps its trace as it stopped
                    for c in range(rows.shape[0]):
                        traces[j, i + 1, c] = rows[c, j]
            if not stop_lanes(P_rows, y, i, done, lane, rows):
                break
        for j in range(y.shape[1]):
            if active[j]:
                last[:, j] = y[:, j]
        return last, counts

    return run_lanes


run_lanes_vmath = runner_with(rk_step_lanes, switches_lanes, trace_lanes)
run_lanes_libm = runner_with(rk_step_lanes_libm, switches_lanes_libm, trace_lanes_libm)


@lanes
def run_lanes(P, P_rows, P_out, T, y0, commands, v_sets, max_rates, tick, max_step, split, traces, done):
    """``run_lanes`` with vmath's math (vectorised): a sweep's batch."""
    return run_lanes_vmath(P, P_rows, P_out, T, y0, commands, v_sets, max_rates, tick, max_step, split,
                           traces, done)


@lanes
def run_lanes_libm_of(P, P_rows, P_out, T, y0, commands, v_sets, max_rates, tick, max_step, split, traces,
                      done):
    """``run_lanes`` with the C library's math: every lane ``whole.run``'s to the bit."""
    return run_lanes_libm(P, P_rows, P_out, T, y0, commands, v_sets, max_rates, tick, max_step, split,
                          traces, done)
