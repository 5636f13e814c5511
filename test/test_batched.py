"""The right-hand side of a batch of schemes, one per SIMD lane (physics/kernel/batched.py), against
the kernel's own ``rhs`` run scheme by scheme (which test_kernel holds to the readable reference,
bit for bit).

One source, two bindings: with the C library's math the batch gives every lane's y', record,
traction and mass bit for bit as ``rhs`` does; with vmath (the binding a sweep uses) within a few
ulp. Random trains of 1-5 carts with every traction law, drafts on several carts, on the level and
on a tilted plane, with and without held branches (each lane on its own branches); and the
compiled loop is vectorised. The same for one Runge-Kutta step across lanes against ``rk.rk_step``,
the steering angle from the actuator's closed form included, and for the switching functions
against ``motion.switches``."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trains
from test_kernel import LAWS

from mta_sim_ros import jit
from mta_sim_ros.integrate import rk, rk_lanes
from mta_sim_ros.integrate.tableau import TABLEAUX
from mta_sim_ros.physics import kernel
from mta_sim_ros.physics.dynamics import Model
from mta_sim_ros.physics.kernel import batched
from mta_sim_ros.physics.kinematic import KinematicModel
from mta_sim_ros.physics.spec import Draft
from mta_sim_ros.physics.terrain import Plane

ALL_LAWS = {**LAWS, "kinematic": None}


def least_packed() -> dict:
    """The fewest packed instructions each compiled batch loop must hold (3 carts). Measured on
    2026-12-07: LLVM 22 (PyPI's llvmlite) 390 in rhs_lanes, 456 in an rk4 step, 151 in the switching
    functions; LLVM 14 (Ubuntu 24.04's numba 0.59) 2425, 3201 and 1143 with the runtime alias checks
    jit.py allows (each loop versioned: a vector and a scalar form), 413, 1182 and 718 without them,
    where its vectoriser left the loops that needed more checks scalar (docs/lanes.md)."""
    import llvmlite.binding

    if llvmlite.binding.llvm_version_info[0] >= 15:
        return {"rhs": 200, "step": 300, "switches": 100}
    return {"rhs": 1000, "step": 1500, "switches": 500}


def assert_same_bits(got, want):
    """Equal to the bit, the sign of zero included; NaN where NaN (IEEE leaves a NaN's sign to the
    operation that made it)."""
    got, want = np.asarray(got, dtype=np.float64), np.asarray(want, dtype=np.float64)
    assert got.shape == want.shape
    nan = np.isnan(want)
    np.testing.assert_array_equal(np.isnan(got), nan)
    np.testing.assert_array_equal(got[~nan].view(np.int64), want[~nan].view(np.int64))


def random_train(n: int, rng, traction, sloped: bool):
    """n carts of random size; drafts on the last cart and, for n > 1, two on cart 2 (one with B)."""
    carts = [(rng.uniform(2.0, 7.0), rng.uniform(-1.5, 2.0), rng.uniform(0.3, 2.5), rng.uniform(2e3, 2e4),
              rng.uniform(1e4, 1e5)) for _ in range(n)]
    tr = trains.train(carts=carts, traction=traction or trains.GOVERNOR)
    if n > 1:
        extra = (Draft("cart2", A=rng.uniform(20, 60), B=rng.uniform(0, 4), C=0.0, soil_factor=1.0, width=20.0,
                       depth=rng.uniform(5, 10)), Draft("cart2", A=rng.uniform(2e3, 5e3), width=3.0))
        tr = dataclasses.replace(tr, draft=tr.draft + extra)
    return dataclasses.replace(tr, terrain=Plane(rng.uniform(-8, 8), rng.uniform(-6, 6))) if sloped else tr


def batch(n: int, law: str, sloped: bool, held: bool, width: int, seed: int):
    """(P per lane, stacked P, y, commands, v_sets, max_rates, mode) of ``width`` random schemes."""
    rng = np.random.default_rng(seed)
    models = []
    for _ in range(width):
        tr = random_train(n, rng, ALL_LAWS[law], sloped)
        models.append(KinematicModel(tr) if law == "kinematic" else Model(tr))
    Ps = [m.P for m in models]
    y = np.stack([trains.random_state(m, rng, steering=0.7, slow=True) for m in models], axis=1)
    commands, v_sets = rng.uniform(-1.0, 1.0, width), rng.uniform(-1.0, 4.0, width)
    max_rates = np.array([kernel.max_rate_of(P) for P in Ps]) * rng.choice([1.0, 0.3], width)
    rows = kernel.FORCE_SWITCHES + n + 2
    if held:  # each lane on branches of its own, the state's or not
        mode = rng.choice([kernel.LOW, kernel.HIGH], (rows, width)).astype(np.int64)
    else:
        mode = np.empty((0, width), dtype=np.int64)
    return Ps, kernel.stack(Ps), np.ascontiguousarray(y), commands, v_sets, max_rates, mode


def one_by_one(Ps, y, commands, v_sets, max_rates, mode):
    """Each lane through the kernel's ``rhs`` (as plain Python, which test_kernel holds to the compiled
    rhs and the reference bit for bit): (dy, rec, F_A1, M) stacked as the batch returns them."""
    with np.errstate(divide="ignore", invalid="ignore"):  # held at V = 0 on the power limit: inf, as compiled
        return stacked(Ps, y, commands, v_sets, max_rates, mode)


def stacked(Ps, y, commands, v_sets, max_rates, mode):
    dys, recs, tractions, masses = [], [], [], []
    for j, P in enumerate(Ps):
        n = int(P[kernel.H.n])
        dy, rec = np.empty(y.shape[0]), np.empty((n, kernel.REC))
        traction, mass = kernel.rhs(P, y[:, j].copy(), commands[j], v_sets[j], max_rates[j], dy, rec, mode[:, j].copy())
        dys.append(dy)
        recs.append(rec)
        tractions.append(traction)
        masses.append(mass)
    return np.stack(dys, axis=1), np.stack(recs, axis=2), np.array(tractions), np.array(masses)


CASES = [(n, law, sloped, held) for n in (1, 2, 3, 5) for law in ALL_LAWS for sloped in (False, True)
         for held in (False, True)]


def seed_of(n, law, sloped, held) -> int:
    return 1000 * n + 10 * list(ALL_LAWS).index(law) + 2 * sloped + held


@pytest.mark.parametrize("n, law, sloped, held", CASES)
def test_with_the_c_library_a_batch_is_rhs_lane_by_lane_bit_for_bit(n, law, sloped, held):
    Ps, P, y, commands, v_sets, max_rates, mode = batch(n, law, sloped, held, 9, seed=seed_of(n, law, sloped, held))
    want = one_by_one(Ps, y, commands, v_sets, max_rates, mode)
    got = batched.rhs_lanes_libm_of(P, y, commands, v_sets, max_rates, mode, True)
    forces = law != "kinematic"  # the kinematic level records kapT, kapB and psi only
    columns = slice(None) if forces else [kernel.KAPT, kernel.KAPB, kernel.PSI]
    assert_same_bits(got[0], want[0])
    assert_same_bits(got[1][:, columns], want[1][:, columns])
    assert_same_bits(got[2], want[2])
    if forces:
        assert_same_bits(got[3], want[3])


@pytest.mark.parametrize("n, law, sloped, held", CASES)
def test_with_vmath_a_batch_is_within_a_few_ulp_of_rhs(n, law, sloped, held):
    Ps, P, y, commands, v_sets, max_rates, mode = batch(n, law, sloped, held, 33, seed=7 + seed_of(n, law, sloped, held))
    dy_want, _, traction_want, _ = one_by_one(Ps, y, commands, v_sets, max_rates, mode)
    dy, _, traction, _ = batched.rhs_lanes_of(P, y, commands, v_sets, max_rates, mode, False)
    # a branch held where its law's formula has no value (the power limit at V = 0) gives inf in both
    finite = np.isfinite(dy_want)
    np.testing.assert_array_equal(dy[~finite], dy_want[~finite])
    dy, dy_want = np.where(finite, dy, 0.0), np.where(finite, dy_want, 0.0)
    # each row against its own scale: y' sums terms (M V' = F - Q - R) that may nearly cancel
    scale = np.max(np.abs(dy_want), axis=1, keepdims=True) + 1e-300
    assert np.max(np.abs(dy - dy_want) / scale) < 1e-13
    finite = np.isfinite(traction_want)
    np.testing.assert_array_equal(traction[~finite], traction_want[~finite])
    assert np.max(np.abs(traction[finite] - traction_want[finite]), initial=0.0) <= \
        1e-13 * (np.max(np.abs(traction_want[finite]), initial=0.0) + 1.0)


@pytest.mark.skipif(not jit.ENABLED, reason="without numba both lives are the plain function")
def test_the_two_lives_of_a_batch_give_the_same_bits():
    Ps, P, y, commands, v_sets, max_rates, mode = batch(3, "governor", True, True, 5, seed=3)
    compiled = batched.rhs_lanes_of(P, y, commands, v_sets, max_rates, mode, True)
    with np.errstate(divide="ignore", invalid="ignore"):
        plain = batched.rhs_lanes_of.py_func(P, y, commands, v_sets, max_rates, mode, True)
    for a, b in zip(compiled, plain):
        assert_same_bits(a, b)


@pytest.mark.skipif(not jit.ENABLED, reason="reads what numba compiled")
def test_the_batch_loop_is_vectorised_and_calls_no_c_math():
    _, P, y, commands, v_sets, max_rates, mode = batch(3, "governor", True, True, 16, seed=5)
    vmath_loop = jit.vector_evidence(batched.rhs_lanes_of, P, y, commands, v_sets, max_rates, mode, True)
    libm_loop = jit.vector_evidence(batched.rhs_lanes_libm_of, P, y, commands, v_sets, max_rates, mode, True)
    assert vmath_loop["packed"] >= least_packed()["rhs"], vmath_loop
    assert vmath_loop["c_math_calls"] == [], vmath_loop
    assert {"sin", "cos", "atan2"} <= set(libm_loop["c_math_calls"]), libm_loop  # the check sees calls
    switching = jit.vector_evidence(batched.switches_lanes_of, P, y, v_sets)
    assert switching["packed"] >= least_packed()["switches"] and switching["c_math_calls"] == [], switching


def test_schemes_of_another_shape_are_not_stacked():
    rng = np.random.default_rng(1)
    level = Model(random_train(3, rng, trains.GOVERNOR, False)).P
    with pytest.raises(ValueError, match="scheme 1 has another shape"):
        kernel.stack([level, Model(random_train(2, rng, trains.GOVERNOR, False)).P])
    with pytest.raises(ValueError, match="scheme 1 has another shape"):
        kernel.stack([level, Model(random_train(3, rng, trains.GOVERNOR, True)).P])
    with pytest.raises(ValueError, match="at least one"):
        kernel.stack([])
    assert kernel.stack([level, level]).shape == (level.shape[0], 2)


def test_a_batch_on_a_height_grid_is_refused_by_the_kernel_too():
    """A P not built by kernel.stack, on a height grid: refused, not run without its relief."""
    _, P, y, commands, v_sets, max_rates, mode = batch(2, "governor", False, False, 3, seed=2)
    P = P.copy()
    P[kernel.H.relief] = 1.0
    with pytest.raises(ValueError, match="height grid is not batched"):
        batched.rhs_lanes_of(P, y, commands, v_sets, max_rates, mode, False)


# -- one Runge-Kutta step across lanes (integrate/rk_lanes.py) ---------------------------------------

def lags(Ps, y, commands, max_rates, on: bool, T0: float):
    """rk_step's ``lag`` per lane: the actuator's closed form from the state's psi_1 (its release
    from ``actuator_release``: some lanes rate-limited through the step, some released in it)."""
    lag = np.zeros((5, len(Ps)))
    if on:
        for j, P in enumerate(Ps):
            psi = y[int(P[kernel.H.n]) + 2, j]
            lag[:, j] = 1.0, psi, commands[j], kernel.actuator_release(P, psi, commands[j], max_rates[j]), T0
    return lag


def step_one_by_one(Ps, T, y, commands, v_sets, max_rates, h, mode, lag):
    """Each lane through rk.rk_step (plain Python, bit for bit the compiled stepper: test_kernel)."""
    out = np.empty_like(y)
    for j, P in enumerate(Ps):
        size = y.shape[0]
        K, tmp = np.empty((T.shape[0] - 2, size)), np.empty(size)
        rk.rk_step(kernel.model_rhs, P, T, 0.0, y[:, j].copy(), commands[j], v_sets[j], max_rates[j], h, K, tmp,
                   out[:, j], np.empty((0, kernel.REC)), mode[:, j].copy(), lag[:, j].copy())
    return out


STEP_CASES = [(n, method, held, on) for n in (1, 3, 5) for method in ("euler", "heun", "kutta3", "rk4", "rk38")
              for held, on in ((False, False), (True, True))]


@pytest.mark.parametrize("n, method, held, on", STEP_CASES)
def test_a_step_across_lanes_is_rk_step_lane_by_lane(n, method, held, on):
    """With the C library's math bit for bit; with vmath within 1e-13 of each row's scale."""
    law = "governor" if n != 3 else "prescribed_speed, accel limit"
    Ps, P, y, commands, v_sets, max_rates, mode = batch(n, law, n == 5, held, 11, seed=50 + n)
    if held:  # each lane on its state's branches, as a step's start holds them
        release = lags(Ps, y, commands, max_rates, True, 0.0)[3]
        mode = np.stack([kernel.mode_of(P_j, y[:, j].copy(), commands[j], v_sets[j], bool(np.isfinite(release[j])))
                         for j, P_j in enumerate(Ps)], axis=1)
    T = TABLEAUX[method].packed
    lag = lags(Ps, y, commands, max_rates, on, 0.03)
    with np.errstate(divide="ignore", invalid="ignore"):
        want = step_one_by_one(Ps, T, y, commands, v_sets, max_rates, 0.02, mode, lag)
    assert_same_bits(rk_lanes.step_lanes_libm_of(P, T, y, commands, v_sets, max_rates, 0.02, mode, lag), want)
    got = rk_lanes.step_lanes_of(P, T, y, commands, v_sets, max_rates, 0.02, mode, lag)
    finite = np.isfinite(want)
    np.testing.assert_array_equal(got[~finite], want[~finite])
    scale = np.max(np.abs(np.where(finite, want, 0.0)), axis=1, keepdims=True) + 1e-300
    assert np.max(np.abs(np.where(finite, got - want, 0.0)) / scale) < 1e-13


@pytest.mark.skipif(not jit.ENABLED, reason="reads what numba compiled")
def test_the_step_loop_is_vectorised():
    Ps, P, y, commands, v_sets, max_rates, mode = batch(3, "governor", False, False, 16, seed=9)
    T = TABLEAUX["rk4"].packed
    lag = lags(Ps, y, commands, max_rates, True, 0.0)
    seen = jit.vector_evidence(rk_lanes.step_lanes_of, P, T, y, commands, v_sets, max_rates, 0.02, mode, lag)
    assert seen["packed"] >= least_packed()["step"] and seen["c_math_calls"] == [], seen


def test_a_branch_that_is_not_taken_divides_by_nothing():
    """The laws on numbers compute every branch and pick one: a branch not taken must not divide
    where the law's own branch does not (compiled with Python's error model, x / 0 raises). Held on
    the steering's rate limit with tau = 0 the rate is +-max_rate; rate-limited, the actuator's
    closed form is the straight line; without a power limit, the traction limit is max_force."""
    P = Model(random_train(2, np.random.default_rng(4), trains.GOVERNOR, False)).P.copy()
    P[kernel.H.time_constant] = 0.0
    y = np.zeros(2 + 5)
    y[4], y[5] = 0.1, 2.0  # psi_1, V
    mode = np.full(kernel.FORCE_SWITCHES + 2 + 2, kernel.LOW, dtype=np.int64)
    mode[0] = kernel.HIGH
    dy = kernel.held_rhs_of(P, y, 0.5, 2.0, 0.6, mode)
    assert dy[4] == 0.6
    P[kernel.H.time_constant] = 0.2
    assert kernel.actuator_psi(P, 0.1, 0.5, 0.6, 1.0, 0.5) == 0.1 + 0.6 * 0.5
    P[kernel.H.max_power] = np.inf
    assert kernel.traction_limit(P, 0.0, kernel.NATURAL, kernel.HIGH) == P[kernel.H.max_force]


@pytest.mark.parametrize("n, law, sloped", [(n, law, sloped) for n in (1, 2, 3, 5) for law in ALL_LAWS
                                            for sloped in (False, True)])
def test_the_switching_functions_across_lanes_are_switches_lane_by_lane(n, law, sloped):
    Ps, P, y, commands, v_sets, _, _ = batch(n, law, sloped, False, 9, seed=300 + seed_of(n, law, sloped, False))
    want = [kernel.switches_of(P_j, y[:, j].copy(), commands[j], v_sets[j]) for j, P_j in enumerate(Ps)]
    g, m = batched.switches_lanes_libm_of(P, y, v_sets)
    assert m == len(want[0])
    assert_same_bits(g, np.stack(want, axis=1).reshape(m, len(Ps)))
    g, _ = batched.switches_lanes_of(P, y, v_sets)
    want = np.stack(want, axis=1).reshape(m, len(Ps))
    assert np.all(np.abs(g - want) <= 1e-13 * (np.abs(want).max(axis=1, keepdims=True) + 1e-300))
