"""A whole run in one compiled call, and what it measured: a sweep's unit of work. No ROS here.

``run_metrics(scene)`` runs the scene with its own inputs as ``sim.run_scene`` does (the same
``Simulation`` set-up, stepper, kernels and guards, so the same numbers tick for tick) but without
Python per tick: the held inputs are sampled for every tick at once, ``whole.run`` steps the whole
run and writes one trace row per tick, and the metrics are read off the trace (``metrics``). Python
runs again only where the kernel's fast guard is not sure (near a jackknife limit, a non-finite
state): ``guards.check_state`` then decides, and a run it stops is a result with its verdict and
reason, not an error. Methods and levels without a whole-run kernel (adaptive methods, the slip
level, algorithm 1) run tick by tick through ``Simulation`` into the same trace.

Metrics (``metric_names``; each column's name ends in its unit; per hitch k = 2..n and per cart too):
    energy, mean and peak traction power      from F_A1 V over the run (trapezoid, as summary.py)
    worked area, energy per hectare           each cart carrying a draft works a strip as wide as
                                              its widest draft (``outline.cart_widths``) along the
                                              path of its axle B_k; the draft acts the whole run
    largest hitch angle, smallest jackknife margin
    off-tracking of cart k                    the largest distance of B_k(t) from the polyline the
                                              tractor's axle B_1 traced up to t, samples whose
                                              nearest point is an end left out: mta analyze's
                                              definition (analysis.track_geometry;
                                              ``offsets.path_offsets``, growing)
    swept width                               the width of the envelope the outlines sweep, across
                                              the tractor's path: largest left minus largest right
                                              signed distance of every cart's box corners and
                                              axle ends (outline.box_of: the boxes RViz draws) from
                                              B_1's whole path joined by arcs (offsets: samples
                                              on a circle give the circle, not its chords),
                                              samples beside it (not beyond an end). In a
                                              steady turn: the outermost corner's radius minus
                                              the innermost axle end's
    headland width                            how far the outlines reach along the initial heading
                                              beyond the tractor's front axle A_1 at the first tick
                                              the scene steers (NaN: it never steers)
    drawbar pull at A_k                       mean and largest, the model's constraint force
                                              along cart k (kernel.drawbar_pulls)
    roll, pitch, rollover margin              the largest |roll| and |pitch| of any cart on the scene's
                                              terrain (0 on the level), the smallest static rollover
                                              margin of a cart that gives track_width and com_height
                                              (physics.terrain.Stance; NaN when none does)
    tip margin                                the tractor's smallest longitudinal tip margin with
                                              the drawbar pull (terrain.tip_margin; NaN when its
                                              com_height, or the hitch_height of a tractor that
                                              tows, is not given, or the slip level: no pulls)
    grip margin                               the smallest of any no-slip axle: 1 - its lateral
                                              force over mu x its static load (physics.loads;
                                              NaN without lateral_friction, or at the slip level)
    position error                            the run's estimated largest position error
                                              (accuracy.settle: a companion run; with no step
                                              the scene's tolerance chose the step)
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..compat import trapezoid
from ..integrate import IntegrationError
from ..physics import kernel
from ..physics.outline import box_of, cart_widths
from ..physics.guards import ModelValidityError, check_state
from ..physics.loads import grip_margins
from ..physics.terrain import Stance
from . import offsets, whole
from .accuracy import settle
from .margins import constraint_forces
from .simulation import Simulation, speed_setpoints, table_values

#: the verdicts of a run
OK, STOPPED = "ok", "stopped"


@dataclass
class RunResult:
    """One run: its metrics (name -> float, SI units as METRICS says), verdict and reason."""

    metrics: dict
    verdict: str  # OK, or STOPPED by a validity guard / the integrator
    reason: str  # why it stopped ("" when ok)
    simulated: float  # s reached
    level: str  # the fidelity level that ran
    trace: np.ndarray  # ticks + 1 rows of whole.trace_row


def scheduled_inputs(scene, sim: Simulation) -> tuple[np.ndarray, np.ndarray]:
    """(commands, v_sets) held over every tick of the run: the scene's tables at t = i tick, as
    ``Simulation.scheduled_inputs`` samples them one tick at a time (np.interp at the same points)."""
    ticks = int(math.floor(scene.duration / sim.tick + 1e-9))
    t = np.arange(ticks) * sim.tick
    return (np.ascontiguousarray(table_values(scene.steering, t), dtype=np.float64),
            np.ascontiguousarray(speed_setpoints(scene, t), dtype=np.float64))


def run_trace(scene, **options) -> tuple[Simulation, np.ndarray, np.ndarray, int, Exception | None]:
    """(simulation, trace, commands, ticks run, the error that stopped it or None)."""
    sim = Simulation(scene, **options)
    commands, v_sets = scheduled_inputs(scene, sim)
    ticks = commands.shape[0]
    model = sim.model
    n = model.layout.n
    trace = np.full((ticks + 1, whole.TRACE_HEAD + whole.TRACE_CART * n), np.nan)
    if sim.compiled is None or not sim.kernel_ticks:
        return (sim, trace, commands) + _tick_by_tick(sim, commands, v_sets, trace)
    P_out = model.P_outputs
    y = np.ascontiguousarray(sim.y, dtype=np.float64)
    law_input = model.output_input(y, sim.v_set)
    max_rates = np.full(ticks, sim.max_rate)  # a scene holds the actuator's own rate limit
    trace_of = whole.trace_of if sim.compiled else whole.trace_of.py_func
    run = whole.run if sim.compiled else whole.run.py_func
    trace[0] = trace_of(P_out, y, float(sim.command), float(law_input), sim.max_rate)
    return (sim, trace, commands) + continue_run(sim, trace, commands, v_sets, max_rates, y, 0, run)


def continue_run(sim: Simulation, trace, commands, v_sets, max_rates, y, done: int, run=None) -> tuple:
    """A run on from tick ``done`` at state y (0 at the start; or where a kernel call stopped it,
    whole_lanes too), ``whole.run`` called until the last tick or the guard that stops it: a state
    the kernel's fast guard is not sure of is decided by guards.check_state. Returns (ticks run,
    the error that stopped it or None)."""
    model, stepper = sim.model, sim.stepper
    run = run or whole.run
    while True:
        sim.y, sim.ticks = y, done
        if done and not kernel.clear(model.P, y):
            try:
                check_state(model, sim.t, y)
            except ModelValidityError as err:  # the failing tick is not part of the run (as in run_scene)
                trace[done] = np.nan
                sim.ticks = done - 1
                return done - 1, detached(err)
        if done >= commands.shape[0]:
            return done, None
        y, done, nfev, kinks = run(model.P, model.P_outputs, stepper.tableau.packed, y, commands, v_sets, max_rates,
                                   sim.tick, stepper.step, stepper.split_kinks, done, trace)
        stepper.nfev += nfev
        stepper.kinks += kinks


def detached(err: BaseException) -> BaseException:
    """``err`` (and the exceptions it was raised from) without its traceback, to be kept as a value: a
    traceback holds the frames it passed, with their locals (a batch's traces), and, through the
    frames, the list the error is kept in: a cycle that only the garbage collector frees, late."""
    chain, link = set(), err
    while link is not None and id(link) not in chain:
        chain.add(id(link))
        link.__traceback__ = None
        link = link.__cause__ or link.__context__
    return err


def _tick_by_tick(sim: Simulation, commands, v_sets, trace) -> tuple[int, Exception | None]:
    """The run through Simulation.advance, one trace row a tick from its Outputs and, on a level
    with them, the constraint forces at its state (margins.constraint_forces; NaN at the slip level)."""
    def row(out, i):
        trace[i, :whole.TRACE_HEAD] = out.traction, out.speed, out.jackknife_margin, out.steering, math.nan
        cart = trace[i, whole.TRACE_HEAD:].reshape(-1, whole.TRACE_CART)
        cart[:, whole.TR_BX], cart[:, whole.TR_BY] = out.axle[:, 0], out.axle[:, 1]
        cart[:, whole.TR_HEADING] = out.heading
        cart[0, whole.TR_PHI] = 0.0
        cart[1:, whole.TR_PHI] = out.hitch_angle
        cart[:, whole.TR_PULL] = cart[:, whole.TR_LAT] = math.nan
        forces = constraint_forces(sim.model, sim.y, sim.command, sim.v_set, sim.rate_limit, sim.compiled is not False)
        if forces is not None:
            cart[:, whole.TR_PULL], cart[:, whole.TR_LAT] = forces[0][:, kernel.PULL], forces[0][:, kernel.LAT]
            trace[i, whole.TR_FRONT_LAT] = forces[1][kernel.FRONT_LAT]

    row(sim.outputs(), 0)
    for i in range(commands.shape[0]):
        try:
            sim.advance(float(commands[i]), float(v_sets[i]))
        except (ModelValidityError, IntegrationError) as err:
            return i, detached(err)
        row(sim.outputs(), i + 1)
    return commands.shape[0], None


def run_metrics(scene, **options) -> RunResult:
    """Run ``scene`` to its end (or to the guard that stops it) and measure it (module docstring).
    ``options`` as for ``Simulation``. Input faults (a bad scene, a step refused) raise as there."""
    return result_of(scene, *settle(scene, **options))


def result_of(scene, run, stated) -> RunResult:
    """The RunResult of ``run`` (run_trace's tuple) of ``scene`` and its stated Accuracy."""
    sim, trace, commands, done, err = run
    used = trace[: done + 1]
    result = metrics(scene.train, used, sim.tick, commands[:done])
    result["position_error_m"] = stated.error
    if err is None:
        return RunResult(result, OK, "", sim.t, sim.level, used)
    return RunResult(result, STOPPED, str(err), sim.t, sim.level, used)


def metric_names(n: int) -> list[str]:
    """The metric columns of a train of n carts, in order."""
    names = ["energy_kWh", "mean_power_kW", "peak_power_kW", "worked_area_ha", "energy_per_ha_kWh",
             "max_hitch_angle_deg", "min_jackknife_margin_deg", "max_offtracking_m", "swept_width_m",
             "headland_width_m", "distance_m", "max_roll_deg", "max_pitch_deg", "min_rollover_margin",
             "min_tip_margin", "min_grip_margin", "position_error_m"]
    for k in range(2, n + 1):
        names += [f"hitch{k}_max_angle_deg", f"hitch{k}_mean_pull_kN", f"hitch{k}_max_pull_kN",
                  f"cart{k}_offtracking_m"]
    return names


def metrics(train, trace: np.ndarray, tick: float, commands: np.ndarray) -> dict:
    """The metrics (module docstring) of a run's trace (rows of whole.trace_row, one a tick)."""
    n = train.n
    rows = trace.shape[0]
    t = np.arange(rows) * tick
    power = trace[:, whole.TR_TRACTION] * trace[:, whole.TR_SPEED]
    cart = trace[:, whole.TRACE_HEAD:].reshape(rows, n, whole.TRACE_CART)
    bx, by, th = cart[:, :, whole.TR_BX], cart[:, :, whole.TR_BY], cart[:, :, whole.TR_HEADING]
    energy = float(trapezoid(power, t)) if rows > 1 else 0.0
    duration = t[-1]
    widths = cart_widths(train)
    travelled = np.hypot(np.diff(bx, axis=0), np.diff(by, axis=0)).sum(axis=0)  # per cart, m
    working = [k for k, c in enumerate(train.carts) if any(d.cart == c.name for d in train.draft)]
    area = sum(widths[k] * travelled[k] for k in working) / 1e4  # ha
    out = {
        "energy_kWh": energy / 3.6e6,
        "mean_power_kW": energy / duration / 1e3 if duration > 0 else math.nan,
        "peak_power_kW": float(np.max(power)) / 1e3,
        "worked_area_ha": area,
        "energy_per_ha_kWh": energy / 3.6e6 / area if area > 0 else math.nan,
        "min_jackknife_margin_deg": math.degrees(float(np.min(trace[:, whole.TR_MARGIN]))) if n > 1 else math.nan,
        "distance_m": float(travelled[0]),
    }
    front = train.carts[0].length  # A_1 = B_1 + l_1 e_1 (a height grid's stance needs it)
    a1 = (bx[:, 0] + front * np.cos(th[:, 0]), by[:, 0] + front * np.sin(th[:, 0]))
    out.update(stance_metrics(train, th, cart[:, 0, whole.TR_PULL], a1))
    out["min_grip_margin"] = float(np.min(grip_margins(train, trace[:, whole.TR_FRONT_LAT], cart[:, :, whole.TR_LAT])))
    path_x, path_y = np.ascontiguousarray(bx[:, 0]), np.ascontiguousarray(by[:, 0])
    distances = offsets.path_offsets if kernel_compiled() else offsets.path_offsets.py_func
    extent = offsets.outline_extent if kernel_compiled() else offsets.outline_extent.py_func
    bend = (offsets.arc_bends if kernel_compiled() else offsets.arc_bends.py_func)(path_x, path_y)
    steer = np.flatnonzero(commands != 0.0)
    start = int(steer[0]) if steer.size else -1
    e0 = np.array([math.cos(th[0, 0]), math.sin(th[0, 0])])
    steered_at = np.zeros(2)  # A_1 at the first tick the scene steers
    if start >= 0:
        steered_at = np.array([bx[start, 0], by[start, 0]]) + train.carts[0].length * np.array(
            [math.cos(th[start, 0]), math.sin(th[start, 0])])
    corners = np.empty((n, 6, 2))
    for k in range(n):
        centre, length, width, _ = box_of(train, k)
        # front and rear corners, the axle's ends
        corners[k] = [(along, across) for along in (centre + length / 2, centre - length / 2, 0.0)
                      for across in (width / 2, -width / 2)]
    left, right, reach = extent(path_x, path_y, bend, np.ascontiguousarray(bx), np.ascontiguousarray(by),
                                np.ascontiguousarray(th), corners, start, steered_at[0], steered_at[1], e0[0], e0[1])
    out["swept_width_m"] = left - right if right < math.inf else math.nan
    out["headland_width_m"] = reach if start >= 0 else math.nan
    largest_angle, offtracks = 0.0, []
    for k in range(1, n):
        phi = math.degrees(float(np.max(np.abs(cart[:, k, whole.TR_PHI]))))
        pull = cart[:, k, whole.TR_PULL]
        d, at_end = distances(path_x, path_y, np.ascontiguousarray(bx[:, k]), np.ascontiguousarray(by[:, k]), True)
        beside = np.abs(d[~at_end])
        off = float(beside.max()) if beside.size else math.nan
        out[f"hitch{k + 1}_max_angle_deg"] = phi
        out[f"hitch{k + 1}_mean_pull_kN"] = float(np.mean(pull)) / 1e3
        out[f"hitch{k + 1}_max_pull_kN"] = float(np.max(pull)) / 1e3
        out[f"cart{k + 1}_offtracking_m"] = off
        largest_angle = max(largest_angle, phi)
        offtracks += [off] if math.isfinite(off) else []
    out["max_hitch_angle_deg"] = largest_angle if n > 1 else math.nan
    out["max_offtracking_m"] = max(offtracks, default=math.nan)  # NaN: no axle was ever beside the path
    out["position_error_m"] = math.nan  # the run's, not the trace's: run_metrics sets it (accuracy.settle)
    return {name: out[name] for name in metric_names(n)}


def stance_metrics(train, heading: np.ndarray, pull: np.ndarray, a1=None) -> dict:
    """The largest |roll| and |pitch| (deg) of any cart, the smallest static rollover margin
    (NaN: no cart gives track_width and com_height) over ``heading``, rows x carts, and the
    tractor's smallest tip margin with the drawbar pull ``pull`` along its axis (rows; NaN: not
    known, Stance.tip_margins). ``a1``: (x, y) rows of A_1, which a height grid needs."""
    stance = Stance(train)
    roll, pitch = stance.angles(heading, a1)
    margins = stance.margins(heading, a1)[:, stance.measured]
    return {"max_roll_deg": math.degrees(float(np.max(np.abs(roll)))),
            "max_pitch_deg": math.degrees(float(np.max(np.abs(pitch)))),
            "min_rollover_margin": float(np.min(margins)) if margins.size else math.nan,
            "min_tip_margin": float(np.min(stance.tip_margins(heading, pull, a1)))}


def kernel_compiled() -> bool:
    """Whether the kernels run compiled here (numba runs, MTA_SIM_NO_JIT unset)."""
    import os

    from .. import jit
    from .simulation import NO_JIT_ENV

    return jit.ENABLED and os.environ.get(NO_JIT_ENV, "").strip() in ("", "0")
