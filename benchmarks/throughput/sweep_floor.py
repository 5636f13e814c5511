"""The plain-C floor of ``python -m benchmarks sweep-lanes`` (issue 24): run_floor.c, the arithmetic of
a run's rk4 steps (the kernel's right-hand side and rk_lanes' step, for the benchmark's trains),
built here by gcc where there is one, and the same steps in the kernel.

Four ways to step the headland run's 3500 ticks (0.02 s, one rk4 step a tick, the scene's held
inputs, the actuator in closed form; no kink splitting, switching functions, trace or guard):

- ``C alone``: run_floor.c at W = 1, gcc -O2 -ffp-contract=off: one scheme at a time, its runs'
  final states bit for bit the kernel's steps alone (``variants`` checks it on every run);
- ``C lanes``: W = 8, gcc -O3 -march=native -fno-math-errno -D__FAST_MATH__: eight schemes a
  vector register (AVX-512), the arithmetic IEEE and in the same order, sin, cos, atan2, tanh and
  exp from glibc's vector math library (libmvec, whose declarations glibc's math.h makes only
  under __FAST_MATH__, defined here by hand so that the rest stays IEEE);
- ``kernel steps alone``: rk.rk_step with motion.rhs, one scheme at a time, as a run's ticks call it;
- ``kernel steps lanes``: rk_lanes.rk_step_lanes (vmath) across the batch.

So the sweep-lanes report can say how far a sweep's run is from the floor, and which part of the
distance is the step itself and which the run around it.
"""
from __future__ import annotations

import ctypes
import math
import shutil
import subprocess
from pathlib import Path

import numba
import numpy as np

from mta_sim_ros.integrate import rk, rk_lanes
from mta_sim_ros.integrate.tableau import TABLEAUX
from mta_sim_ros.physics import kernel
from mta_sim_ros.physics.kernel import C, D, H
from mta_sim_ros.physics.kernel.laws import actuator_release
from mta_sim_ros.physics.kernel.motion import model_rhs

from ..common import table

SOURCE = Path(__file__).with_name("run_floor.c")
#: the C floor's lanes a vector (its W); a batch is whole blocks of it
VECTOR = 8
HEAD_FIELDS = ("time_constant", "max_rate", "max_angle", "max_force", "max_power", "kp", "ki", "windup_time",
               "smoothing_speed")
CART_FIELDS = ("length", "lam", "lam2", "mu2", "mass", "inertia", "rolling")
DRAFT_FIELDS = ("soil_factor", "A", "B", "C", "width", "depth")
#: run_floor.c's MAXN: its stage arrays hold so many carts
MAX_CARTS = 8
#: W: gcc's flags (module docstring)
BUILDS = {1: ["-O2", "-ffp-contract=off"], VECTOR: ["-O3", "-march=native", "-fno-math-errno", "-D__FAST_MATH__"]}


def build(folder: Path) -> tuple[dict, str]:
    """{W: the library's ``run`` and ``step``} for W = 1 and VECTOR, and how they were built; ({}, why)
    where there is no gcc or it fails."""
    gcc = shutil.which("gcc")
    if not gcc:
        return {}, "left out: no gcc"
    built = {}
    for width, flags in BUILDS.items():
        lib = folder / f"run_floor_{width}.so"
        try:
            subprocess.run([gcc, *flags, f"-DW={width}", "-shared", "-fPIC", str(SOURCE), "-o", str(lib), "-lm"],
                           check=True, capture_output=True, text=True)
            built[width] = ctypes.CDLL(str(lib))
        except (subprocess.SubprocessError, OSError) as err:
            detail = getattr(err, "stderr", "") or str(err)
            return {}, f"left out: gcc could not build or load run_floor.c ({detail.strip().splitlines()[-1]})"
    for lib in built.values():
        pointer = np.ctypeslib.ndpointer(np.float64, flags="C_CONTIGUOUS")
        ints = np.ctypeslib.ndpointer(np.int32, flags="C_CONTIGUOUS")
        lib.run.argtypes = [ctypes.c_int, ints, pointer, pointer, pointer, pointer, pointer, ctypes.c_double,
                            ctypes.c_long, ctypes.c_long]
        lib.step.argtypes = [ctypes.c_int, ints, pointer, pointer, pointer, pointer, pointer, pointer,
                             ctypes.c_double, ctypes.c_long]
        lib.run.restype = lib.step.restype = None
    how = "; ".join(f"W = {w}: `gcc {' '.join(f)} -DW={w} run_floor.c -lm`" for w, f in BUILDS.items())
    calls = vector_calls(folder / f"run_floor_{VECTOR}.so")
    return built, how + f"; the W = {VECTOR} build calls {', '.join(calls) if calls else 'NO vector math function'}"


def vector_calls(lib: Path) -> list[str]:
    """The vector math functions (glibc's _ZGV* entries) a built library calls, by nm."""
    import re

    listed = subprocess.run(["nm", "-D", str(lib)], capture_output=True, text=True).stdout
    return sorted(set(re.findall(r"_ZGV\w+", listed)))


def constants(P: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(drafts[n], head[block][NH][W], cart[block][n][NC][W]) of the stacked P (fields x lanes) in the
    C floor's layout; a cart has at most one draft (the benchmark's trains)."""
    n, lanes = int(P[H.n, 0]), P.shape[1]
    drafts = np.array([int(P[kernel.HEAD_SIZE + kernel.CART_SIZE * k + C.draft_count, 0]) for k in range(n)],
                      dtype=np.int32)
    if drafts.max() > 1:
        raise ValueError("run_floor.c takes at most one draft a cart")
    if n > MAX_CARTS:
        raise ValueError(f"run_floor.c takes at most {MAX_CARTS} carts (its MAXN)")
    head = np.stack([P[getattr(H, f)] for f in HEAD_FIELDS])
    cart = np.zeros((n, len(CART_FIELDS) + len(DRAFT_FIELDS), lanes))
    for k in range(n):
        b = kernel.HEAD_SIZE + kernel.CART_SIZE * k
        cart[k, :len(CART_FIELDS)] = np.stack([P[b + getattr(C, f)] for f in CART_FIELDS])
        if drafts[k]:
            d = kernel.HEAD_SIZE + kernel.CART_SIZE * n + kernel.DRAFT_SIZE * P[b + C.draft_first].astype(int)
            cart[k, len(CART_FIELDS):] = np.stack([P[d + getattr(D, f), np.arange(lanes)] for f in DRAFT_FIELDS])
    return drafts, blocks(head, width), blocks(cart, width)


def blocks(a: np.ndarray, width: int) -> np.ndarray:
    """A copy of a (..., lanes) as contiguous blocks of ``width`` lanes: (lanes / width, ..., width)
    (a copy always: the C floor steps its arrays in place)."""
    lanes = a.shape[-1]
    split = a.reshape(a.shape[:-1] + (lanes // width, width))
    return np.array(np.moveaxis(split, -2, 0), order="C", copy=True)


def unblock(a: np.ndarray) -> np.ndarray:
    """``blocks`` undone: (..., lanes)."""
    return np.moveaxis(a, 0, -2).reshape(a.shape[1:-1] + (a.shape[0] * a.shape[-1],))


def c_step(lib, width: int, P, y, commands, v_sets, release, h) -> np.ndarray:
    """One rk4 step of every lane of the batch by the C floor: the stepped states (size, lanes)."""
    drafts, head, cart = constants(P, width)
    out = blocks(y, width)
    lib.step(int(P[H.n, 0]), drafts, head, cart, out, blocks(commands[None], width), blocks(v_sets[None], width),
             blocks(release[None], width), h, y.shape[1])
    return unblock(out)


def c_runner(lib, width: int, P, y0, commands, v_sets, h):
    """A call that runs every lane's ticks from y0 by the C floor (inputs (ticks, lanes)), and its
    final states' array (size, lanes, blocked)."""
    drafts, head, cart = constants(P, width)
    cmd, vs = blocks(commands, width), blocks(v_sets, width)
    start = blocks(y0, width)
    y = start.copy()
    n, ticks, lanes = int(P[H.n, 0]), commands.shape[0], y0.shape[1]

    def go():
        y[...] = start
        lib.run(n, drafts, head, cart, y, cmd, vs, h, ticks, lanes)
    return go, y


@numba.njit
def kernel_steps_alone(P_rows, T, y0, commands, v_sets, h):
    """rk.rk_step of each scheme over the ticks (the actuator's closed form from each tick's start):
    the final states, a row each."""
    lanes, size = y0.shape[0], y0.shape[1]
    n = int(P_rows[0, H.n])
    K, tmp, out = np.empty((T.shape[0] - 2, size)), np.empty(size), np.empty((lanes, size))
    rec, mode, lag = np.empty((0, kernel.REC)), kernel.no_mode(), np.zeros(5)
    for j in range(lanes):
        y = y0[j].copy()
        for i in range(commands.shape[0]):
            P = P_rows[j]
            lag[0], lag[1], lag[2] = 1.0, y[n + 2], commands[i, j]
            lag[3] = actuator_release(P, y[n + 2], commands[i, j], P[H.max_rate])
            rk.rk_step(model_rhs, P, T, 0.0, y, commands[i, j], v_sets[i, j], P[H.max_rate], h, K, tmp, out[j], rec,
                       mode, lag)
            y[:] = out[j]
    return out


@numba.njit(error_model="numpy")
def kernel_steps_lanes(P, P_rows, T, y0, commands, v_sets, h):
    """rk_lanes.rk_step_lanes (vmath) of the batch over the ticks: the final states (size, lanes)."""
    size, lanes = y0.shape[0], y0.shape[1]
    n = int(P_rows[0, H.n])
    K, tmp, out, rec, work, acc = rk_lanes.arrays(T, y0)
    mode, lag, y = np.empty((0, lanes), dtype=np.int64), np.zeros((5, lanes)), y0.copy()
    max_rates = P[H.max_rate].copy()
    for i in range(commands.shape[0]):
        for j in range(lanes):
            lag[0, j], lag[1, j], lag[2, j] = 1.0, y[n + 2, j], commands[i, j]
            lag[3, j] = actuator_release(P_rows[j], y[n + 2, j], commands[i, j], max_rates[j])
        rk_lanes.rk_step_lanes(P, T, y, commands[i], v_sets[i], max_rates, h, K, tmp, out, rec, mode, lag, work, acc)
        for m in range(size):
            for j in range(lanes):
                y[m, j] = out[m, j]
    return y


def check(built: dict, P, y, commands, v_sets, h) -> dict:
    """How the C floor's steps compare with the kernel's on one batch: W = 1 against
    rk_step_lanes_libm (whether bit for bit), W = VECTOR against it (``largest_difference``), lanes on their free lag and, every third, on their rate limit."""
    n, lanes = int(P[H.n, 0]), y.shape[1]
    release = np.full(lanes, math.inf)
    release[::3] = np.linspace(0.001, 0.03, release[::3].size)
    lag = np.vstack([np.ones(lanes), y[n + 2], commands, release, np.zeros(lanes)])
    max_rates = np.ascontiguousarray(P[H.max_rate])
    want = rk_lanes.step_lanes_libm_of(P, TABLEAUX["rk4"].packed, y, commands, v_sets, max_rates, h,
                                       np.empty((0, lanes), dtype=np.int64), lag)
    one = c_step(built[1], 1, P, y, commands, v_sets, release, h)
    wide = c_step(built[VECTOR], VECTOR, P, y, commands, v_sets, release, h)
    return {"one_bit_identical": bool(np.array_equal(one.view(np.int64), want.view(np.int64))),
            "lanes_max_rel": largest_difference(wide, want)}


def largest_difference(got: np.ndarray, want: np.ndarray) -> float:
    """The largest |got - want| of states (size, lanes), each row's relative to its largest |value|
    and at least 1 (metres, radians, m/s, newtons: a steering angle that ends near 0 rad is not
    compared to its own round-off)."""
    scale = np.maximum(np.abs(want).max(axis=1, keepdims=True), 1.0)
    return float((np.abs(got - want) / scale).max())


def inputs(scenes: list) -> tuple:
    """(P stacked, P's rows, y0 (size, lanes), commands and v_sets (ticks, lanes), tick) of the scenes'
    runs at one rk4 step a tick of 0.02 s, dynamic level."""
    from mta_sim_ros.run.batch import scheduled_inputs
    from mta_sim_ros.run.simulation import Simulation

    sims = [Simulation(s, fidelity="dynamic", step=0.02) for s in scenes]
    P = kernel.stack([sim.model.P for sim in sims])
    y0 = np.ascontiguousarray(np.stack([sim.y for sim in sims], axis=1), dtype=np.float64)
    held = [scheduled_inputs(s, sim) for s, sim in zip(scenes, sims)]
    commands = np.ascontiguousarray(np.stack([c for c, _ in held], axis=1))
    v_sets = np.ascontiguousarray(np.stack([v for _, v in held], axis=1))
    return P, np.ascontiguousarray(P.T), y0, commands, v_sets, sims[0].tick


def variants(built: dict, scenes: list, alone: int, widths) -> tuple[dict, dict]:
    """({label: (call, runs it makes)}, checks) for the four ways to step the scenes' runs (module
    docstring): one scheme at a time on the first ``alone`` scenes, across lanes on the first w of
    each width w; checks: whether the C floor's runs end bit for bit where the kernel's steps
    alone end, and the largest difference of its 8-lane runs from the kernel's lanes
    (``largest_difference``)."""
    T = TABLEAUX["rk4"].packed
    P, P_rows, y0, commands, v_sets, h = inputs(scenes)
    out = {}
    few = slice(0, alone)
    rows_few = np.ascontiguousarray(P_rows[few])
    y_rows = np.ascontiguousarray(y0[:, few].T)
    out["kernel steps alone"] = (lambda: kernel_steps_alone(rows_few, T, y_rows, commands[:, few], v_sets[:, few], h),
                                 alone)
    checks = {}
    if built:
        go, y_one = c_runner(built[1], 1, P[:, few], y0[:, few], commands[:, few], v_sets[:, few], h)
        out["C alone"] = (go, alone)
        go()
        checks["C alone equals the kernel's steps to the bit"] = bool(np.array_equal(
            unblock(y_one).view(np.int64), kernel_steps_alone(rows_few, T, y_rows, commands[:, few], v_sets[:, few],
                                                              h).T.view(np.int64)))
    for w in widths:
        part = slice(0, w)
        Pw, rows_w, yw = np.ascontiguousarray(P[:, part]), np.ascontiguousarray(P_rows[part]), \
            np.ascontiguousarray(y0[:, part])
        cw, vw = np.ascontiguousarray(commands[:, part]), np.ascontiguousarray(v_sets[:, part])
        out[f"kernel steps lanes {w}"] = ((lambda a: lambda: kernel_steps_lanes(*a))((Pw, rows_w, T, yw, cw, vw, h)), w)
        if built:
            go, y_wide = c_runner(built[VECTOR], VECTOR, Pw, yw, cw, vw, h)
            out[f"C lanes {w}"] = (go, w)
            if w == max(widths):
                go()
                want = kernel_steps_lanes(Pw, rows_w, T, yw, cw, vw, h)
                checks["C lanes against the kernel's lanes, largest difference / row scale"] = largest_difference(
                    unblock(y_wide), want)
    return out, checks


def report(figures: dict, carts, widths) -> list[str]:
    """The sweep-lanes report's section on the floor: ms per run of the steps alone, in the kernel and
    in C, and what they say about a sweep's run."""
    if not figures.get("floor_built", "").startswith("W ="):
        return ["## The plain-C floor", "", f"The C floor was {figures.get('floor_built', 'not built')}.", ""]
    rows = []
    for n in carts:
        ms = figures[n]["ms"]
        rows.append([n, "C", f"{ms['C alone']:.2f}", *(f"{ms[f'C lanes {w}']:.2f}" for w in widths)])
        rows.append([n, "kernel", f"{ms['kernel steps alone']:.2f}", *(
            f"{ms[f'kernel steps lanes {w}']:.2f} ({ms[f'kernel steps lanes {w}'] / ms[f'C lanes {w}']:.1f}x C)"
            for w in widths)])
        rows.append([n, "kernel's run", f"{ms['kernel alone']:.2f}", *(f"{ms[f'kernel lanes {w}']:.2f}" for w in widths)])
    lines = ["## The plain-C floor", "",
             "The headland run's 3500 rk4 steps (0.02 s, the scene's held inputs, the actuator in closed form) and "
             "nothing else: no kink splitting, switching functions, trace rows or guard. `C`: "
             "benchmarks/throughput/run_floor.c, the kernel's arithmetic for these trains (the governor, at most one "
             f"draft a cart, the level), built here ({figures['floor_built']}); alone one scheme at a time, across "
             "lanes eight schemes a vector with glibc's vector math. `kernel`: `rk.rk_step` one scheme at a time and "
             "`rk_lanes.rk_step_lanes` (vmath) across the batch, in a compiled loop. `kernel's run`: the "
             "kernel's part of a sweep's run from the first table (the same run at 0.02 s with its trace, switching "
             "functions and kinks), for comparison. ms per run, in turns with the first table's variants.", ""]
    lines += table(rows, ["carts", "steps of", "alone", *(f"{w} lanes" for w in widths)], "rl" + "r" * (1 + len(widths)))
    checks = [(n, figures[n]["floor_checks"]) for n in carts]
    same = all(c.get("C alone equals the kernel's steps to the bit") for _, c in checks)
    worst = max(c.get("C lanes against the kernel's lanes, largest difference / row scale", math.nan)
                for _, c in checks)
    best = {n: min(figures[n]["ms"][f"C lanes {w}"] for w in widths) for n in carts}
    lines += ["", f"Checked on these runs: C alone ends every run {'bit for bit' if same else 'NOT bit for bit'} "
              "where the kernel's steps alone end it (the same operations in the same order, the C library's "
              f"functions); C across lanes within {worst:.1e} of the kernel's lanes after 70 s (each state row's "
              "largest value, at least 1, the scale).", "",
              "A sweep's run steps its scene three times over (the run, and its companion at half the step, which "
              "states its accuracy), so even at the C floor's steps across lanes it costs at least " +
              ", ".join(f"{3 * best[n]:.1f} ms ({1e3 / (3 * best[n]):.0f} runs/s/core) at {n} carts" for n in carts) +
              ", before its metrics.", ""]
    return lines
