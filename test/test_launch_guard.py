"""The launch files start nothing when an optional package is missing, and end together.

launch has no wheels here, so the descriptions are read (launchfiles.py), not run: each node of
an optional package (robot_state_publisher, rviz2, foxglove_bridge), and each include that starts
one, comes after a require_packages call that names the package, in the same function; every
node takes shutdown_on_failure as its on_exit (ros2/launch#747: a failed launch left sim_node
running). require_packages itself runs here against a real ament index (a prefix the test
lays out as colcon does), and so does the RViz config the namespace gets.
"""
from __future__ import annotations

import ast
import os
import subprocess
import sys
import textwrap

import launchfiles
import pytest
import yaml
from dds import REPO

from mta_sim_ros.node.launch_support import OPTIONAL_PACKAGES, rviz_config


@pytest.fixture(scope="module")
def launch_files():
    return launchfiles.read_all()


def optional_nodes(tree: ast.AST) -> list[tuple[int, str]]:
    """(line, package) of the Node calls under ``tree`` whose package is optional."""
    return [(n.lineno, launchfiles.text(launchfiles.keyword(n, "package"))) for n in ast.walk(tree)
            if launchfiles.called(n) == "Node"
            and launchfiles.text(launchfiles.keyword(n, "package")) in OPTIONAL_PACKAGES]


def started_by(lf, function: ast.FunctionDef, files) -> list[tuple[int, str]]:
    """(line, optional package) of what ``function`` starts: its own nodes and its includes'."""
    found = optional_nodes(function)
    for call in ast.walk(function):
        if launchfiles.called(call) == "IncludeLaunchDescription":
            included = [files[p.value] for p in ast.walk(call)
                        if isinstance(p, ast.Constant) and isinstance(p.value, str) and p.value in files]
            for other in included:
                found += [(call.lineno, pkg) for _, pkg in optional_nodes(other.tree)]
    return found


def test_every_optional_package_is_checked_before_anything_starts(launch_files):
    checked_any = False
    for name, lf in launch_files.items():
        for function in (n for n in ast.walk(lf.tree) if isinstance(n, ast.FunctionDef)):
            started = started_by(lf, function, launch_files)
            if not started:
                continue
            checks = [c for c in ast.walk(function) if launchfiles.called(c) == "require_packages"]
            assert len(checks) == 1, f"{name}:{function.name} starts {started} without one require_packages"
            check = checks[0]
            # the packages it names: keys of the dicts package -> the asking argument (text)
            named = {launchfiles.text(k) for d in ast.walk(function) if isinstance(d, ast.Dict)
                     and d.lineno <= check.lineno and all(launchfiles.text(v) for v in d.values) for k in d.keys}
            every_node = [c.lineno for c in ast.walk(function) if launchfiles.called(c) == "Node"]
            for line, package in started:
                assert package in named, f"{name}:{line}: {package} starts unchecked"
            assert check.lineno < min(every_node + [line for line, _ in started]), (
                f"{name}:{function.name}: a node is made before require_packages")
            checked_any = True
    assert checked_any


def test_every_node_shuts_the_launch_down_when_it_fails(launch_files):
    nodes = 0
    for name, lf in launch_files.items():
        for call in (n for n in ast.walk(lf.tree) if launchfiles.called(n) == "Node"):
            nodes += 1
            on_exit = launchfiles.keyword(call, "on_exit")
            assert isinstance(on_exit, ast.Name) and on_exit.id == "shutdown_on_failure", f"{name}:{call.lineno}"
    assert nodes >= 7


CHECK = """
    import sys
    from mta_sim_ros.node.launch_support import require_packages
    try:
        require_packages({asked!r}, "sim.launch.py")
    except RuntimeError as err:
        print(err)
        sys.exit(3)
"""


def check_in(prefix, asked: dict[str, str]) -> subprocess.CompletedProcess:
    env = {"PATH": "/usr/bin:/bin", "AMENT_PREFIX_PATH": str(prefix), "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-c", textwrap.dedent(CHECK.format(asked=asked))], env=env,
                          capture_output=True, text=True, timeout=60)


def test_require_packages_reads_the_ament_index(tmp_path):
    """A prefix laid out as colcon installs a package: share/ament_index/resource_index/packages/<pkg>."""
    index = tmp_path / "share" / "ament_index" / "resource_index" / "packages"
    index.mkdir(parents=True)
    (index / "robot_state_publisher").write_text("")
    ok = check_in(tmp_path, {"robot_state_publisher": "robot_state_publisher:=true"})
    assert ok.returncode == 0 and ok.stdout == "", ok.stderr
    refused = check_in(tmp_path, {"robot_state_publisher": "robot_state_publisher:=true", "rviz2": "rviz:=true",
                                  "foxglove_bridge": "foxglove:=true"})
    assert refused.returncode == 3, refused.stderr
    assert refused.stdout == (
        "sim.launch.py: rviz:=true needs the ROS package rviz2 (apt install ros-jazzy-rviz2); foxglove:=true "
        "needs the ROS package foxglove_bridge (apt install ros-jazzy-foxglove-bridge), which is not installed: "
        "no node was started\n")


@pytest.mark.parametrize("namespace", ["", "unit1"])
def test_rviz_gets_a_copy_of_its_config_with_the_namespaces_frames(namespace):
    config = REPO / "config" / "rviz" / "mta.rviz"
    before = config.read_bytes()
    prefix = namespace + "/" if namespace else ""
    path = rviz_config(str(config), prefix + "odom", prefix + "base_link")
    try:
        copy, original = yaml.safe_load(open(path)), yaml.safe_load(before)
        assert config.read_bytes() == before and path != str(config)
        manager = copy["Visualization Manager"]
        assert manager["Global Options"]["Fixed Frame"] == prefix + "odom"
        assert manager["Views"]["Current"]["Target Frame"] == prefix + "base_link"
        original["Visualization Manager"]["Global Options"]["Fixed Frame"] = prefix + "odom"
        original["Visualization Manager"]["Views"]["Current"]["Target Frame"] = prefix + "base_link"
        assert copy == original  # nothing else changed
    finally:
        os.unlink(path)


@pytest.mark.parametrize("content, expected", [
    (None, "cannot be read as YAML (No such file or directory)"),
    ("a: [unclosed", "cannot be read as YAML"),
    ("", "not an RViz config"),
    ("- a\n- b\n", "not an RViz config"),
    ("Visualization Manager:\n  Global Options: {}\n", "not an RViz config"),
])
def test_a_config_that_is_no_rviz_config_is_one_line_naming_it(tmp_path, content, expected):
    path = tmp_path / "view.rviz"
    if content is not None:
        path.write_text(content)
    with pytest.raises(RuntimeError) as err:
        rviz_config(str(path), "odom", "base_link")
    message = str(err.value)
    assert message.startswith(f"rviz.launch.py: config:={path}: ") and expected in message and "\n" not in message
