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

import dataclasses

import numpy as np

from ..integrate import IntegrationError
from ..physics import kernel
from ..physics.guards import ModelValidityError
from ..validate import InputError
from . import whole, whole_lanes
from .accuracy import settling
from .batch import continue_run, detached, result_of, run_trace, scheduled_inputs
from .simulation import Simulation

MATHS = ("vmath", "libm")
#: at most this many lanes a batch: past a few hundred a batch's rows leave the caches, and it runs no faster
LANES = 256
#: a batch's traces take at most this many bytes (a long run steps with fewer lanes)
TRACE_BYTES = 32 * 2**20


def lane_key(sim: Simulation, ticks: int):
    """What runs of one batch share, or None for a run that cannot join one: the shapes of the packed
    constants of the model and of its outputs (packing.shape_of), the method's tableau, the tick, the step, kink
    splitting and the number of ticks."""
    if not sim.compiled or not sim.kernel_ticks or sim.model.P[kernel.H.relief]:
        return None
    stepper = sim.stepper
    return (kernel.shape_of(sim.model.P), kernel.shape_of(sim.model.P_outputs), stepper.tableau.packed.tobytes(), sim.tick,
            stepper.step, bool(stepper.split_kinks), ticks, sim.y.shape[0])


#: what refuses one run of a batch without touching the others (the sweep engine's refusals)
REFUSALS = (InputError, ModelValidityError, IntegrationError, ValueError)


def run_traces(scenes, math: str = "vmath", trace_bytes: int = TRACE_BYTES, **options) -> list:
    """``run_trace(scene, **options)`` of every scene (module docstring), in order; a scene's
    refusal raises as there. ``trace_bytes``: run_each's."""
    runs = run_each([(scene, options) for scene in scenes], math, trace_bytes)
    for run in runs:
        if isinstance(run, Exception):
            raise run
    return runs


def run_each(requests, math: str = "vmath", trace_bytes: int = TRACE_BYTES) -> list:
    """``run_trace(scene, **options)`` of every (scene, options) request, in order: the run's tuple,
    or the refusal (REFUSALS) its set-up raised. Runs that share a ``lane_key`` run as batches of
    ``lanes_for`` lanes (their traces within ``trace_bytes``)."""
    if math not in MATHS:
        raise ValueError(f"math: {math!r} is not one of {', '.join(MATHS)}")
    out: list = [None] * len(requests)
    groups: dict = {}
    sims, inputs = {}, {}
    for i, (scene, options) in enumerate(requests):
        try:
            sims[i] = Simulation(scene, **options)
        except REFUSALS as err:
            out[i] = detached(err)
            continue
        inputs[i] = scheduled_inputs(scene, sims[i])
        groups.setdefault(lane_key(sims[i], inputs[i][0].shape[0]), []).append(i)
    for key, members in groups.items():
        if key is None:
            for i in members:
                out[i] = run_trace(requests[i][0], **requests[i][1])
            continue
        size = lanes_for(requests[members[0]][0], key[6], trace_bytes)
        for first in range(0, len(members), size):
            some = members[first:first + size]
            for i, run in zip(some, _run_batch([sims[i] for i in some], [inputs[i] for i in some], math)):
                out[i] = run
    return out


def lanes_for(scene, ticks: int, trace_bytes: int = TRACE_BYTES) -> int:
    """How many runs of ``scene``'s shape step together: at most LANES, and at most as many as keep
    their traces (ticks + 1 rows of whole.trace_row each) within ``trace_bytes``."""
    row = 8 * (whole.TRACE_HEAD + whole.TRACE_CART * scene.train.n)
    return max(1, min(LANES, trace_bytes // (row * (ticks + 1))))


def settle_many(scenes, math: str = "vmath", **options) -> list:
    """``accuracy.settle(scene, **options)`` of every scene, in order: (run, Accuracy), or the
    refusal that stopped that scene. Each scene's search (``accuracy.settling``) runs as alone; the
    runs the searches ask for in the same round run as batches (``run_each``)."""
    searches = {i: settling(scene, options) for i, scene in enumerate(scenes)}
    out: list = [None] * len(scenes)
    requests = {}
    for i, search in searches.items():
        try:
            requests[i] = next(search)
        except REFUSALS as err:
            out[i] = detached(err)
    while requests:
        requests = _round(scenes, searches, requests, math, out)
    return out


def _round(scenes, searches, requests: dict, math: str, out: list) -> dict:
    """One round of ``settle_many``: the runs ``requests`` asks for (scene index -> options), run as
    batches and sent to their searches; returns the next round's requests (a search that ends puts
    its answer in ``out``). A function of its own so that the round's runs are let go of when it
    returns: a search keeps only what it needs (its best run), not the round's companions."""
    order = list(requests)
    runs = run_each([(scenes[i], requests[i]) for i in order], math)
    following = {}
    for i, run in zip(order, runs):
        if isinstance(run, Exception) and not isinstance(run, InputError):
            out[i] = run  # alone, it would leave settle as it is
            continue
        try:
            try:
                if isinstance(run, InputError):  # the search decides: it gives up on that run, or raises
                    following[i] = searches[i].throw(run)
                else:
                    following[i] = searches[i].send(run)
            except StopIteration as answer:
                out[i] = answer.value
        except REFUSALS as err:
            out[i] = detached(err)
    return following


def run_metrics_many(scenes, math: str = "vmath", keep_traces: bool = False, trace_bytes: int = TRACE_BYTES,
                     **options) -> list:
    """``batch.run_metrics(scene, **options)`` of every scene, in order: its RunResult, or the
    refusal (REFUSALS) that stopped it. The runs and their companions run across SIMD lanes, in
    chunks of scenes alike (the same scene's name, carts, duration and rate) whose traces fit in
    ``trace_bytes``: a chunk's runs and companions are all that is held at once. A RunResult's
    trace is kept only with ``keep_traces`` (a sweep reads the metrics)."""
    out: list = [None] * len(scenes)
    alike: dict = {}
    for i, scene in enumerate(scenes):
        alike.setdefault((scene.name, scene.train.n, scene.duration, scene.publish_rate), []).append(i)
    for members in alike.values():
        first = scenes[members[0]]
        size = lanes_for(first, int(first.duration * first.publish_rate + 1e-9), trace_bytes)
        for start in range(0, len(members), size):
            some = members[start:start + size]
            for i, result in zip(some, _results([scenes[i] for i in some], math, keep_traces, options)):
                out[i] = result
    return out


def _results(chunk, math, keep_traces, options) -> list:
    """The RunResults (or refusals) of a chunk of scenes: its runs' traces are let go of on return
    (a name left bound to the last one would hold its whole batch's block into the next chunk)."""
    return [_result(scene, settled, keep_traces) for scene, settled in zip(chunk, settle_many(chunk, math, **options))]


def _result(scene, settled, keep_trace: bool):
    """The RunResult of a settled run (or its refusal), its trace dropped unless kept."""
    if isinstance(settled, Exception):
        return settled
    try:
        result = result_of(scene, *settled)
    except REFUSALS as err:
        return detached(err)
    return result if keep_trace else dataclasses.replace(result, trace=None)


def _run_batch(sims, inputs, math):
    """The runs of one batch (one lane_key): run_trace's tuples, in order."""
    L = len(sims)
    first = sims[0]
    ticks = inputs[0][0].shape[0]
    n = first.model.layout.n
    P = kernel.stack([sim.model.P for sim in sims])
    P_rows = np.ascontiguousarray(P.T)
    P_out = kernel.stack([sim.model.P_outputs for sim in sims])
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
    y, counts = run(P, P_rows, P_out, stepper.tableau.packed, y0, commands, v_sets, max_rates, first.tick, stepper.step,
                    stepper.split_kinks, traces, done)
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
