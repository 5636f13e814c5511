"""The package's rooms import one way, and the code reaches into nothing private.

- import-linter (its own contracts file, .importlinter): model <- integrate <- a run (sim, session
  and their parts) <- the ROS glue <- tools <- cli, bag beside model; and the physics, a run, the
  bags and the research commands import no ROS package.
- No module imports another package's private names (``from x import _y``, ``x._y``), ours
  included, and none assigns to an attribute of something it imported (monkeypatching).
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

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "mta_sim_ros"
SOURCES = sorted(PACKAGE.rglob("*.py"))


def test_the_import_contracts_hold():
    lint = Path(sys.executable).with_name("lint-imports")
    assert lint.exists(), "import-linter is a test requirement (requirements.txt)"
    done = subprocess.run([str(lint), str(REPO / ".importlinter")], cwd=REPO, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert "2 kept, 0 broken" in done.stdout


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


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_private_imports_and_no_monkeypatching(path):
    tree = ast.parse(path.read_text(), str(path))
    assert private_imports(tree) == []
    assert patches(tree) == []


def test_the_scans_see_what_they_look_for():
    """The two scans above on code that does what they forbid."""
    code = ast.parse("from mcap_ros2._dynamic import serialize_dynamic\nfrom .loader import _Loader\n"
                     "import numpy as np\nfrom .node import SimNode\nSimNode._on_tick = None\nnp.pi = 3\n"
                     "setattr(SimNode, 'x', 1)\nself_like = object()\nself_like.x = 1\n")
    assert private_imports(code) == ["mcap_ros2._dynamic", "loader._Loader"]
    assert len(patches(code)) == 3
