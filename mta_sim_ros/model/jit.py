"""numba where it can run, the same functions as plain Python where it cannot. No physics here.

The kernels (``model/kernel.py``) are written once, in the subset of Python that numba compiles.
Two decorators give them their two lives:

``jitable``  a function the kernels call from each other: plain Python when called from Python,
             compiled into its caller when called from compiled code (numba's register_jitable).
``entry``    a function Python calls: compiled and cached on disk (numba's njit(cache=True)); its
             ``py_func`` is the same source run as plain Python, calling the plain-Python
             ``jitable`` functions. So ``entry.py_func`` is a whole Python path, not a mix.

Without numba, or with the environment variable ``MTA_SIM_NO_JIT=1`` set when the package is
imported, both decorators leave the function as it is (``entry`` adds ``py_func``, itself).
``ENABLED`` and ``NOTE`` say which holds.

numba checks a cached function against the source file it is defined in, not against the files
of the functions it calls: compiled code that calls into another file would run stale after
that file changes. So every compiled entry point and everything it calls lives in one file.
"""
from __future__ import annotations

import os

NO_JIT_ENV = "MTA_SIM_NO_JIT"


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
    jitable = _plain
    entry = _plain_entry
else:
    ENABLED = True
    NOTE = f"numba {numba.__version__}"
    jitable = register_jitable

    def entry(f):
        """Compile ``f`` (lazily, on first call) and cache it on disk beside its source."""
        return numba.njit(cache=True)(f)
