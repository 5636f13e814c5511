"""The lanes' math (physics/kernel/vmath.py) against the C library, and what the compiler makes of it.

Each function is held to the bound its algorithm is known for (fdlibm's and Cephes' own figures,
module docstring) in units in the last place of the C library's value (``math``), on random
arguments across its range and at the special values; its two lives (compiled, plain Python) give
the same bits; and its loop over lanes compiles to packed vector instructions, with no call to a
C library function left in it."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from mta_sim_ros import jit
from mta_sim_ros.physics.kernel import vmath

RNG_SEED = 20261205
SPECIAL = [0.0, -0.0, 1.0, -1.0, 0.5, -2.5, 1e-300, -5e-324, 1e300, math.inf, -math.inf, math.nan]


def ulps(got: np.ndarray, want: np.ndarray) -> np.ndarray:
    """|got - want| in units in the last place of want (of the smallest normal near 0)."""
    return np.abs(got - want) / np.spacing(np.maximum(np.abs(want), np.finfo(float).tiny))


def c_library(fn, *columns) -> np.ndarray:
    return np.array([fn(*args) for args in zip(*columns)])


def same(got: np.ndarray, want: np.ndarray) -> bool:
    """Equal values, equal signs of zero, NaN where NaN."""
    return all((math.isnan(a) and math.isnan(b)) or (a == b and math.copysign(1, a) == math.copysign(1, b))
               for a, b in zip(got, want))


def sincos(x):
    s, c = np.empty_like(x), np.empty_like(x)
    with np.errstate(all="ignore"):  # without numba: plain Python computes both sides of every pick
        vmath.sincos_lanes(x, s, c)
    return s, c


def one(lanes, *columns):
    out = np.empty_like(columns[0])
    with np.errstate(all="ignore"):
        lanes(*columns, out)
    return out


@pytest.mark.parametrize("scale", [1.0, 1e3, vmath.REDUCTION_LIMIT])
def test_sin_and_cos_are_within_one_ulp(scale):
    x = np.random.default_rng(RNG_SEED).uniform(-scale, scale, 200_000)
    s, c = sincos(x)
    assert ulps(s, c_library(math.sin, x)).max() <= 1.0
    assert ulps(c, c_library(math.cos, x)).max() <= 1.0


def test_sin_and_cos_where_the_reduction_cancels():
    """Next to n pi/2, where x - n pi/2 loses most of its bits: every 97th n up to the limit, and
    the doubles one and two ulp either side."""
    n = np.arange(-2 ** 20, 2 ** 20 + 1, 97, dtype=float)
    centre = n * (math.pi / 2)
    x = np.concatenate([centre, *(np.nextafter(centre, math.copysign(math.inf, d)) for d in (-1.0, 1.0)),
                        *(np.nextafter(np.nextafter(centre, d * math.inf), d * math.inf) for d in (-1.0, 1.0))])
    x = x[np.abs(x) <= vmath.REDUCTION_LIMIT]
    s, c = sincos(x)
    assert ulps(s, c_library(math.sin, x)).max() <= 1.0
    assert ulps(c, c_library(math.cos, x)).max() <= 1.0


def test_sin_and_cos_are_nan_beyond_the_reduction_limit():
    x = np.array([np.nextafter(vmath.REDUCTION_LIMIT, math.inf), -2e6, 1e8, 1e20, 1e300])
    assert all(math.isnan(v) for v in np.concatenate(sincos(x)))


def test_sin_and_cos_at_zeros_infinities_and_nan():
    x = np.array([0.0, -0.0, math.inf, -math.inf, math.nan])
    s, c = sincos(x)
    assert same(s, [0.0, -0.0, math.nan, math.nan, math.nan])
    assert same(c, [1.0, 1.0, math.nan, math.nan, math.nan])
    plain_s, plain_c = np.empty_like(x), np.empty_like(x)
    with np.errstate(invalid="ignore"):  # plain Python too: numpy's inf - inf, no OverflowError
        vmath.sincos_lanes.py_func(x, plain_s, plain_c)
    assert same(plain_s, s) and same(plain_c, c)


def test_atan2_is_within_two_ulp_and_the_c_library_at_zeros_and_infinities():
    rng = np.random.default_rng(RNG_SEED)
    y = rng.standard_normal(200_000) * 10.0 ** rng.uniform(-8, 8, 200_000)
    x = rng.standard_normal(200_000) * 10.0 ** rng.uniform(-8, 8, 200_000)
    assert ulps(one(vmath.atan2_lanes, y, x), c_library(math.atan2, y, x)).max() <= 2.0
    ys, xs = (np.array(a).ravel() for a in np.meshgrid(SPECIAL, SPECIAL))
    got, want = one(vmath.atan2_lanes, ys, xs), c_library(math.atan2, ys, xs)
    exact = np.isin(np.abs(ys), [0.0, math.inf]) | np.isin(np.abs(xs), [0.0, math.inf]) | np.isnan(ys) | np.isnan(xs)
    assert same(got[exact], want[exact])
    assert ulps(got[~exact], want[~exact]).max() <= 2.0


def c_exp(x: float) -> float:
    try:
        return math.exp(x)
    except OverflowError:
        return math.inf


def test_exp_is_within_one_ulp_from_underflow_to_overflow():
    x = np.random.default_rng(RNG_SEED).uniform(vmath.EXP_MIN, vmath.EXP_MAX, 200_000)
    x = np.concatenate([x, np.random.default_rng(RNG_SEED + 1).uniform(-1.0, 1.0, 50_000)])
    got, want = one(vmath.exp_lanes, x), c_library(c_exp, x)
    normal = want >= np.finfo(float).tiny
    assert ulps(got[normal], want[normal]).max() <= 1.0
    assert np.abs(got[~normal] - want[~normal]).max() <= np.spacing(0.0)  # subnormals: two roundings, one ulp
    edges = np.array([0.0, -0.0, math.inf, -math.inf, math.nan, 1e300, -1e300, 709.79, -745.14, -800.0])
    assert same(one(vmath.exp_lanes, edges), c_library(c_exp, edges))  # 1, 0 or inf exactly


def test_tanh_is_within_two_ulp():
    rng = np.random.default_rng(RNG_SEED)
    x = np.concatenate([rng.uniform(-1.0, 1.0, 100_000), rng.uniform(-30.0, 30.0, 100_000),
                        rng.uniform(-1e-6, 1e-6, 20_000), [0.625, -0.625, 22.0, -22.0]])
    assert ulps(one(vmath.tanh_lanes, x), c_library(math.tanh, x)).max() <= 2.0
    edges = np.array(SPECIAL)
    assert same(one(vmath.tanh_lanes, edges), c_library(math.tanh, edges))


@pytest.mark.skipif(not jit.ENABLED, reason="compares compiled code with plain Python: numba not used here")
def test_compiled_and_plain_python_give_the_same_bits():
    rng = np.random.default_rng(RNG_SEED)
    x = np.concatenate([rng.uniform(-50.0, 50.0, 2000), SPECIAL, [1e8, -1e20, 709.79, -745.14, 22.5, 0.625]])
    y = rng.permutation(x)
    with np.errstate(all="ignore"):  # plain Python computes both sides of every pick, in numpy scalars
        for lanes, columns in [(vmath.atan2_lanes, (y, x)), (vmath.exp_lanes, (x,)), (vmath.tanh_lanes, (x,))]:
            compiled, plain = np.empty_like(x), np.empty_like(x)
            lanes(*columns, compiled)
            lanes.py_func(*columns, plain)
            assert same(compiled, plain)
        s, c = np.empty_like(x), np.empty_like(x)
        vmath.sincos_lanes.py_func(x, s, c)
    assert all(same(a, b) for a, b in zip(sincos(x), (s, c)))


@pytest.mark.skipif(not jit.ENABLED, reason="reads numba's assembly: numba not used here")
@pytest.mark.parametrize("name", ["sincos_lanes", "atan2_lanes", "exp_lanes", "tanh_lanes"])
def test_the_loop_over_lanes_is_vectorised(name):
    lanes = getattr(vmath, name)
    x = np.linspace(-3.0, 3.0, 64)
    args = (x, np.empty_like(x), np.empty_like(x)) if name in ("sincos_lanes", "atan2_lanes") else (x, np.empty_like(x))
    seen = jit.vector_evidence(lanes, *args)
    assert seen["packed"] >= 10, f"the loop holds {seen['packed']} packed instructions: not vectorised"
    assert seen["vector_types"], "no vector type in the loop's IR"
    assert not seen["c_math_calls"], seen["c_math_calls"]


@pytest.mark.skipif(not jit.ENABLED, reason="reads numba's assembly: numba not used here")
def test_the_evidence_sees_a_loop_that_calls_the_c_library():
    """The reading above can fail: the same loop over math.atan2 is one C call a value, no lanes."""
    x = np.linspace(-3.0, 3.0, 64)
    seen = jit.vector_evidence(LIBM_ATAN2_LANES, x, x, np.empty_like(x))
    assert seen["packed"] == 0 and seen["c_math_calls"] == ["atan2"]


@pytest.mark.skipif(not jit.ENABLED, reason="numba's own check: numba not used here")
def test_numba_inlines_each_function_twice_into_one_loop_without_a_warning():
    """Two inlined calls of a function holding an if-expression trip numba issue 9489 on Python 3.11
    (NumbaIRAssumptionWarning: a variable not in scope); vmath's selects are ``pick`` calls instead."""
    x = np.linspace(-3.0, 3.0, 64)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        jit.vector_evidence(TWICE_LANES, x, np.empty_like(x))


def twice_lanes(x, out):
    for j in range(x.shape[0]):
        s, c = vmath.sincos(x[j])
        s2, c2 = vmath.sincos(s + c)
        out[j] = vmath.atan2(s2, c2) + vmath.atan2(c2, s2) + vmath.tanh(s) + vmath.tanh(c) + vmath.exp(s) + vmath.exp(c)


TWICE_LANES = jit.lanes(twice_lanes)


def libm_atan2_lanes(y, x, out):
    for j in range(x.shape[0]):
        out[j] = math.atan2(y[j], x[j])


LIBM_ATAN2_LANES = jit.lanes(libm_atan2_lanes)
