"""A field plan worked closed loop, offline: the set-up of ``loop.drive`` (the route as its table,
the speeds, the train's start on the route, the implement lifted as a second set of constants) and
its trace as a ``field.types.FieldTrace``. No ROS.

The run is the dynamic level (forces: power and fuel), rk4 with kinks split, the controller's
command held over each tick (Settings.tick, step Settings.step). The train starts straight on the
route's first heading with W on its first vertex, moving at the first stretch's speed with the
governor's integral at the balance of its resistances (``run.simulation.start_state``). A run that
a guard stops is a trace with its verdict and reason, never an exception: a jackknife (the kernel's
fast guard, then ``guards.check_state`` words it), W farther than Settings.off_route from the
route, or the route's end not reached in twice its planned time (plus ten minutes).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ...field.types import FieldTrace, Plan, Route
from ...integrate.stability import resolved_step, stable_step
from ...integrate.tableau import TABLEAUX
from ...physics.dynamics import Model
from ...physics.guards import ModelValidityError, check_state, fast_modes
from ...physics.levels import lifted
from ...physics.spec import Initial, Integrator, Scene, Table
from ...run.simulation import kernel_path, start_state
from . import loop
from .design import Controller, Settings, controller, working_point_reach

OK, STOPPED = "ok", "stopped"
#: the columns of a run's raw trace beyond FieldTrace's, kept for the report (name -> column)
EXTRA = {"station": loop.T_STATION, "steering": loop.T_STEERING, "command": loop.T_COMMAND,
         "set_speed": loop.T_SET_SPEED, "heading_error": loop.T_HEADING_ERROR}


@dataclass
class FieldRun:
    """A field worked: its trace, the controller that drove it, and what it cost to run."""

    trace: FieldTrace
    controller: Controller
    rows: np.ndarray  # the raw trace (loop.T_* columns), trace's rows
    timings: dict  # s: "design", "compile" (first call: numba's compile or cache load), "loop"
    nfev: int  # right-hand sides evaluated
    step: float  # s, rk4's step used
    compiled: bool


def route_table(route: Route, speeds: tuple, early: float) -> np.ndarray:
    """The route as ``loop.drive`` reads it (loop.R_* columns): the Route's arrays, each vertex's
    direction stretch's last vertex, its gain row (0 working, 1 lifted, 2 reversing) and its
    speed set-point (signed), a lower speed ahead taken ``early`` m before it within a stretch."""
    m = route.s.shape[0]
    rev = np.asarray(route.reverse, dtype=bool)
    working = np.asarray(route.working, dtype=bool)
    R = np.empty((m, loop.ROUTE_COLUMNS))
    R[:, loop.R_X], R[:, loop.R_Y] = route.xy[:, 0], route.xy[:, 1]
    R[:, loop.R_S], R[:, loop.R_HEADING] = route.s, route.heading
    R[:, loop.R_WORKING], R[:, loop.R_REVERSE], R[:, loop.R_SEGMENT] = working, rev, route.segment
    cusps = np.flatnonzero(rev[1:m - 1] != rev[:m - 2]) + 1  # vertex c: the direction changes there
    ends = np.append(cusps, m - 1)
    R[:, loop.R_END] = ends[np.minimum(np.searchsorted(ends, np.arange(m), side="right"), ends.size - 1)]
    starts = np.concatenate(([0], cusps))[np.searchsorted(cusps, np.arange(m), side="right")]
    R[:, loop.R_START] = starts
    R[:, loop.R_GAIN] = np.where(rev, 2, np.where(working, 0, 1))
    v = np.where(rev, speeds[2], np.where(working, speeds[0], speeds[1]))
    size = np.abs(v)
    for i in np.flatnonzero(np.abs(v[1:]) < np.abs(v[:-1])) + 1:  # each drop of the speed, in order
        lo = max(int(np.searchsorted(route.s, route.s[i] - early, side="left")), int(starts[i]))
        size[lo:i] = np.minimum(size[lo:i], abs(v[i]))
    R[:, loop.R_SPEED] = np.copysign(size, v)
    return R


def planned_time(R: np.ndarray) -> float:
    """s the route takes at its set-points."""
    ds = np.diff(R[:, loop.R_S])
    return float(np.sum(ds / np.abs(R[:-1, loop.R_SPEED])))


def start_pose(train, route: Route) -> tuple[float, float, float]:
    """(x, y, heading) of A_1 for the straight train with W on the route's first vertex, pointing
    along its first heading (against it when the route starts reversed)."""
    heading = float(route.heading[0]) + (math.pi if route.reverse[0] else 0.0)
    reach = working_point_reach(train)
    return (float(route.xy[0, 0]) + reach * math.cos(heading), float(route.xy[0, 1]) + reach * math.sin(heading),
            heading)


def start_scene(train, route: Route, speed: float, settings: Settings) -> Scene:
    """A scene of the run's start (what ``run.simulation.start_state`` reads)."""
    x, y, heading = start_pose(train, route)
    return Scene(name="field", train=train, duration=settings.tick, initial=Initial(x, y, heading, speed),
                 steering=Table((0.0,), (0.0,)), speed=Table((0.0,), (speed,)),
                 integrator=Integrator("rk4", settings.step), publish_rate=1.0 / settings.tick, fidelity="dynamic")


def rk4_step(train, settings: Settings) -> float:
    """rk4's step: Settings.step, shortened to the stability limit of the governor's modes and to
    resolve the actuator's time constant (the run takes the actuator in closed form)."""
    step, _ = stable_step("rk4", settings.step, settings.tick, fast_modes(train, actuator=False))
    step, _ = resolved_step(step, settings.tick, train.actuator.time_constant)
    return step


def law_inputs(route: Route, train, settings: Settings) -> tuple[Controller, np.ndarray, np.ndarray]:
    """(the controller, the route as its table, loop.params): what ``loop.law`` reads besides the
    state, for the offline run and the tracker (tracker.py) alike."""
    ctl = controller(train, settings)
    R = route_table(route, ctl.speeds, ctl.early)
    params = np.zeros(loop.PARAMS)
    params[loop.P_CART], params[loop.P_OFFSET] = ctl.cart, ctl.offset
    params[loop.P_LEAD] = ctl.lead
    params[loop.P_MAX_ERROR], params[loop.P_OFF_ROUTE] = settings.max_error, settings.off_route
    params[loop.P_DECEL], params[loop.P_CREEP] = settings.decel, settings.creep
    params[loop.P_FORWARD_ANGLE] = ctl.forward_angle
    return ctl, R, params


def run_field(plan: Plan, train, settings: Settings = Settings(), compiled: bool | None = None,
              start_offset: float = 0.0) -> FieldRun:
    """Work ``plan`` with ``train`` closed loop (module docstring). ``compiled``: as Simulation's
    (None: compiled where numba runs and MTA_SIM_NO_JIT is not set). ``start_offset``: the train
    starts that far (m) left of the route's start, across its travel (a planted error)."""
    t0 = time.perf_counter()
    ctl, R, params = law_inputs(plan.route, train, settings)
    work, lift = Model(train), Model(lifted(train))
    first = work if R[0, loop.R_WORKING] else lift
    y = np.ascontiguousarray(start_state(start_scene(first.train, plan.route, float(R[0, loop.R_SPEED]), settings),
                                         first), dtype=np.float64)
    travel = float(plan.route.heading[0])
    y[0] -= start_offset * math.sin(travel)
    y[1] += start_offset * math.cos(travel)
    step = rk4_step(train, settings)
    T = TABLEAUX["rk4"].packed
    ticks = int(math.ceil((2.0 * planned_time(R) + 600.0) / settings.tick))
    trace = np.full((ticks + 1, loop.TRACE_HEAD + loop.TRACE_CART * train.n), np.nan)
    use, _ = kernel_path(work, compiled)
    drive = loop.drive if use else loop.drive.py_func
    ref = np.empty((R.shape[0], train.n + 1))
    arrays = (np.ascontiguousarray(ctl.K), ctl.row, params, settings.tick, step, True)
    timings = {"design": time.perf_counter() - t0}
    t0 = time.perf_counter()
    if use:  # compile, or load from numba's cache: one tick on the route's first two vertices
        head = R[:2].copy()
        head[:, loop.R_END] = 1
        drive(work.P, lift.P, T, y, head, ref[:2].copy(), *arrays, np.zeros(loop.CURSOR), np.empty((2, trace.shape[1])))
    timings["compile"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    cursor = np.zeros(loop.CURSOR)
    nfev, verdict, reason = 0, OK, ""
    while True:
        y, status, used = drive(work.P, lift.P, T, y, R, ref, *arrays, cursor, trace)
        nfev += used
        done = int(cursor[loop.CU_TICKS])
        if status == loop.NOT_CLEAR:
            try:
                check_state(work, done * settings.tick, y)
            except ModelValidityError as err:  # the failing tick is not part of the run (as in batch.run_trace)
                verdict, reason, done = STOPPED, str(err), done - 1
                break
            continue  # the fast guard was not sure, the model's own check lets it go on
        if status == loop.OFF_ROUTE:
            row = trace[done]
            verdict, reason = STOPPED, (
                f"off the route at t = {done * settings.tick:.1f} s: the working point at ({row[loop.T_WX]:.1f}, "
                f"{row[loop.T_WY]:.1f}) m is {abs(row[loop.T_ERROR]):.2f} m from it (limit {settings.off_route:g} m)")
        elif status == loop.OUT_OF_TIME:
            verdict, reason = STOPPED, (f"the route's end not reached in {ticks * settings.tick:.0f} s (twice its "
                                        f"planned {planned_time(R):.0f} s, plus 600 s)")
        break
    timings["loop"] = time.perf_counter() - t0
    rows = trace[:done + 1]
    return FieldRun(field_trace(plan, train, rows, settings.tick, verdict, reason), ctl, rows, timings, nfev, step,
                    bool(use))


def field_trace(plan: Plan, train, rows: np.ndarray, tick: float, verdict: str, reason: str) -> FieldTrace:
    """The FieldTrace of a run's raw rows (loop.T_* columns)."""
    n = train.n
    cart = rows[:, loop.TRACE_HEAD:].reshape(rows.shape[0], n, loop.TRACE_CART)
    return FieldTrace(
        plan=plan, tick=tick, t=rows[:, loop.T_TIME].copy(), implement=rows[:, [loop.T_WX, loop.T_WY]].copy(),
        lowered=rows[:, loop.T_LOWERED] != 0.0, segment=rows[:, loop.T_SEGMENT].astype(np.int64),
        tracking_error=rows[:, loop.T_ERROR].copy(), axle=cart[:, :, [loop.T_BX, loop.T_BY]].copy(),
        heading=cart[:, :, loop.T_TH].copy(), hitch_angle=cart[:, 1:, loop.T_PHI].copy(),
        margin=rows[:, loop.T_MARGIN].copy(), speed=rows[:, loop.T_SPEED].copy(), power=rows[:, loop.T_POWER].copy(),
        verdict=verdict, reason=reason)

