"""numba where it can run, the same functions as plain Python where it cannot. No physics here.

The kernels (``physics/kernel/``, ``integrate/rk.py``, ``run/whole.py``, ``run/offsets.py``,
``controllers/implement/loop.py``) are written once, in the subset of Python that numba compiles.
Four decorators give them their two lives:

``jitable``  a function the kernels call from each other: plain Python when called from Python,
             compiled into its caller when called from compiled code (numba's register_jitable).
``inlined``  a ``jitable`` inlined into its caller by numba itself (its IR, before LLVM's own
             inliner decides): for the lanes' math (``physics/kernel/vmath.py``), which a loop over
             lanes vectorises only when no call is left in its body
``entry``    a function Python calls: compiled and cached on disk (numba's njit(cache=True)); its
             ``py_func`` is the same source run as plain Python, calling the plain-Python
             ``jitable`` functions. So ``entry.py_func`` is a whole Python path, not a mix.
``lanes``    an ``entry`` whose loop runs over a batch of schemes, one per SIMD lane, compiled with
             numba's numpy error model: a division by zero gives inf or NaN, as in C, instead of
             raising ZeroDivisionError, whose check would put a branch in every lane and keep
             LLVM from vectorising the loop.

Without numba, or with the environment variable ``MTA_SIM_NO_JIT=1`` set when the package is
imported, the decorators leave the function as it is (``entry`` and ``lanes`` add ``py_func``,
itself).
``ENABLED`` and ``NOTE`` say which holds.

The compile unit. numba checks a cached function against the source file it is defined in, not
against the files of the functions it calls (numba issue 8396): compiled code calling into another
file would run stale after that file changed. So every file of compiled code is listed in ``UNIT``
and the cache of every entry point is named after ``unit_digest()``, the digest of all of them: a
change in any compiled file compiles every entry point anew. test_rooms.py holds ``UNIT`` to the
files that use the decorators, and checks that compiled code reads names only from files of the
unit (a constant read from another file would be frozen into the cache unseen).
"""
from __future__ import annotations

import functools
import hashlib
import os
import re
from importlib import resources

NO_JIT_ENV = "MTA_SIM_NO_JIT"

#: every file whose functions numba compiles, relative to the package (and this file: the
#: decorators' options are part of what is compiled)
UNIT = (
    "jit.py",
    "physics/kernel/base.py",
    "physics/kernel/laws.py",
    "physics/kernel/relief.py",
    "physics/kernel/vmath.py",
    "physics/kernel/walk.py",
    "physics/kernel/batched.py",
    "physics/kernel/motion.py",
    "physics/kernel/entries.py",
    "physics/kernel/inverse.py",
    "integrate/rk.py",
    "integrate/rk_lanes.py",
    "run/whole.py",
    "run/trace_lanes.py",
    "run/whole_lanes.py",
    "run/offsets.py",
    "controllers/implement/loop.py",
)


@functools.cache
def unit_digest() -> str:
    """The first 12 hex digits of sha256 over the files of UNIT (names and contents); 'nosource'
    where the sources cannot be read (then numba's own check of the defining file is all)."""
    h = hashlib.sha256()
    package = resources.files(__package__)
    try:
        for name in UNIT:
            h.update(name.encode() + b"\0" + package.joinpath(name).read_bytes() + b"\0")
    except OSError:
        return "nosource"
    return h.hexdigest()[:12]


def _plain(f):
    return f


def _plain_entry(f):
    f.py_func = f
    return f


def _disabled_by_env() -> bool:
    return os.environ.get(NO_JIT_ENV, "").strip() not in ("", "0")


try:
    if _disabled_by_env():
        raise ImportError(f"{NO_JIT_ENV}={os.environ[NO_JIT_ENV]}")
    import numba
    from numba.extending import register_jitable
except (ImportError, OSError) as _err:  # OSError: llvmlite's shared library failed to load
    ENABLED = False
    NOTE = f"numba not used ({_err})"
    jitable = inlined = _plain
    entry = lanes = _plain_entry
else:
    ENABLED = True
    NOTE = f"numba {numba.__version__}"
    jitable = register_jitable
    from llvmlite import binding as _llvm

    # LLVM's loop vectoriser proves a loop's arrays apart at run time, with at most this many checks
    # (LLVM's default 8): a loop over lanes reads and writes rows of more arrays than that, and LLVM
    # 14 (Ubuntu 24.04's numba 0.59) left such loops scalar, an rk4 step across 256 lanes 1.4x the
    # scalar kernel's speed where with the checks it is 4.6x (docs/lanes.md). LLVM 22 vectorises
    # them without (the same code either way). A check costs a comparison of two address ranges at
    # a loop's entry; the arithmetic is the same, so the results are the same bits. Set once, before
    # anything compiles (this file is in UNIT: a cache compiled without it is not used).
    _llvm.set_option("mta_sim_ros", "-runtime-memory-check-threshold=128")

    def inlined(f):
        # a new register_jitable per function: it pops ``inline`` from the options it was given
        return register_jitable(inline="always")(f)

    def entry(f):
        """Compile ``f`` (lazily, on first call) and cache it on disk beside its source, in a cache
        file named after the unit's digest (numba names it after the function's qualified name)."""
        f.__qualname__ = f"{f.__qualname__}_unit_{unit_digest()}"
        return numba.njit(cache=True)(f)

    def lanes(f):
        """``entry`` with the numpy error model (module docstring)."""
        f.__qualname__ = f"{f.__qualname__}_unit_{unit_digest()}"
        return numba.njit(cache=True, error_model="numpy")(f)


#: a packed double-precision arithmetic instruction (SSE2, AVX, AVX-512: 2, 4 or 8 lanes at once)
PACKED = re.compile(r"\b(v?(add|sub|mul|div|min|max|blendv|and|or)pd|vfn?m(add|sub)\d{3}pd)\b")
#: a call to the C library's math in LLVM IR, direct or through an LLVM intrinsic: a call a value
C_MATH_CALL = re.compile(r"call [^@\n]*@(llvm\.)?(sin|cos|tan|atan2|atan|tanh|exp|log|pow)(\.f64)?\b")


def assembly(f, *args) -> tuple[str, str]:
    """(assembly, LLVM IR) of the entry ``f`` compiled anew for ``args`` with its own options: numba
    cannot show code it loaded from its cache. For the tests and benchmarks that read what the
    compiler made of a loop (vectorised or not); needs numba."""
    options = {k: v for k, v in f.targetoptions.items() if k not in ("cache", "nopython")}
    fresh = numba.njit(**options)(f.py_func)
    fresh(*args)
    signature = fresh.signatures[0]
    return fresh.inspect_asm(signature), fresh.inspect_llvm(signature)


def vector_evidence(f, *args) -> dict:
    """What the compiler made of the loop in ``f`` for ``args``: the packed instructions in its
    assembly, the vector types in its IR (``<4 x double>``) and the C math calls left in it."""
    asm, ir = assembly(f, *args)
    return {"packed": len(PACKED.findall(asm)), "vector_types": sorted(set(re.findall(r"<\d+ x double>", ir))),
            "c_math_calls": sorted({m.group(2) for m in C_MATH_CALL.finditer(ir)})}
