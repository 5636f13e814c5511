"""A Python process of its own, for what a test must not do to the process pytest runs in: change
its working directory or its environment, or hook every file it opens. The child is this
interpreter, with the checkout and this folder importable (as in the test process)."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

TESTS = Path(__file__).resolve().parent
REPO = TESTS.parent


def python(code: str, *args: str, cwd: Path | str | None = None, env: dict[str, str] | None = None,
           timeout: float = 300) -> subprocess.CompletedProcess:
    """``code`` (dedented) run with ``args`` (its sys.argv[1:]) in a child from ``cwd``, its
    environment this process's with ``env`` over it; the finished process, its output as text."""
    path = os.pathsep.join(p for p in (str(REPO), str(TESTS), os.environ.get("PYTHONPATH", "")) if p)
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code), *args], cwd=cwd,
                          env={**os.environ, "PYTHONPATH": path, **(env or {})},
                          capture_output=True, text=True, timeout=timeout)


def call(function, *args: str, cwd: Path | str | None = None, env: dict[str, str] | None = None,
         timeout: float = 300) -> str:
    """``function(*args)``, a module-level function of a test module called with literal
    arguments, run in a child as ``python`` runs code; asserts it returned (its assertions held),
    and gives back what it printed."""
    done = python(f"import {function.__module__} as m\nm.{function.__name__}(*{args!r})", cwd=cwd, env=env,
                  timeout=timeout)
    assert done.returncode == 0, f"{function.__name__} in a child process:\n{done.stderr[-4000:]}"
    return done.stdout
