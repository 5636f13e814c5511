"""Facts the scaling benchmark (``python -m benchmarks scaling``) and the fast right-hand side rely on.
No timing here: counts and memory, which do not depend on the machine.

- The kernel's right-hand side (``kernel.rhs``, one fused pass over the carts) does O(n) work:
  each transcendental function runs a fixed number of times per cart, and the memory it allocates
  grows linearly with n and is all released (counted on its plain-Python run, where every call
  and allocation is visible; the compiled run is the same source). test_kernel.py holds it equal
  to the reference path bit for bit.
- A run keeps nothing per tick (no history): traced memory does not grow over ticks.
- The bench's 100-cart train is a valid train: it settles on the closed-form steady circles.
"""
from __future__ import annotations

import dataclasses
import gc
import math
import os
import subprocess
import sys
import textwrap
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import trains

from benchmarks.throughput.scaling import ENDLESS, bench_scene, default_train, scaled_train, steering_amplitude
from mta_sim_ros.physics import kernel
from mta_sim_ros.physics.dynamics import Model
from mta_sim_ros.physics.steady import steady_circle
from mta_sim_ros.run.simulation import Simulation, run_scene

REPO = Path(__file__).resolve().parents[1]

LAWS = {
    "governor": trains.GOVERNOR,
    "constant": trains.Traction("constant", force=40000.0),
    "prescribed_speed": trains.prescribed(3.0),
}


def python_rhs(model, y, command, v_set):
    """The kernel's y' run as plain Python (kernel.rhs_of.py_func)."""
    return kernel.rhs_of.py_func(model.P, np.asarray(y, dtype=np.float64), float(command), float(v_set),
                                 kernel.max_rate_of(model.P))


def long_train(n: int, traction=trains.GOVERNOR):
    """n carts cycling through the test carts (with a draft on the last), as trains.train."""
    return trains.train(carts=[trains.CARTS[k % len(trains.CARTS)] for k in range(n)], traction=traction)




def test_algorithm_1_still_goes_through_the_reference_path():
    tr = long_train(4)
    y = trains.random_state(Model(tr), np.random.default_rng(0), spread=0.3)
    a1, a2 = Model(tr, algorithm=1), Model(tr, algorithm=2)
    np.testing.assert_allclose(a1.rhs(0.0, y, 0.1, 3.0), a2.rhs(0.0, y, 0.1, 3.0), rtol=1e-9, atol=1e-9)


def math_calls(fn, names) -> dict[str, int]:
    """How many times ``fn()`` calls each of the math functions ``names`` (the interpreter's
    profile hook hears every call of a C function: nothing is replaced)."""
    wanted = {getattr(math, name): name for name in names}
    counts: dict[str, int] = {}

    def hear(frame, event, arg):
        if event == "c_call" and arg in wanted:
            counts[wanted[arg]] = counts.get(wanted[arg], 0) + 1

    before = sys.getprofile()
    sys.setprofile(hear)
    try:
        fn()
    finally:
        sys.setprofile(before)
    return counts


def test_rhs_work_is_linear_in_the_carts():
    """Per call: sin and cos once per cart plus once for the course, sqrt twice per cart but the
    last, atan2 once per hitch, tanh once per cart: exactly linear in n."""
    for n in (1, 3, 10, 100):
        model = Model(long_train(n))
        y = trains.random_state(model, np.random.default_rng(1), spread=0.3)
        counts = math_calls(lambda: python_rhs(model, y, 0.1, 3.0), ("sin", "cos", "sqrt", "atan2", "tanh"))
        expected = {"sin": n + 1, "cos": n + 1, "sqrt": 2 * n - 1, "atan2": n - 1, "tanh": n}
        assert counts == {k: v for k, v in expected.items() if v}, (n, counts)


def traced_peak(fn) -> tuple[int, int]:
    """(peak bytes allocated during fn(), bytes still held after it and its result are dropped).
    The garbage collector's callbacks are off meanwhile: Hypothesis (test_fuzz_inputs.py) leaves
    one that keeps a few bytes at each collection."""
    callbacks = gc.callbacks[:]
    gc.callbacks.clear()
    gc.collect()
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        result = fn()
        peak = tracemalloc.get_traced_memory()[1] - before
        del result
        gc.collect()
        after = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
        gc.callbacks.extend(callbacks)
    return peak, after


@pytest.mark.slow
def test_rhs_memory_is_linear_in_the_carts_and_released():
    peaks = {}
    for n in (100, 200, 400):
        model = Model(long_train(n))
        y = trains.random_state(model, np.random.default_rng(2), spread=0.3)
        python_rhs(model, y, 0.1, 3.0)  # warm: nothing lazily built on the first call counts
        peak, held = traced_peak(lambda: python_rhs(model, y, 0.1, 3.0))
        peaks[n] = peak
        assert held < 256, f"n = {n}: {held} bytes kept after the call"  # tracemalloc's own few bytes
    # the same bytes per cart from 100 to 200 as from 200 to 400 (the output array's 8 B, and the
    # float objects the plain-Python run makes and frees); no n^2 term: one n x n float64 array
    # would part the two slopes by 8 B x (600 - 300) = 2400 B a cart, allocator rounding by a few
    per_cart = (peaks[400] - peaks[200]) / 200
    assert per_cart == pytest.approx((peaks[200] - peaks[100]) / 100, abs=8.0), peaks
    assert per_cart < 150, peaks


@pytest.mark.slow
def test_a_run_keeps_no_history():
    """Traced memory after 1000 more ticks of advance + outputs is what it was after 200: cost per
    simulated second cannot grow from anything kept per tick (the kernels run as plain Python here,
    where tracemalloc sees every allocation; the compiled run is below)."""
    sim = Simulation(bench_scene(scaled_train(3), 100.0, duration=ENDLESS), compiled=False)

    def ticks(k):
        for _ in range(k):
            command, v_set = sim.scheduled_inputs(math.fmod(sim.t, 60.0))
            sim.advance(command, v_set)
            sim.outputs()

    ticks(200)
    gc.collect()
    tracemalloc.start()
    try:
        ticks(200)
        gc.collect()
        base = tracemalloc.get_traced_memory()[0]
        ticks(1000)
        gc.collect()
        grown = tracemalloc.get_traced_memory()[0] - base
    finally:
        tracemalloc.stop()
    assert grown < 4096, f"{grown} bytes more after 1000 ticks"


@pytest.mark.slow
def test_the_compiled_kernels_free_every_array_they_make():
    """The compiled kernels' arrays live in numba's runtime, which tracemalloc does not see: count
    them with numba's allocation statistics (NUMBA_NRT_STATS=1, in a process of its own). Over
    1000 ticks as many are freed as are made, but for those the last state and Outputs hold."""
    code = textwrap.dedent("""
        import math
        from numba.core.runtime import rtsys
        from mta_sim_ros.run.simulation import Simulation
        from benchmarks.throughput.scaling import ENDLESS, bench_scene, scaled_train
        sim = Simulation(bench_scene(scaled_train(3), 100.0, duration=ENDLESS))
        assert sim.compiled

        def ticks(k):
            for _ in range(k):
                sim.advance(*sim.scheduled_inputs(math.fmod(sim.t, 60.0)))
                out = sim.outputs()
            return out

        out = ticks(200)
        s0 = rtsys.get_allocation_stats()
        out = ticks(1000)
        s1 = rtsys.get_allocation_stats()
        print(s1.alloc - s0.alloc, (s1.alloc - s1.free) - (s0.alloc - s0.free))
    """)
    env = dict(os.environ, NUMBA_NRT_STATS="1")
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH", "")) if p)
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    made, kept = map(int, done.stdout.split())
    assert made >= 1000  # the kernels did allocate: the statistics are live
    assert kept <= 0, f"{kept} arrays more alive after 1000 ticks"


def test_the_bench_trains_are_the_default_train_cut_or_lengthened():
    three, default = scaled_train(3), default_train()
    assert three.carts == default.carts and three.draft == default.draft
    assert three.traction.kp == pytest.approx(default.traction.kp)
    assert three.traction.max_force == pytest.approx(default.traction.max_force)
    hundred = scaled_train(100)
    assert hundred.n == 100 and len({c.name for c in hundred.carts}) == 100
    assert {r.cart for r in hundred.rolling} == {c.name for c in hundred.carts}
    assert [d.cart for d in hundred.draft] == [d.cart for d in default.draft]
    assert hundred.carts[0] == default.carts[0] and hundred.carts[-1] == default.carts[-1]
    # the governor is scaled with the mass: the same time constant kp / M as the default train
    ratio = sum(c.mass for c in hundred.carts) / sum(c.mass for c in three.carts)
    assert hundred.traction.kp == pytest.approx(three.traction.kp * ratio)
    assert steering_amplitude(hundred) > 0.0
    steady_circle(hundred, 2.0 * steering_amplitude(hundred) * 0.999)  # exists: the amplitude is half the limit


def test_the_100_cart_train_settles_on_the_closed_form_circles():
    """Starting straight, the bench's 100-cart train held at the steering it oscillates to settles
    on the circles of model.steady.steady_circle: the chain is right at n = 100, not only n <= 5."""
    tr = dataclasses.replace(scaled_train(100), traction=trains.prescribed(5.0))
    steering = steering_amplitude(tr)
    expected = steady_circle(tr, steering)
    sc = trains.scene(tr, table=((0.0,), (steering,)), duration=8000.0 / 5.0, rate=0.05, method="DOP853",
                      step=20.0, rtol=1e-11, atol=1e-11, steering=steering)
    sim, err = run_scene(sc)
    assert err is None, err
    out = sim.model.outputs(sim.t, sim.y, steering, 5.0)
    th1 = out.heading[0]
    centre = out.axle[0] + expected.R_B[0] * np.array([-math.sin(th1), math.cos(th1)])
    np.testing.assert_allclose(np.hypot(*(out.axle - centre).T), expected.R_B, rtol=1e-6)
    np.testing.assert_allclose(np.hypot(*(out.front - centre).T), expected.R_A, rtol=1e-6)
    np.testing.assert_allclose(np.hypot(*(out.com - centre).T), expected.R_C, rtol=1e-6)
    np.testing.assert_allclose(out.hitch_angle, expected.hitch_angles, rtol=1e-5, atol=1e-9)
