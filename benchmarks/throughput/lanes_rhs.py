"""The train's whole right-hand side across lanes, for ``python -m benchmarks lanes``: the kernel's
``motion.rhs`` one scheme a call against ``batched.rhs_lanes`` (vmath) and ``rhs_lanes_libm`` (the
same source with the C library's math), on batches of random trains of 2, 3 and 5 carts with the
governor, a draft on the last cart and (from 3 carts) one on the second, on the level. ns per
scheme, thread CPU time, in turns. The scalar loop is compiled as the kernel's entries are (numba's
Python error model: a check on each division), the lanes' loops with the numpy error model."""
from __future__ import annotations

import math
import statistics
import time

import numba
import numpy as np

from mta_sim_ros import jit
from mta_sim_ros.integrate import rk, rk_lanes
from mta_sim_ros.integrate.tableau import TABLEAUX
from mta_sim_ros.physics import kernel
from mta_sim_ros.physics.kernel import batched
from mta_sim_ros.physics.kernel.motion import model_rhs, rhs
from ..common import log, random_train, side_by_side, table

CARTS, WIDTHS = (2, 3, 5), (1, 8, 64, 256)
#: right-hand sides a timed call evaluates, whatever the width
EVALUATIONS = 4096


def batch(n: int, width: int, seed: int = 20261206) -> dict:
    """The arrays of ``width`` random schemes, scheme index innermost, and one scheme a row."""
    rng = np.random.default_rng(seed)
    P = kernel.stack([kernel.pack(random_train(n, rng)) for _ in range(width)])
    y = np.zeros((n + 5, width))
    y[0:2] = rng.normal(0.0, 10.0, (2, width))
    y[2:2 + n] = rng.uniform(-math.pi, math.pi, width) + np.cumsum(rng.uniform(-0.4, 0.4, (n, width)), axis=0)
    y[n + 2], y[n + 3], y[n + 4] = rng.uniform(-0.5, 0.5, width), rng.uniform(0.5, 4.0, width), rng.normal(0, 2e4, width)
    inputs = (rng.uniform(-0.7, 0.7, width), rng.uniform(1.0, 4.0, width), P[kernel.H.max_rate].copy())
    return {"lanes": (P, y, *inputs), "rows": (np.ascontiguousarray(P.T), np.ascontiguousarray(y.T), *inputs)}


@numba.njit
def one_scheme_a_call(P, y, commands, v_sets, max_rates, dy, times):
    """The kernel today: ``rhs`` on each scheme's own arrays (a row each), ``times`` over."""
    rec = np.empty((0, kernel.REC))
    mode = kernel.no_mode()
    for _ in range(times):
        for j in range(P.shape[0]):
            rhs(P[j], y[j], commands[j], v_sets[j], max_rates[j], dy[j], rec, mode)


def across_lanes(fn):
    @numba.njit(error_model="numpy")
    def run(P, y, commands, v_sets, max_rates, dy, times):
        rec = np.empty((0, kernel.REC, y.shape[1]))
        mode = np.empty((0, y.shape[1]), dtype=np.int64)
        work = np.empty((batched.WORK_ROWS, y.shape[1]))
        for _ in range(times):
            fn(P, y, commands, v_sets, max_rates, dy, rec, mode, work)
    return run


@numba.njit
def steps_one_scheme_a_call(P, T, y, commands, v_sets, max_rates, h, lag, out, times):
    """rk.rk_step on each scheme's own arrays (the actuator in closed form), ``times`` over."""
    size = y.shape[1]
    K, tmp, rec, mode = np.empty((T.shape[0] - 2, size)), np.empty(size), np.empty((0, kernel.REC)), kernel.no_mode()
    for _ in range(times):
        for j in range(P.shape[0]):
            rk.rk_step(model_rhs, P[j], T, 0.0, y[j], commands[j], v_sets[j], max_rates[j], h, K, tmp, out[j], rec,
                       mode, lag[j])


def steps_across(step):
    @numba.njit(error_model="numpy")
    def run(P, T, y, commands, v_sets, max_rates, h, lag, out, times):
        K, tmp, _, rec, work, acc = rk_lanes.arrays(T, y)
        mode = np.empty((0, y.shape[1]), dtype=np.int64)
        for _ in range(times):
            step(P, T, y, commands, v_sets, max_rates, h, K, tmp, out, rec, mode, lag, work, acc)
    return run


def step_figures(rounds: int) -> dict:
    """ns per scheme of one rk4 step (the actuator in closed form), per carts and width."""
    forms = {"rk_step, one scheme a call": steps_one_scheme_a_call, "rk_step_lanes": steps_across(rk_lanes.rk_step_lanes),
             "rk_step_lanes, libm": steps_across(rk_lanes.rk_step_lanes_libm)}
    T = TABLEAUX["rk4"].packed
    out: dict = {}
    for n in CARTS:
        for width in WIDTHS:
            arrays = batch(n, width)
            lag = np.zeros((5, width))
            lag[0], lag[1], lag[2], lag[3] = 1.0, arrays["lanes"][1][n + 2], arrays["lanes"][2], math.inf
            times = max(1, EVALUATIONS // (4 * width))
            given = {"rows": arrays["rows"] + (0.02, np.ascontiguousarray(lag.T)),
                     "lanes": arrays["lanes"] + (0.02, lag)}
            outs = {label: np.zeros_like(arrays["rows" if label.startswith("rk_step,") else "lanes"][1]) for label in forms}
            variants = {label: (lambda f, a, o: lambda: f(*a[:1], T, *a[1:], o, times))(
                fn, given["rows" if label.startswith("rk_step,") else "lanes"], outs[label]) for label, fn in forms.items()}
            for fn in variants.values():
                fn()
            taken = side_by_side(variants, rounds, clock=time.thread_time)
            out[f"{n} carts, {width} lane{'s' if width > 1 else ''}"] = {
                "ns": {k: 1e9 * statistics.median(v) / (times * width) for k, v in taken.items()},
                "libm_bit_identical": same_bits(outs["rk_step_lanes, libm"], outs["rk_step, one scheme a call"].T)}
    return out


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal to the bit (the sign of zero included), NaN where NaN."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    nan = np.isnan(b)
    return bool(a.shape == b.shape and np.array_equal(np.isnan(a), nan)
                and np.array_equal(a[~nan].view(np.int64), b[~nan].view(np.int64)))


def figures(rounds: int) -> dict:
    """ns per scheme of each form, per carts and width; the largest difference of vmath's y' from
    ``rhs``'s (relative to each row's largest value) and whether the libm form's is the same bits."""
    forms = {"rhs, one scheme a call": one_scheme_a_call, "rhs_lanes": across_lanes(batched.rhs_lanes),
             "rhs_lanes, libm": across_lanes(batched.rhs_lanes_libm)}
    out: dict = {}
    for n in CARTS:
        for width in WIDTHS:
            arrays = batch(n, width)
            times = max(1, EVALUATIONS // width)
            dys = {label: np.zeros_like(arrays["rows" if label.startswith("rhs,") else "lanes"][1]) for label in forms}
            variants = {label: (lambda f, a, d: lambda: f(*a, d, times))(
                fn, arrays["rows" if label.startswith("rhs,") else "lanes"], dys[label]) for label, fn in forms.items()}
            for fn in variants.values():
                fn()
            taken = side_by_side(variants, rounds, clock=time.thread_time)
            want = dys["rhs, one scheme a call"].T
            scale = np.abs(want).max(axis=1, keepdims=True) + 1e-300
            out[f"{n} carts, {width} lane{'s' if width > 1 else ''}"] = {
                "ns": {k: 1e9 * statistics.median(v) / (times * width) for k, v in taken.items()},
                "vmath_max_rel": float((np.abs(dys["rhs_lanes"] - want) / scale).max()),
                "libm_bit_identical": same_bits(dys["rhs_lanes, libm"], want)}
        log(f"rhs, {n} carts, {WIDTHS[-1]} lanes: " + ", ".join(
            f"{k} {v:.1f} ns" for k, v in out[f"{n} carts, {WIDTHS[-1]} lanes"]["ns"].items()))
    P, y, commands, v_sets, max_rates = batch(3, 16)["lanes"]
    out["compiled"] = jit.vector_evidence(batched.rhs_lanes_of, P, y, commands, v_sets, max_rates,
                                          np.empty((0, 16), dtype=np.int64), False)
    return out


def figs_packed(figs: dict) -> str:
    seen = figs["compiled"]
    return f"{seen['packed']}" + ("" if not seen["c_math_calls"] else f" (and C calls: {seen['c_math_calls']})")


def speed_cells(ns: dict, labels: list[str]) -> list[str]:
    """Each form's ns and, in brackets, its speed-up over the first label's."""
    return [f"{ns[k]:.1f} ({ns[labels[0]] / ns[k]:.2f}x)" for k in labels]


def yes_no(same: bool) -> str:
    return "yes" if same else "NO"


def report(figs: dict) -> list[str]:
    labels = ["rhs, one scheme a call", "rhs_lanes", "rhs_lanes, libm"]
    lines = ["## The train's right-hand side across lanes", "",
             "The kernel's whole y' (`physics/kernel/batched.py`: chain walk, inertia, drafts, governor, steering "
             "actuator) for batches of random trains with the governor, a draft on the last cart and (from 3 carts) one on the "
             "second, on the level: "
             "`motion.rhs` one scheme a call from a compiled loop (what a run's stepper calls today; numba's Python error "
             "model, as the kernel's entries), "
             "`rhs_lanes` with vmath (what a sweep's batch will call), and `rhs_lanes, libm`, the same source with "
             "the C library's math. ns per scheme, medians, thread CPU time, in turns; in brackets the speed-up "
             f"over `rhs`. {EVALUATIONS} right-hand sides a timed call. The compiled `rhs_lanes` holds "
             f"{figs_packed(figs)} packed instructions and no C math call (jit.vector_evidence).", ""]
    rows = [[key] + speed_cells(f["ns"], labels) + [f"{f['vmath_max_rel']:.1e}", yes_no(f["libm_bit_identical"])]
            for key, f in figs.items() if "ns" in f]
    lines += table(rows, ["batch"] + labels + ["vmath: largest difference / row scale", "libm: same bits"], "lr")
    return lines + [""]


def step_report(figs: dict) -> list[str]:
    labels = ["rk_step, one scheme a call", "rk_step_lanes", "rk_step_lanes, libm"]
    lines = ["## One rk4 step across lanes", "",
             "`rk.rk_step` one scheme a call (the steering angle from the actuator's closed form, as a run with kinks "
             "split steps it) against `integrate/rk_lanes.py`'s `rk_step_lanes` with vmath and with the C library "
             "bound; the same trains as above, every lane's actuator on its free lag (release = inf). ns per scheme and "
             "step (four right-hand sides), medians in turns.", ""]
    rows = [[key] + speed_cells(f["ns"], labels) + [yes_no(f["libm_bit_identical"])] for key, f in figs.items()]
    lines += table(rows, ["batch"] + labels + ["libm: same bits"], "lr")
    return lines + [""]
