"""The package's rooms import one way, its compiled code is one cache unit, and the code reaches
into nothing private.

- import-linter (its own contracts file, .importlinter): each room imports only the rooms below it
  (docs/architecture.md), and the physics, a run, the bags and the research commands import no ROS
  package.
- The compiled unit (jit.UNIT): exactly the files that use jit's decorators, and their compiled
  functions read names only from files of the unit (numba freezes what they read into its cache,
  which is keyed on the unit's files alone).
- No module imports another package's private names (``from x import _y``, ``x._y``), ours
  included, and none assigns to an attribute of something it imported (monkeypatching); the
  tests' files neither, nor do they take pytest's monkeypatch or unittest.mock's patch (a test
  changes what it needs through a seam the code offers, or in a process of its own: child.py).
- That the commands of the ROS-free rooms run where no ROS is installed at all is shown by
  test_no_ros.py, in a venv without ROS (not by blocking imports here, where the ROS share
  directories would still be read).
"""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from mta_sim_ros import jit

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "mta_sim_ros"
SOURCES = sorted(PACKAGE.rglob("*.py"))
TEST_SOURCES = sorted(Path(__file__).resolve().parent.glob("*.py"))


def test_the_import_contracts_hold():
    lint = Path(sys.executable).with_name("lint-imports")
    assert lint.exists(), "import-linter is a test requirement (requirements.txt)"
    done = subprocess.run([str(lint), str(REPO / ".importlinter")], cwd=REPO, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    contracts = (REPO / ".importlinter").read_text().count("[importlinter:contract:")
    assert f"{contracts} kept, 0 broken" in done.stdout


def compiled_functions(tree: ast.Module) -> list[ast.FunctionDef]:
    """The functions decorated ``@jitable``, ``@inlined``, ``@entry`` or ``@lanes`` (jit.py)."""
    return [node for node in tree.body if isinstance(node, ast.FunctionDef)
            and any(isinstance(d, ast.Name) and d.id in ("jitable", "inlined", "entry", "lanes") for d in node.decorator_list)]


def module_of(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def bindings(tree: ast.Module, module: str, is_package: bool) -> dict[str, str]:
    """Module-level names bound by imports -> the absolute module they come from: ``import numpy as
    np``: numpy; ``from .laws import rhs``: the package's laws; ``from .. import forces``: forces
    (a package's names count as the package: conservative)."""
    package = module.split(".") if is_package else module.split(".")[:-1]
    found = {}
    for node in tree.body:
        if isinstance(node, ast.Import):
            for a in node.names:
                found[a.asname or a.name.split(".")[0]] = a.name if a.asname else a.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom) and node.module != "__future__":
            base = node.module
            if node.level:
                base = ".".join(package[:len(package) - node.level + 1] + ([node.module] if node.module else []))
            for a in node.names:
                found[a.asname or a.name] = base if node.module else f"{base}.{a.name}"
    return found


def foreign_reads(path: Path, unit: set[str], module: str | None = None) -> list[str]:
    """Names the compiled functions of ``path`` (module ``module``, by default its own) read from
    modules outside ``unit`` (math and numpy are numba's own)."""
    tree = ast.parse(path.read_text(), str(path))
    bound = bindings(tree, module or module_of(path), path.name == "__init__.py")
    found = []
    for fn in compiled_functions(tree):
        for node in ast.walk(fn):
            if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load) and node.id in bound:
                source = bound[node.id]
                if source.split(".")[0] not in ("math", "numpy") and source not in unit:
                    found.append(f"{fn.name} reads {node.id} from {source}")
    return found


UNIT_MODULES = {"mta_sim_ros." + name[:-3].replace("/", ".") for name in jit.UNIT}


def test_the_compiled_unit_is_every_file_of_compiled_code():
    compiled = {str(p.relative_to(PACKAGE)) for p in SOURCES if compiled_functions(ast.parse(p.read_text()))}
    assert compiled | {"jit.py"} == set(jit.UNIT)


@pytest.mark.parametrize("name", jit.UNIT)
def test_compiled_code_reads_names_only_from_the_unit(name):
    assert foreign_reads(PACKAGE / name, UNIT_MODULES) == []


def test_the_unit_scan_sees_a_foreign_read(tmp_path):
    """The scan on compiled code that reads a constant of a file outside the unit, as kernel.py once
    read forces.MS_TO_KMH, beside a function of the unit it may call."""
    probe = tmp_path / "motion.py"
    probe.write_text("import math\nfrom .. import forces\nfrom .laws import steering_rate\n"
                     "@jitable\ndef f(x):\n    return forces.MS_TO_KMH * math.pi * steering_rate(x)\n")
    assert foreign_reads(probe, UNIT_MODULES, "mta_sim_ros.physics.kernel.motion") == [
        "f reads forces from mta_sim_ros.physics.forces"]


def imported_names(tree: ast.Module) -> set[str]:
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            names.update(a.asname or a.name for a in node.names)
    return names


def private_imports(tree: ast.Module) -> list[str]:
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module != "__future__":
            parts = (node.module or "").split(".")
            found += [f"{node.module}.{a.name}" for a in node.names if private(a.name)]
            found += [node.module] if any(private(p) for p in parts) else []
        elif isinstance(node, ast.Import):
            found += [a.name for a in node.names if any(private(p) for p in a.name.split("."))]
    return found


def private(name: str) -> bool:
    """_name is private; __name__ (a module's __version__, __doc__) is not."""
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def patches(tree: ast.Module) -> list[str]:
    """Assignments to an attribute of an imported name (``Module.f = ...``, ``Class.x.y = ...``),
    and setattr on one."""
    imported = imported_names(tree)
    found = []
    for node in ast.walk(tree):
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(
            node, (ast.AugAssign, ast.AnnAssign)) else []
        for target in targets:
            root = target
            while isinstance(root, (ast.Attribute, ast.Subscript)):
                root = root.value
            if isinstance(target, ast.Attribute) and isinstance(root, ast.Name) and root.id in imported:
                found.append(f"line {node.lineno}: {ast.unparse(target)} = ...")
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "setattr" \
                and node.args and isinstance(node.args[0], ast.Name) and node.args[0].id in imported:
            found.append(f"line {node.lineno}: {ast.unparse(node)}")
    return found


def patching_tools(tree: ast.Module) -> list[str]:
    """A function that takes pytest's ``monkeypatch`` fixture, a ``MonkeyPatch`` made by hand,
    and unittest.mock's ``patch``."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            if "monkeypatch" in {a.arg for a in node.args.posonlyargs + node.args.args + node.args.kwonlyargs}:
                found.append(f"line {node.lineno}: {node.name} takes monkeypatch")
        elif isinstance(node, ast.ImportFrom):
            found += [f"line {node.lineno}: from {node.module} import {a.name}" for a in node.names
                      if a.name in ("MonkeyPatch", "patch")]
        elif isinstance(node, ast.Attribute) and node.attr in ("MonkeyPatch", "patch") \
                and isinstance(node.value, ast.Name) and node.value.id in ("pytest", "mock"):
            found.append(f"line {node.lineno}: {ast.unparse(node)}")
    return found


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_private_imports_and_no_monkeypatching(path):
    tree = ast.parse(path.read_text(), str(path))
    assert private_imports(tree) == []
    assert patches(tree) == []


@pytest.mark.parametrize("path", TEST_SOURCES, ids=lambda p: p.name)
def test_the_tests_import_nothing_private_and_patch_nothing(path):
    tree = ast.parse(path.read_text(), str(path))
    assert private_imports(tree) == []
    assert patches(tree) == []
    assert patching_tools(tree) == []


def test_the_scans_see_what_they_look_for():
    """The scans above on code that does what they forbid."""
    code = ast.parse("from mcap_ros2._dynamic import serialize_dynamic\nfrom .loader import _Loader\n"
                     "import numpy as np\nfrom .node import SimNode\nSimNode._on_tick = None\nnp.pi = 3\n"
                     "setattr(SimNode, 'x', 1)\nself_like = object()\nself_like.x = 1\n")
    assert private_imports(code) == ["mcap_ros2._dynamic", "loader._Loader"]
    assert len(patches(code)) == 3
    tests = ast.parse("import pytest\nfrom unittest.mock import patch\nfrom unittest import mock\n"
                      "def test_a(tmp_path, monkeypatch):\n    monkeypatch.setenv('A', '1')\n"
                      "def test_b():\n    with pytest.MonkeyPatch.context() as mp, mock.patch('os.getcwd'):\n"
                      "        pass\n")
    assert len(patching_tools(tests)) == 4


def test_no_file_over_600_lines_and_no_function_over_80():
    """The house's size rules (docs/architecture.md): a file a newcomer can read, a function that
    fits a screen or two, in the package."""
    too_long = []
    for path in sorted((REPO / "mta_sim_ros").rglob("*.py")):
        text = path.read_text()
        if len(text.splitlines()) > 600:
            too_long.append(f"{path.relative_to(REPO)}: {len(text.splitlines())} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.end_lineno - node.lineno >= 80:
                too_long.append(f"{path.relative_to(REPO)}:{node.lineno} {node.name}: "
                                f"{node.end_lineno - node.lineno + 1} lines")
    assert not too_long, too_long
