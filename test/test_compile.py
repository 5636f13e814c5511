"""``mta compile`` (tools/compile.py): after it, numba's cache holds every kernel entry point the
package calls, so the first node start, run, sweep or field run compiles nothing."""
from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

from mta_sim_ros import jit

REPO = Path(__file__).resolve().parents[1]
#: entry points only the tests call: the per-point form of outline_extent's walk, which
#: test_sweep_metrics holds outline_extent to
TESTS_ONLY: set[str] = {"beside_offsets"}


def entry_points() -> set[str]:
    """(module stem).(function) of every function decorated ``@entry`` in jit.UNIT's files."""
    found = set()
    for name in jit.UNIT:
        path = REPO / "mta_sim_ros" / name
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef) and any(
                    getattr(d, "id", getattr(getattr(d, "func", None), "id", None)) == "entry" for d in node.decorator_list):
                found.add(f"{path.stem}.{node.name}")
    return found


@pytest.mark.slow
@pytest.mark.skipif(not jit.ENABLED, reason=f"numba is not used here: {jit.NOTE}")
def test_after_mta_compile_every_entry_point_is_in_numbas_cache(tmp_path):
    cache = tmp_path / "numba-cache"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    env.pop("MTA_SIM_NO_JIT", None)
    done = subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", "compile", "--quiet"], env=env, cwd=tmp_path,
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("mta compile: the kernels are in numba's cache"), done.stdout
    cached = {p.name.split("_unit_")[0] for p in cache.rglob("*.nbi")}
    wanted = {e for e in entry_points() if e.split(".")[1] not in TESTS_ONLY}
    assert len(wanted) >= 16 and wanted <= cached, wanted - cached
    assert not list(tmp_path.glob("mta-compile-*")) and sorted(p.name for p in tmp_path.iterdir()) == ["numba-cache"]


def test_without_numba_there_is_nothing_to_compile(tmp_path):
    env = {**os.environ, "MTA_SIM_NO_JIT": "1"}
    done = subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", "compile"], env=env, cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.startswith("mta compile: nothing to compile"), done
