"""Runs of many scenes at once, one per SIMD lane (issue 24, docs/lanes.md): ``batch.run_trace`` for a
batch of scenes whose runs share a shape (``lane_key``). No ROS here.

``run_traces(scenes)`` sets each scene up as ``run_trace`` does (``Simulation``), stacks the runs that
can share a batch into ``whole_lanes.run_lanes`` and hands back, per scene, what ``run_trace`` hands
back: (simulation, trace, commands, ticks run, the error that stopped it or None). A lane that stops
on the kernel's fast guard is decided by ``guards.check_state`` as in ``run_trace``, and where the
guard lets it go on, ``run_trace``'s own loop continues it alone. A scene that cannot share a batch
(no whole-run kernel, a height grid, a shape of its own) runs alone through ``run_trace``.

``math``: "vmath" (vectorised; each lane within a few ulp a step of its run alone) or "libm" (the C
library's, every lane's trace ``run_trace``'s bit for bit: the proof that the batch runs the same
physics)."""
from __future__ import annotations

import numpy as np

from ..physics import kernel
from . import whole, whole_lanes
from .batch import continue_run, run_trace, scheduled_inputs
from .simulation import Simulation

MATHS = ("vmath", "libm")


def lane_key(sim: Simulation, ticks: int):
    """What runs of one batch share, or None for a run that cannot join one: the packed constants'
    shape (packing.shape_of), the outputs' length, the method's tableau, the tick, the step, kink
    splitting and the number of ticks."""
    if not sim.compiled or not sim.kernel_ticks or sim.model.P[kernel.H.relief]:
        return None
    stepper = sim.stepper
    return (kernel.shape_of(sim.model.P), len(sim.model.P_outputs), stepper.tableau.packed.tobytes(), sim.tick,
            stepper.step, bool(stepper.split_kinks), ticks, sim.y.shape[0])


def run_traces(scenes, math: str = "vmath", **options) -> list:
    """``run_trace(scene, **options)`` of every scene (module docstring), in order."""
    if math not in MATHS:
        raise ValueError(f"math: {math!r} is not one of {', '.join(MATHS)}")
    sims = [Simulation(scene, **options) for scene in scenes]
    inputs = [scheduled_inputs(scene, sim) for scene, sim in zip(scenes, sims)]
    groups: dict = {}
    for i, (sim, (commands, _)) in enumerate(zip(sims, inputs)):
        groups.setdefault(lane_key(sim, commands.shape[0]), []).append(i)
    out: list = [None] * len(sims)
    for key, members in groups.items():
        if key is None:
            for i in members:
                out[i] = run_trace(scenes[i], **options)
            continue
        for i, result in zip(members, _run_batch([sims[i] for i in members], [inputs[i] for i in members], math)):
            out[i] = result
    return out


def _run_batch(sims, inputs, math):
    """The runs of one batch (one lane_key): run_trace's tuples, in order."""
    L = len(sims)
    first = sims[0]
    ticks = inputs[0][0].shape[0]
    n = first.model.layout.n
    P = kernel.stack([sim.model.P for sim in sims])
    P_rows = np.ascontiguousarray(P.T)
    P_out_rows = np.ascontiguousarray(np.stack([sim.model.P_outputs for sim in sims]))
    y0 = np.ascontiguousarray(np.stack([np.asarray(sim.y, dtype=np.float64) for sim in sims], axis=1))
    commands = np.ascontiguousarray(np.stack([c for c, _ in inputs], axis=1))
    v_sets = np.ascontiguousarray(np.stack([v for _, v in inputs], axis=1))
    max_rates = np.ascontiguousarray(np.tile([sim.max_rate for sim in sims], (ticks, 1)))
    traces = np.full((L, ticks + 1, whole.TRACE_HEAD + whole.TRACE_CART * n), np.nan)
    for j, sim in enumerate(sims):
        y = y0[:, j].copy()
        traces[j, 0] = whole.trace_of(sim.model.P_outputs, y, float(sim.command),
                                      float(sim.model.output_input(y, sim.v_set)), sim.max_rate)
    done = np.zeros(L, dtype=np.int64)
    stepper = first.stepper
    run = whole_lanes.run_lanes if math == "vmath" else whole_lanes.run_lanes_libm_of
    y, counts = run(P, P_rows, P_out_rows, stepper.tableau.packed, y0, commands, v_sets, max_rates,
                            first.tick, stepper.step, stepper.split_kinks, traces, done)
    results = []
    for j, sim in enumerate(sims):
        sim.stepper.nfev += int(counts[0, j])
        sim.stepper.kinks += int(counts[1, j])
        results.append(_finish(sim, traces[j], commands[:, j].copy(), v_sets[:, j].copy(), max_rates[:, j].copy(),
                               np.ascontiguousarray(y[:, j]), int(done[j])))
    return results


def _finish(sim, trace, commands, v_sets, max_rates, y, done):
    """A lane's run after the batch: run_trace's from where the lane stopped (batch.continue_run)."""
    return (sim, trace, commands) + continue_run(sim, trace, commands, v_sets, max_rates, y, done)
