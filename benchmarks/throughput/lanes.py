"""``python -m benchmarks lanes``: the lanes' math (mta_sim_ros/physics/kernel/vmath.py) against the
C library, numpy and gcc's vector math, in nanoseconds per value, with each one's accuracy and the
instructions its loop compiled to.

For each function (sin and cos together, atan2, exp, tanh), on ``--values`` random arguments in
the range the kernel meets, side by side in one process (the contenders take turns every round;
medians of ``--rounds``; thread CPU time):

- ``numba + libm``: a compiled loop calling ``math.*``, as the kernel does today: one call into the
  C library per value, which LLVM cannot vectorise (PyPI's llvmlite has no SVML; docs/lanes.md)
- ``vmath lanes``: the same loop over vmath's own polynomials (``vmath.*_lanes``), which LLVM
  vectorises
- ``numpy``: the ufunc (numpy's own SIMD loops where it has them)
- ``gcc + libmvec``: lanes_floor.c, the same loop in C, built here by gcc -O3 -ffast-math
  -march=native, which calls glibc's vector math library; the floor a C compiler reaches. Left out,
  and said, where there is no gcc or no libmvec.

Accuracy: the largest error of each in units in the last place of the C library's value (``math``),
over the same arguments. Instructions: packed double-precision arithmetic in the assembly of the
numba loops (jit.assembly) and the C library calls left in their LLVM IR; the vector entries the
C floor calls (nm).

Then the shapes of a loop over a batch of schemes (lanes_shapes.py): one walk of the kinematic
chain for 2, 3 and 5 carts and 1 to 256 lanes, one scheme a call (today's kernel) against the two
ways of putting the schemes across the lanes; which of them LLVM vectorises, and at what speed;
and at one lane, called from compiled code (the node's tick as a batch of one), the vectorisable
shape with vmath and with the C library bound, against the scalar walk.

Last, the train's whole right-hand side across lanes (lanes_rhs.py): the kernel's ``motion.rhs``
one scheme a call against ``batched.rhs_lanes`` at 1 to 256 lanes, with vmath and with the C
library bound (the latter's y' bit for bit ``rhs``'s); and one rk4 step, ``rk.rk_step`` against
``rk_lanes.rk_step_lanes``.
Writes docs/benchmarks/lanes.md (and .json).
"""
from __future__ import annotations

import ctypes
import ctypes.util
import json
import math
import re
import shutil
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from mta_sim_ros.validate import COUNT, Range, number_arg, output_file, path_arg

from ..common import header_lines, log, side_by_side, table, write_report

HELP = "the lanes' math (vmath) against libm, numpy and gcc's libmvec: ns per value, accuracy, instructions"
FLOOR = Path(__file__).with_name("lanes_floor.c")
FUNCTIONS = ("sincos", "atan2", "exp", "tanh")
CARTS, WIDTHS = (2, 3, 5), (1, 8, 64, 256)
ONE_LANE_CALLS = 20_000  # calls from compiled code, one lane each, a figure


def add_arguments(p) -> None:
    p.add_argument("--values", type=number_arg(Range.of(64, 10_000_000), int), default=4096,
                   help="arguments per call, one per lane (default 4096)")
    p.add_argument("--rounds", type=number_arg(COUNT, int), default=21, help="rounds (default 21)")
    p.add_argument("--out", type=path_arg(output_file), default="docs/benchmarks/lanes.md", help="Markdown report")


def arguments(n: int) -> dict[str, tuple]:
    """Each function's arguments: the ranges a train's angles, ratios and laws meet."""
    rng = np.random.default_rng(20261205)
    return {"sincos": (rng.uniform(-10.0, 10.0, n),), "atan2": (rng.standard_normal(n), rng.standard_normal(n)),
            "exp": (rng.uniform(-30.0, 30.0, n),), "tanh": (rng.uniform(-5.0, 5.0, n),)}


def numba_libm():
    """The loops of vmath.*_lanes with ``math.*`` in their bodies (the C library, a call a value)."""
    import numba

    @numba.njit(error_model="numpy")
    def sincos(x, s, c):
        for j in range(x.shape[0]):
            s[j], c[j] = math.sin(x[j]), math.cos(x[j])

    @numba.njit(error_model="numpy")
    def atan2(y, x, out):
        for j in range(x.shape[0]):
            out[j] = math.atan2(y[j], x[j])

    @numba.njit(error_model="numpy")
    def exp(x, out):
        for j in range(x.shape[0]):
            out[j] = math.exp(x[j])

    @numba.njit(error_model="numpy")
    def tanh(x, out):
        for j in range(x.shape[0]):
            out[j] = math.tanh(x[j])

    return {"sincos": sincos, "atan2": atan2, "exp": exp, "tanh": tanh}


def numpy_ufuncs():
    def sincos(x, s, c):
        np.sin(x, out=s)
        np.cos(x, out=c)

    return {"sincos": sincos, "atan2": lambda y, x, out: np.arctan2(y, x, out=out),
            "exp": lambda x, out: np.exp(x, out=out), "tanh": lambda x, out: np.tanh(x, out=out)}


def gcc_floor(folder: Path) -> tuple[dict, list[str], str]:
    """lanes_floor.c built and loaded: (function -> callable, the _ZGV entries it calls, why not)."""
    gcc, libmvec = shutil.which("gcc"), ctypes.util.find_library("mvec")
    if not gcc or not libmvec:
        return {}, [], f"left out: {'no gcc' if not gcc else 'no libmvec (glibc >= 2.22 on x86-64)'}"
    lib = folder / "lanes_floor.so"
    flags = ["-O3", "-ffast-math", "-march=native", "-fPIC", "-shared"]
    try:
        subprocess.run([gcc, *flags, str(FLOOR), "-o", str(lib), "-lmvec", "-lm"], check=True,
                       capture_output=True, text=True, timeout=120)
        c = ctypes.CDLL(str(lib))
    except (subprocess.SubprocessError, OSError) as err:
        detail = getattr(err, "stderr", None) or str(err)
        return {}, [], f"left out: gcc could not build or load lanes_floor.c ({detail.strip().splitlines()[-1]})"
    entries = sorted({m for m in re.findall(r"_ZGV\w+", subprocess.run(
        ["nm", "-D", str(lib)], capture_output=True, text=True).stdout)}) if shutil.which("nm") else []
    pointer = np.ctypeslib.ndpointer(np.float64, flags="C_CONTIGUOUS")
    floor = {}
    for name in FUNCTIONS:
        fn = getattr(c, f"{name}_lanes")
        fn.argtypes, fn.restype = [pointer] * (2 if name in ("exp", "tanh") else 3) + [ctypes.c_long], None
        floor[name] = (lambda f: lambda *a: f(*a, a[0].shape[0]))(fn)
    return floor, entries, f"`gcc {' '.join(flags)} lanes_floor.c -lmvec -lm`"


def outputs(name: str, n: int) -> tuple:
    return (np.empty(n), np.empty(n)) if name == "sincos" else (np.empty(n),)


def reference(name: str, args: tuple) -> list[np.ndarray]:
    """The C library's values (``math``), one call a value."""
    if name == "sincos":
        return [np.array([math.sin(v) for v in args[0]]), np.array([math.cos(v) for v in args[0]])]
    fn = {"atan2": math.atan2, "exp": math.exp, "tanh": math.tanh}[name]
    return [np.array([fn(*v) for v in zip(*args)])]


def max_ulp(fn, name: str, args: tuple, want: list[np.ndarray]) -> float:
    out = outputs(name, args[0].shape[0])
    fn(*args, *out)
    return max(float((np.abs(g - w) / np.spacing(np.maximum(np.abs(w), np.finfo(float).tiny))).max())
               for g, w in zip(out, want))


def instructions(name: str, fn, args: tuple) -> tuple[int, bool]:
    """(packed double-precision instructions in fn's assembly, a C library call left in its IR)."""
    from mta_sim_ros import jit

    seen = jit.vector_evidence(fn, *args, *outputs(name, args[0].shape[0]))
    return seen["packed"], bool(seen["c_math_calls"])


def main(args) -> int:
    from mta_sim_ros import jit
    from mta_sim_ros.physics.kernel import vmath

    if not jit.ENABLED:
        raise SystemExit(f"python -m benchmarks lanes: needs numba ({jit.NOTE})")
    n = args.values
    inputs = arguments(n)
    with tempfile.TemporaryDirectory(prefix="mta_lanes_") as tmp:
        floor, entries, built = gcc_floor(Path(tmp))
        contenders = {"numba + libm": numba_libm(), "vmath lanes": {f: getattr(vmath, f"{f}_lanes") for f in FUNCTIONS},
                      "numpy": numpy_ufuncs()}
        if floor:
            contenders["gcc + libmvec"] = floor
        figures: dict = {"values": n, "rounds": args.rounds, "ns_per_value": {}, "max_ulp": {}, "instructions": {},
                         "c_floor": {"built": built, "vector_entries": entries}}
        for name in FUNCTIONS:
            out = outputs(name, n)
            variants = {label: (lambda f, a: lambda: f(*a, *out))(fns[name], inputs[name])
                        for label, fns in contenders.items()}
            for fn in variants.values():
                fn()  # compile
            times = side_by_side(variants, args.rounds, calls=20, clock=time.thread_time)
            figures["ns_per_value"][name] = {k: 1e9 * statistics.median(v) / n for k, v in times.items()}
            want = reference(name, inputs[name])
            figures["max_ulp"][name] = {k: max_ulp(fns[name], name, inputs[name], want)
                                        for k, fns in contenders.items()}
            figures["instructions"][name] = {k: instructions(name, contenders[k][name], inputs[name])
                                             for k in ("numba + libm", "vmath lanes")}
            log(f"{name}: " + ", ".join(f"{k} {v:.2f} ns" for k, v in figures["ns_per_value"][name].items()))
    from . import lanes_rhs  # imports numba: here, not when python -m benchmarks lists the benchmarks

    figures["shapes"] = loop_shapes(args.rounds)
    figures["rhs"] = lanes_rhs.figures(args.rounds)
    figures["step"] = lanes_rhs.step_figures(args.rounds)
    write_report(args.out, report(args, figures) + shapes_report(figures["shapes"]) + lanes_rhs.report(figures["rhs"])
                 + lanes_rhs.step_report(figures["step"]))
    Path(args.out).with_suffix(".json").write_text(json.dumps(figures, indent=1) + "\n")
    return 0


def report(args, figures: dict) -> list[str]:
    labels = list(figures["ns_per_value"]["sincos"])
    lines = header_lines("The lanes' math: vmath against libm, numpy and gcc's libmvec", args)
    lines += ["## Nanoseconds per value", "",
              f"Medians of {figures['rounds']} rounds, {figures['values']} values a call, thread CPU time; the "
              "contenders take turns every round. In brackets: how many times faster than numba + libm "
              "(what the kernel's loops pay today).", ""]
    rows = []
    for name, ns in figures["ns_per_value"].items():
        base = ns["numba + libm"]
        rows.append([name] + [f"{ns[k]:.2f} ({base / ns[k]:.1f}x)" for k in labels])
    lines += table(rows, ["function"] + labels, "lr") + [""]
    lines += ["## Largest error, ulp of the C library's value", ""]
    lines += table([[name] + [f"{u[k]:.2f}" for k in labels] for name, u in figures["max_ulp"].items()],
                   ["function"] + labels, "lr") + [""]
    lines += ["## What the loops compiled to", "",
              "Packed double-precision instructions in the loop's assembly, and whether a call to the C "
              "library is left in its LLVM IR (a call a value: no lanes).", ""]
    lines += table([[name, *(f"{p} packed, {'calls the C library' if c else 'no call'}" for p, c in ins.values())]
                    for name, ins in figures["instructions"].items()],
                   ["function", "numba + libm", "vmath lanes"], "l") + [""]
    floor = figures["c_floor"]
    lines += [f"The C floor: {floor['built']}; the vector entries it calls: "
              + (", ".join(f"`{e}`" for e in floor["vector_entries"]) or "none found") + ".", ""]
    return lines


def loop_shapes(rounds: int) -> dict:
    """ns per scheme of one walk of the chain in each shape (lanes_shapes.py), per carts and width;
    the packed instructions of each; the largest difference from the scalar shape's dy."""
    from mta_sim_ros import jit

    from . import lanes_shapes

    out: dict = {}
    for n in CARTS:
        contenders = lanes_shapes.shapes(n)
        for width in WIDTHS:
            soa = lanes_shapes.batch(n, width)
            args = {label: lanes_shapes.rows(soa) if by_rows else soa for label, (_, by_rows) in contenders.items()}
            variants = {label: (lambda f, a: lambda: f(*a))(fn, args[label]) for label, (fn, _) in contenders.items()}
            for fn in variants.values():
                fn()
            times = side_by_side(variants, rounds, calls=max(1, 4096 // width), clock=time.thread_time)
            scalar_dy = args["scalar"][2].T
            out[f"{n} carts, {width} lane{'s' if width > 1 else ''}"] = {
                "ns": {k: 1e9 * statistics.median(v) / width for k, v in times.items()},
                "max_diff": {k: float(np.abs(args[k][2] - scalar_dy).max()) for k in ("lanes out", "lanes in")}}
        out[f"{n} carts, packed"] = {label: jit.vector_evidence(fn, *args[label])["packed"]
                                     for label, (fn, _) in contenders.items()}
        one = lanes_shapes.batch(n, 1)
        forms = {"scalar": (lanes_shapes.scalar, lanes_shapes.rows(one)), "lanes in": (lanes_shapes.lanes_in, one),
                 "lanes in, libm": (lanes_shapes.lanes_in_libm, one)}
        repeats = {k: (lambda r, a: lambda: r(*a, ONE_LANE_CALLS))(lanes_shapes.repeated(fn), a)
                   for k, (fn, a) in forms.items()}
        for fn in repeats.values():
            fn()
        times = side_by_side(repeats, rounds, clock=time.thread_time)
        out[f"{n} carts, one lane in compiled code"] = {k: 1e9 * statistics.median(v) / ONE_LANE_CALLS
                                                        for k, v in times.items()}
        by_rows, by_lanes = lanes_shapes.rows(lanes_shapes.batch(n, WIDTHS[-1])), lanes_shapes.batch(n, WIDTHS[-1])
        lanes_shapes.scalar(*by_rows)
        lanes_shapes.lanes_in_libm(*by_lanes)
        out[f"{n} carts, one lane in compiled code"]["libm bit-identical"] = bool(
            np.array_equal(by_rows[2].T, by_lanes[2]))  # on every scheme of the widest batch
        widest = out[f"{n} carts, {WIDTHS[-1]} lanes"]["ns"]
        log(f"shapes, {n} carts, {WIDTHS[-1]} lanes: " + ", ".join(f"{k} {v:.1f} ns" for k, v in widest.items()))
    return out


def shapes_report(shapes: dict) -> list[str]:
    lines = ["## Shapes of a loop over schemes", "",
             "One walk of the kinematic chain (sin, cos, atan2, sqrt a cart; `benchmarks/throughput/lanes_shapes.py`) "
             "for a batch of random trains, in three shapes: `scalar`, one scheme a call with `math.*` (the kernel "
             "today); `lanes out`, that body in a loop over lanes with vmath, the number of carts frozen at compile "
             "time; `lanes in`, the carts' loop outside and a loop over lanes inside each of its steps. "
             "ns per scheme, medians, thread CPU time, in turns; in brackets the speed-up over `scalar`. At 1 lane "
             "the call from Python (about half a microsecond) is most of each figure.", ""]
    labels = ["scalar", "lanes out", "lanes in"]
    rows = []
    for key, fig in shapes.items():
        if "ns" in fig:
            ns = fig["ns"]
            rows.append([key] + [f"{ns[k]:.1f} ({ns['scalar'] / ns[k]:.2f}x)" for k in labels]
                        + [f"{max(fig['max_diff'].values()):.1e}"])
    lines += table(rows, ["batch"] + labels + ["largest difference in dy"], "lr") + [""]
    packed = [[key.split(",")[0]] + [str(fig[k]) for k in labels]
              for key, fig in shapes.items() if key.endswith("packed")]
    lines += table(packed, ["packed instructions"] + labels, "lr") + [""]
    lines += ["One lane, the walk called from compiled code (no Python call in the figure): the node's tick as a "
              "batch of one; `lanes in, libm` is the same source with `math.*` bound in place of vmath's. "
              "ns a call, medians; in brackets x scalar.", ""]
    forms = ("scalar", "lanes in", "lanes in, libm")
    one = [[key.split(",")[0]] + [f"{f[k]:.1f} ({f[k] / f['scalar']:.2f}x)" for k in forms]
           for key, f in shapes.items() if key.endswith("compiled code")]
    lines += table(one, ["train", *forms], "lr") + [""]
    same = all(f["libm bit-identical"] for key, f in shapes.items() if key.endswith("compiled code"))
    lines += [f"`lanes in, libm` gives dy {'bit for bit equal to' if same else 'NOT equal to'} the scalar "
              f"shape's, on each of {WIDTHS[-1]} random trains of each length.", ""]
    return lines
