"""Whole runs of a batch of scenes, one per SIMD lane (run/whole_lanes.py, run/lanes_batch.py), against
the same scenes run alone (``batch.run_trace``, which test_sweep_metrics and test_batch hold to the
tick-by-tick simulation).

With the C library's math every lane's trace, ticks run, stopping error, final state, right-hand
sides counted and kinks split are the lone run's bit for bit: random trains of 1-5 carts with every
traction law, steered hard enough that actuators hit their rate limits, forces their limits, drafts
their corners, and some trains jackknife (each lane meets its own kinks and stops on its own). With
vmath (a sweep's binding) every metric of a run is within 1e-10 relative of the lone run's."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import trains
from test_batched import ALL_LAWS, assert_same_bits, random_train

from mta_sim_ros.physics.spec import Table
from mta_sim_ros.run import lanes_batch, whole
from mta_sim_ros.run.batch import metrics, run_metrics, run_trace
from mta_sim_ros.run.lanes_batch import REFUSALS, lane_key, run_metrics_many, run_traces, settle_many


def random_scenes(n: int, law: str, count: int, seed: int, reverse: bool, step: float = 0.05):
    """``count`` scenes of random trains of n carts under ``law``, steered by random tables (a hard
    turn and back); with ``reverse`` some back up and fold."""
    rng = np.random.default_rng(seed)
    scenes = []
    for i in range(count):
        tr = random_train(n, rng, ALL_LAWS[law], sloped=bool(i % 3 == 2))
        turn = rng.uniform(-0.7, 0.7)
        table = ((0.0, 1.0, 1.1, 3.0, 3.2, 6.0), (0.0, 0.0, turn, turn, -turn, 0.0))
        speed = rng.uniform(-2.0, -0.5) if reverse and i % 2 else rng.uniform(1.0, 4.0)
        sc = trains.scene(tr, table=table, duration=6.0, rate=10.0, step=step, speed=speed)
        speeds = (0.0, 2.0, 2.1, 6.0), (speed, speed, speed * rng.uniform(0.2, 1.5), speed)
        scenes.append(dataclasses.replace(sc, speed=Table(*speeds)))
    return scenes


CASES = [(n, law, split) for n in (1, 2, 3, 5) for law in ALL_LAWS for split in (True, False)]


@pytest.mark.parametrize("n, law, split", CASES)
def test_with_the_c_library_a_batch_run_is_the_lone_run_bit_for_bit(n, law, split):
    seed = 100 * n + sorted(ALL_LAWS).index(law) + (50 if split else 0)
    scenes = random_scenes(n, law, 6, seed, reverse=n > 1)
    options = dict(fidelity="kinematic" if law == "kinematic" else "dynamic", split_kinks=split)
    alone = [run_trace(sc, **options) for sc in scenes]
    batch = run_traces(scenes, math="libm", **options)
    assert lane_key(batch[0][0], batch[0][2].shape[0]) is not None  # they did run as one batch
    for (sim_a, trace_a, commands_a, done_a, err_a), (sim_b, trace_b, commands_b, done_b, err_b) in zip(alone, batch):
        assert done_b == done_a
        assert str(err_b) == str(err_a)
        assert_same_bits(trace_b, trace_a)
        assert_same_bits(commands_b, commands_a)
        assert_same_bits(sim_b.y, sim_a.y)
        assert (sim_b.ticks, sim_b.stepper.nfev, sim_b.stepper.kinks) == (
            sim_a.ticks, sim_a.stepper.nfev, sim_a.stepper.kinks)


def test_the_cases_meet_kinks_and_stops():
    """The cases above are not all smooth: lanes split steps at kinks (redone alone) and some stop."""
    scenes = random_scenes(3, "governor", 6, 300 + sorted(ALL_LAWS).index("governor") + 50, reverse=True)
    runs = run_traces(scenes, math="libm", fidelity="dynamic", split_kinks=True)
    assert sum(sim.stepper.kinks for sim, *_ in runs) > 0
    assert any(err is not None for *_, err in runs)
    assert any(err is None for *_, err in runs)


@pytest.mark.parametrize("n, law", [(n, law) for n in (1, 2, 3, 5) for law in ALL_LAWS])
def test_with_vmath_every_metric_is_within_1e_10_of_the_lone_run(n, law):
    scenes = random_scenes(n, law, 8, 700 + 10 * n + sorted(ALL_LAWS).index(law), reverse=False, step=0.02)
    options = dict(fidelity="kinematic" if law == "kinematic" else "dynamic")
    alone = [run_trace(sc, **options) for sc in scenes]
    batch = run_traces(scenes, math="vmath", **options)
    for sc, a, b in zip(scenes, alone, batch):
        assert (b[3], str(b[4])) == (a[3], str(a[4]))
        want = metrics(sc.train, a[1][: a[3] + 1], a[0].tick, a[2][: a[3]])
        got = metrics(sc.train, b[1][: b[3] + 1], b[0].tick, b[2][: b[3]])
        for name, value in want.items():
            if math.isnan(value):
                assert math.isnan(got[name]), name
            else:
                assert abs(got[name] - value) <= 1e-10 * max(abs(value), 1e-300), (name, got[name], value)


def test_scenes_of_other_shapes_run_alone_in_the_same_call():
    rng = np.random.default_rng(5)
    scenes = random_scenes(2, "governor", 3, 11, reverse=False) + random_scenes(3, "governor", 2, 12, reverse=False)
    scenes.append(trains.scene(random_train(2, rng, ALL_LAWS["governor"], False), method="RK45"))
    alone = [run_trace(sc) for sc in scenes]
    batch = run_traces(scenes, math="libm")
    assert lane_key(batch[-1][0], 100) is None  # an adaptive method has no whole-run kernel
    for a, b in zip(alone, batch):
        assert_same_bits(b[1], a[1])
        assert b[3] == a[3]


def test_an_unknown_math_is_refused():
    with pytest.raises(ValueError, match="math: 'svml' is not one of vmath, libm"):
        run_traces([], math="svml")


def test_a_batch_of_none_is_none():
    assert run_traces([]) == []


def tolerance_scenes(count: int, seed: int):
    """Scenes without a step (the step is searched for their tolerance, accuracy.settle), some of
    them refused (a tick past the step a tolerance needs is not; a method that does not exist is)."""
    scenes = random_scenes(3, "governor", count, seed, reverse=False)
    scenes = [dataclasses.replace(sc, integrator=dataclasses.replace(sc.integrator, step=None, tolerance=tol))
              for sc, tol in zip(scenes, [1e-4, 1e-6, 1e-8] * count)]
    bad = dataclasses.replace(scenes[0], integrator=dataclasses.replace(scenes[0].integrator, method="rk5"))
    return scenes + [bad]


def refusal_or_result(scene, **options):
    try:
        return run_metrics(scene, **options)
    except REFUSALS as err:
        return err


def test_a_batch_settles_each_scene_as_alone_bit_for_bit():
    """run_metrics_many with the C library's math: every scene's step search, run, companion and
    metrics as run_metrics alone, to the bit; a refused scene refused with the same line."""
    scenes = tolerance_scenes(6, 21)
    alone = [refusal_or_result(sc, fidelity="dynamic") for sc in scenes]
    many = run_metrics_many(scenes, math="libm", keep_traces=True, fidelity="dynamic")
    assert isinstance(alone[-1], REFUSALS) and str(many[-1]) == str(alone[-1])
    for a, b in zip(alone[:-1], many[:-1]):
        assert (b.verdict, b.reason, b.level, b.simulated) == (a.verdict, a.reason, a.level, a.simulated)
        assert_same_bits(list(b.metrics.values()), list(a.metrics.values()))
        assert_same_bits(b.trace, a.trace)
    settled = settle_many(scenes[:-1], math="libm", fidelity="dynamic")
    assert len({run[0].stepper_step for run, _ in settled}) > 1  # the searches took steps of their own


def test_with_vmath_a_settled_batch_is_within_1e_10_of_alone():
    """Every metric within 1e-10 relative; the position error (the distance between a run and its
    companion, some 1e-8 m from positions of some 10 m: its round-off is absolute) within 1e-12 m."""
    scenes = tolerance_scenes(6, 22)[:-1]
    alone = [run_metrics(sc, fidelity="dynamic") for sc in scenes]
    many = run_metrics_many(scenes, fidelity="dynamic")
    for a, b in zip(alone, many):
        for name, want in a.metrics.items():
            got = b.metrics[name]
            slack = 1e-12 if name == "position_error_m" else 0.0
            assert (math.isnan(got) and math.isnan(want)) or abs(got - want) <= 1e-10 * abs(want) + slack, name


def test_a_lane_runs_the_same_whatever_its_batch():
    """A run's bits do not depend on the batch it is in (its width, its place, its neighbours): a
    sweep's rows are the same on one core, on many and on a Dask cluster."""
    scenes = random_scenes(3, "governor", 9, 31, reverse=True)
    together = run_traces(scenes)
    for k in (0, 4, 8):
        alone = run_traces([scenes[k]])[0]
        pair = run_traces([scenes[(k + 1) % 9], scenes[k]])[1]
        for other in (alone, pair):
            assert_same_bits(other[1], together[k][1])
            assert other[3] == together[k][3]


def test_long_runs_step_in_narrower_batches_with_the_same_results():
    scenes = random_scenes(2, "governor", 5, 41, reverse=False)
    wide = run_traces(scenes, math="libm")
    rows = wide[0][1].shape[0]
    budget = 2 * 8 * (whole.TRACE_HEAD + whole.TRACE_CART * 2) * rows
    assert lanes_batch.lanes_for(scenes[0], rows - 1, budget) == 2
    assert lanes_batch.lanes_for(scenes[0], rows - 1) >= 5  # by default, all five in one batch
    narrow = run_traces(scenes, math="libm", trace_bytes=budget)  # batches of 2, 2 and 1
    for a, b in zip(wide, narrow):
        assert_same_bits(b[1], a[1])
        assert b[3] == a[3]


def test_a_stopped_run_lets_its_batch_go_without_the_garbage_collector():
    """A run the guard stopped keeps its error as a value, without the traceback whose frames held the
    batch's traces and the list the error sits in (a cycle: a sweep's worker grew by a batch's traces
    at every stopped run until the collector came round, 560 MB for 1024 five-cart runs)."""
    import gc
    import weakref

    scenes = random_scenes(3, "governor", 6, 300 + sorted(ALL_LAWS).index("governor") + 50, reverse=True)
    gc.collect()
    gc.disable()
    try:
        runs = run_traces(scenes, fidelity="dynamic")
        stopped = [err for *_, err in runs if err is not None]
        assert stopped and all(err.__traceback__ is None for err in stopped)
        block = weakref.ref(runs[0][1].base)  # the batch's traces, every lane's a view of it
        alone = run_trace(next(sc for sc, run in zip(scenes, runs) if run[4] is not None), fidelity="dynamic")
        assert alone[4].__traceback__ is None
        trace = weakref.ref(alone[1])
        del runs, stopped, alone
        assert block() is None and trace() is None
        folded = next(sc for sc in scenes if run_trace(sc, method="RK45", fidelity="dynamic")[4] is not None)
        tick_by_tick = run_trace(folded, method="RK45", fidelity="dynamic")  # an adaptive method: no whole-run kernel
        assert tick_by_tick[4].__traceback__ is None
        refused = lanes_batch.run_each([(scenes[0], {"method": "rk5"})])[0]
        assert isinstance(refused, REFUSALS) and refused.__traceback__ is None
    finally:
        gc.enable()
