"""A field worked closed loop, in one compiled call: tick by tick, the working point W projected on
the route, the controller's command (design.py) held over the tick, the train stepped as
``run/whole.py`` steps it (``integrate.rk.advance_in``), one trace row written. Python calls
``drive``; its ``py_func`` is the same source as plain Python (jit.py).

The route is one float array, a row a vertex (columns R_*): its points, stations and headings,
and per vertex, for the stretch from it to the next: working (1) or lifted (0), reversed, the
plan's segment, the first and the last vertex of its direction stretch (the start, a cusp or the
end), the speed set-point (signed, lower speeds ahead already taken early: drive.py) and the gain
row.

The projection is a monotone search (as run/offsets.py's): from the segment of the tick before,
on while the next segment is not farther, never past the stretch's last vertex: W passes a cusp
when it is beyond the cusp's normal line, and only then is the next stretch searched.
"""
from __future__ import annotations

import math

import numpy as np

from ...integrate.rk import advance_in, workspace
from ...jit import entry, jitable
from ...physics.kernel.base import BX, BY, CART_SIZE, HEAD_SIZE, MARGIN, OUT, PHI, SCALARS, TRACTION, C, H, wrap_angle
from ...physics.kernel.inverse import inverse_chain
from ...physics.kernel.motion import clear, model_rhs, outputs, switches
from ...run.offsets import segment_distance2

#: the route's columns
R_X, R_Y, R_S, R_HEADING, R_WORKING, R_REVERSE, R_SEGMENT, R_START, R_END, R_SPEED, R_GAIN = range(11)
ROUTE_COLUMNS = 11

#: the controller's numbers (``params``)
P_CART, P_OFFSET, P_LEAD, P_MAX_ERROR, P_OFF_ROUTE, P_DECEL, P_CREEP, P_FORWARD_ANGLE = range(8)
PARAMS = 8

#: a trace row: the scalars, then TRACE_CART per cart
(T_TIME, T_WX, T_WY, T_LOWERED, T_SEGMENT, T_ERROR, T_STATION, T_MARGIN, T_SPEED, T_POWER, T_STEERING,
 T_COMMAND, T_SET_SPEED, T_HEADING_ERROR, T_AX, T_AY) = range(16)
TRACE_HEAD = 16
T_BX, T_BY, T_TH, T_PHI = range(4)
TRACE_CART = 4

#: how a run ended (``drive``'s status)
DONE, NOT_CLEAR, OFF_ROUTE, OUT_OF_TIME = range(4)

#: ``answer``'s out: the law's command, set speed, lowered (1/0), W's segment, share along it, lateral
#: error, finished (1/0), W's x, y, heading
(A_COMMAND, A_SPEED, A_LOWERED, A_SEGMENT, A_SHARE, A_ERROR, A_FINISHED, A_WX, A_WY, A_WTH) = range(10)
ANSWER = 10

#: the cursor: the route segment W was last projected on, the look-ahead's segment, ticks done,
#: whether the reference path is computed (``drive``)
CU_SEGMENT, CU_AHEAD, CU_TICKS, CU_READY = range(4)
CURSOR = 4


@jitable
def working_point(P, y, cart, offset):
    """(x, y, heading) of the point ``offset`` m ahead of cart ``cart``'s axle B_k on its axis."""
    ax, ay = y[0], y[1]
    for k in range(cart + 1):
        b = HEAD_SIZE + CART_SIZE * k
        th = y[2 + k]
        ex, ey = math.cos(th), math.sin(th)
        bx, by = ax - P[b + C.length] * ex, ay - P[b + C.length] * ey
        if k == cart:
            return bx + offset * ex, by + offset * ey, th
        ax, ay = bx - P[b + C.hitch_offset] * ex, by - P[b + C.hitch_offset] * ey
    return ax, ay, 0.0


@jitable
def project(route, j, x, y):
    """(segment j, u along it, signed distance of (x, y) from the route, > 0 left of travel): the
    monotone search from segment j, within j's direction stretch (its end segments extended)."""
    rx, ry = route[:, R_X], route[:, R_Y]
    first, last = int(route[j, R_START]), int(route[j, R_END])
    best, side, u = segment_distance2(rx, ry, j, first, last, x, y)
    while j + 1 <= last - 1:
        d2, s2, u2 = segment_distance2(rx, ry, j + 1, first, last, x, y)
        if d2 > best:
            break
        best, side, u, j = d2, s2, u2, j + 1
    distance = math.sqrt(best)
    return j, u, distance if side >= 0.0 else -distance


@jitable
def locate(route, cursor, x, y):
    """The projection of (x, y) from the cursor's segment (``project``), passing a cusp when W is
    beyond it; the cursor moved. Returns (j, u, error, finished: beyond the route's last vertex)."""
    j = int(cursor[CU_SEGMENT])
    m = route.shape[0]
    while True:
        j, u, error = project(route, j, x, y)
        last = int(route[j, R_END])
        if j == last - 1 and u > 1.0:
            if last >= m - 1:
                cursor[CU_SEGMENT] = j
                return j, u, error, True
            j = last  # beyond the cusp: the next stretch
            continue
        cursor[CU_SEGMENT] = j
        return j, u, error, False


@jitable
def along(route, j, u, column):
    """``column`` interpolated at u along segment j (u clipped to [0, 1])."""
    w = min(max(u, 0.0), 1.0)
    return route[j, column] + w * (route[j + 1, column] - route[j, column])


@jitable
def route_heading(route, j, u):
    """The direction of travel at u along segment j: the vertices' headings interpolated, the far
    one turned by pi where it is the other side of a cusp (more than 90 deg apart)."""
    h0 = route[j, R_HEADING]
    dh = wrap_angle(route[j + 1, R_HEADING] - h0)
    if abs(dh) > 0.5 * math.pi:
        dh = wrap_angle(dh + math.pi)
    return h0 + min(max(u, 0.0), 1.0) * dh


@jitable
def reference_path(P, route, cart, offset, ref):
    """The train's pose that keeps W exactly on the route, at every route vertex, into ``ref``
    (m x (n + 1)): th_1 against the route's heading at W (cart-aligned), the hitch angles
    phi_2..phi_n, the steering psi_1 (physics/kernel/inverse.py: the kinematic chain inverted)."""
    inverse_chain(P, route[:, R_X], route[:, R_Y], route[:, R_HEADING], route[:, R_REVERSE], route[:, R_END], cart,
                  offset, ref)


@jitable
def reference_at(ref, j, u, out):
    """``ref`` interpolated at u along segment j (u clipped to [0, 1]) into ``out``."""
    w = min(max(u, 0.0), 1.0)
    for i in range(out.shape[0]):
        out[i] = ref[j, i] + w * wrap_angle(ref[j + 1, i] - ref[j, i])


@jitable
def ahead(route, cursor, j, station, distance):
    """(segment i, share w along it) at ``distance`` m of travel past ``station``, within segment
    j's direction stretch (held at its end); the look-ahead cursor moved."""
    last = int(route[j, R_END])
    target = min(station + distance, route[last, R_S])
    i = max(int(cursor[CU_AHEAD]), j)
    while i + 1 < last and route[i + 1, R_S] <= target:
        i += 1
    while i > j and route[i, R_S] > target:
        i -= 1
    cursor[CU_AHEAD] = i
    span = route[i + 1, R_S] - route[i, R_S]
    return i, min(max((target - route[i, R_S]) / span if span > 0.0 else 0.0, 0.0), 1.0)


@jitable
def command_of(P, y, route, ref, j, u, error, cursor, gains, row, params, x_ref):
    """(steering command, speed set-point) at state y, W projected at (j, u) with lateral error
    ``error`` (design.py's law)."""
    n = int(P[H.n])
    reverse = route[j, R_REVERSE] != 0.0
    heading = route_heading(route, j, u)
    if reverse:  # the frame of the carts: turned by pi, left and right swapped
        heading += math.pi
        error = -error
    reference_at(ref, j, u, x_ref)
    station = along(route, j, u, R_S)
    i, w = ahead(route, cursor, j, station, abs(y[n + 3]) * params[P_LEAD])
    g = int(route[j, R_GAIN])
    limit = params[P_MAX_ERROR]
    consistent = min(max(error, -limit), limit)  # y = e - C[1:] (x - x_ref)[1:]
    u_cmd = ref[i, n] + w * (ref[i + 1, n] - ref[i, n])  # the feedforward, ``lead`` s ahead
    for k in range(1, n + 2):
        if k == 1:
            dev = wrap_angle(y[2] - heading - x_ref[0])
        elif k <= n:
            dev = wrap_angle(y[k] - y[k + 1] - x_ref[k - 1])
        else:
            dev = y[n + 2] - x_ref[n]
        consistent -= row[k] * dev
        u_cmd -= gains[g, k] * dev
    u_cmd -= gains[g, 0] * consistent
    max_angle = P[H.max_angle] if reverse else min(P[H.max_angle], params[P_FORWARD_ANGLE])
    u_cmd = min(max(u_cmd, -max_angle), max_angle)
    v_set = route[j, R_SPEED]
    last = int(route[j, R_END])
    if last < route.shape[0] - 1:  # a cusp ahead: slow to creep at it
        cap = params[P_CREEP] + math.sqrt(2.0 * params[P_DECEL] * max(route[last, R_S] - station, 0.0))
        v_set = min(max(v_set, -cap), cap)
    return u_cmd, v_set


@jitable
def law(P, y, route, ref, cursor, gains, row, params, x_ref, W):
    """The controller's tick (design.py), at state y: the working point W (into ``W``) projected
    on the route from the cursor (``locate``), the steering command and speed set-point
    (``command_of``), and whether the implement is lowered (W's stretch is worked). What the
    offline loop (``drive``) and the tracker fed pose by pose (``answer``) both run. Returns
    (command, v_set, lowered, j, u, error, finished); the cursor moved."""
    W[0], W[1], W[2] = working_point(P, y, int(params[P_CART]), params[P_OFFSET])
    j, u, error, finished = locate(route, cursor, W[0], W[1])
    command, v_set = command_of(P, y, route, ref, j, u, error, cursor, gains, row, params, x_ref)
    return command, v_set, route[j, R_WORKING] != 0.0, j, u, error, finished


@entry
def answer(P, y, route, ref, cursor, gains, row, params, out):
    """``law`` at one state, called from Python (controllers/implement/tracker.py): into ``out``
    (A_* columns). The first call (cursor[CU_READY] = 0) computes the reference path into ``ref``,
    as ``drive``'s first call does."""
    x_ref = np.empty(int(P[H.n]) + 1)
    W = np.empty(3)
    if cursor[CU_READY] == 0.0:
        reference_path(P, route, int(params[P_CART]), params[P_OFFSET], ref)
        cursor[CU_READY] = 1.0
    command, v_set, lowered, j, u, error, finished = law(P, y, route, ref, cursor, gains, row, params, x_ref, W)
    out[A_COMMAND], out[A_SPEED], out[A_LOWERED] = command, v_set, 1.0 if lowered else 0.0
    out[A_SEGMENT], out[A_SHARE], out[A_ERROR], out[A_FINISHED] = j, u, error, 1.0 if finished else 0.0
    out[A_WX], out[A_WY], out[A_WTH] = W[0], W[1], W[2]


@jitable
def write_row(P_out, y, command, v_set, max_rate, route, j, u, error, W, t, cart, sc, dy, row):
    """One trace row (T_*) at state y, W = (x, y, heading) projected at (j, u); ``command`` and
    ``v_set`` the input held over the tick that ended here (row 0: the first tick's)."""
    n = int(P_out[H.n])
    outputs(P_out, y, command, v_set, max_rate, cart, sc, dy)
    row[T_TIME], row[T_WX], row[T_WY] = t, W[0], W[1]
    row[T_LOWERED], row[T_SEGMENT], row[T_ERROR] = route[j, R_WORKING], route[j, R_SEGMENT], error
    row[T_STATION] = along(route, j, u, R_S)
    row[T_MARGIN], row[T_SPEED] = sc[MARGIN], y[n + 3]
    row[T_POWER] = sc[TRACTION] * y[n + 3]
    row[T_STEERING], row[T_COMMAND], row[T_SET_SPEED] = y[n + 2], command, v_set
    row[T_AX], row[T_AY] = y[0], y[1]
    travel = W[2] + (math.pi if route[j, R_REVERSE] != 0.0 else 0.0)
    row[T_HEADING_ERROR] = wrap_angle(travel - route_heading(route, j, u))
    for k in range(n):
        c = TRACE_HEAD + TRACE_CART * k
        row[c + T_BX], row[c + T_BY], row[c + T_TH], row[c + T_PHI] = cart[k, BX], cart[k, BY], y[2 + k], cart[k, PHI]


@entry
def drive(P_work, P_lift, T, y0, route, ref, gains, row, params, tick, max_step, split, cursor, trace):
    """Ticks cursor[CU_TICKS] on, until W passes the route's end or a guard stops the run: each tick
    the command of ``law`` held, the train stepped with P_work where W's stretch is worked,
    P_lift where it is lifted (the implement's draft off), trace row i + 1 written after tick i.
    The first call (cursor[CU_READY] = 0) computes the reference path into ``ref``
    (``reference_path``) and writes row 0, the start. Stops after the first tick whose state is not
    ``clear`` (the caller's guards.check_state decides), whose W is more than params[P_OFF_ROUTE] m
    from the route, or at the trace's last row. Returns (y, status, right-hand sides evaluated);
    cursor holds where it stopped."""
    n = int(P_work[H.n])
    cart = np.empty((n, OUT))
    sc = np.empty(SCALARS)
    dy = np.empty(y0.shape[0])
    x_ref = np.empty(n + 1)
    W = np.empty(3)
    y = y0.copy()
    work = workspace(P_work, T, y0.shape[0])
    max_rate = P_work[H.max_rate]
    m_cart, offset = int(params[P_CART]), params[P_OFFSET]
    i = int(cursor[CU_TICKS])
    first = cursor[CU_READY] == 0.0
    if first:
        reference_path(P_work, route, m_cart, offset, ref)
        cursor[CU_READY] = 1.0
    command, v_set, lowered, j, u, error, finished = law(P_work, y, route, ref, cursor, gains, row, params, x_ref, W)
    if first:
        write_row(P_work, y, command, v_set, max_rate, route, j, u, error, W, i * tick, cart, sc, dy, trace[i])
    nfev = 0
    while True:
        if finished:
            return y, DONE, nfev
        if i + 1 >= trace.shape[0]:
            return y, OUT_OF_TIME, nfev
        P = P_work if lowered else P_lift
        t0 = i * tick
        y1, used, _ = advance_in(model_rhs, switches, P, T, y, command, v_set, max_rate, t0, t0 + tick, max_step,
                                 split, work)
        y[:] = y1
        nfev += used
        i += 1
        cursor[CU_TICKS] = i
        command_next, v_next, lowered, j, u, error, finished = law(P, y, route, ref, cursor, gains, row, params,
                                                                   x_ref, W)
        write_row(P, y, command, v_set, max_rate, route, j, u, error, W, i * tick, cart, sc, dy, trace[i])
        if not clear(P, y):
            return y, NOT_CLEAR, nfev
        if abs(error) > params[P_OFF_ROUTE]:
            return y, OFF_ROUTE, nfev
        command, v_set = command_next, v_next
