"""What the launch files (launch/*.launch.py) check before they start anything, and how they end.

A launch that fails after it has started a node leaves that node running, an orphan that goes on
recording (ros2/launch#747). So each launch file asks :func:`require_packages` for the optional
ROS packages its arguments ask for (robot_state_publisher, rviz2, foxglove_bridge: not
exec_depends, package.xml says why) before it returns a single node: one missing, the launch
fails in one line naming the argument, the package and its Debian package, and no node was
started. And every node it starts takes :func:`shutdown_on_failure` as its ``on_exit``: a node
that fails (or the simulator itself ending) shuts the whole launch down, so no node is left
waiting for one that is gone.

Plain Python (ament_index_python): the tests call it without launch, which has no wheels here.
"""
from __future__ import annotations

from typing import Iterable

#: the optional ROS packages a launch argument may ask for -> the Debian package that brings it
OPTIONAL_PACKAGES = {
    "robot_state_publisher": "ros-jazzy-robot-state-publisher",
    "rviz2": "ros-jazzy-rviz2",
    "foxglove_bridge": "ros-jazzy-foxglove-bridge",
}

#: the node whose exit, even a clean one, ends the launch: nothing else runs without it
SIMULATOR = "sim_node"


def missing_packages(packages: Iterable[str]) -> list[str]:
    """Those of ``packages`` that the ament index (AMENT_PREFIX_PATH) does not have."""
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    missing = []
    for package in packages:
        try:
            get_package_prefix(package)
        except PackageNotFoundError:
            missing.append(package)
    return missing


def require_packages(asked: dict[str, str], launch_file: str) -> None:
    """``asked``: package -> the launch argument that asks for it ('rviz:=true'). Raises
    RuntimeError (launch prints its message in one line and exits 1) if any is not installed."""
    missing = missing_packages(asked)
    if missing:
        said = "; ".join(f"{asked[p]} needs the ROS package {p} (apt install {OPTIONAL_PACKAGES.get(p, p)})"
                         for p in missing)
        raise RuntimeError(f"{launch_file}: {said}, which is not installed: no node was started")


def shutdown_on_failure(event, context):
    """``on_exit`` of every node a launch file starts (launch calls it with the ProcessExited
    event): a non-zero exit, or any exit of the simulator, shuts the launch down."""
    name = getattr(event.action, "node_executable", None) or event.process_name
    if event.returncode == 0 and name != SIMULATOR:
        return None  # a driver that finished its manoeuvre, RViz closed by its user
    from launch.actions import Shutdown

    return [Shutdown(reason=f"{event.process_name} exited with code {event.returncode}")]


def rviz_config(config: str, fixed_frame: str, target_frame: str) -> str:
    """A copy of the RViz config ``config`` (config/rviz/mta.rviz) whose fixed frame and view
    target are the given frames (a namespace's ``unit1/odom`` and ``unit1/base_link``: RViz takes
    the fixed frame on its command line, the view's target only from its config); returns its
    path, a new file in the temporary directory (the config itself is never written)."""
    import tempfile

    import yaml

    try:
        with open(config, encoding="utf-8") as f:
            data = yaml.safe_load(f)
        manager = data["Visualization Manager"]
        manager["Global Options"]["Fixed Frame"] = fixed_frame
        manager["Views"]["Current"]["Target Frame"] = target_frame
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as err:
        raise RuntimeError(f"rviz.launch.py: config:={config}: cannot be read as YAML "
                           f"({' '.join(str(getattr(err, 'strerror', None) or err).split())})") from None
    except (KeyError, TypeError):
        raise RuntimeError(f"rviz.launch.py: config:={config}: not an RViz config (it must have "
                           "'Visualization Manager' with 'Global Options' and 'Views: Current')") from None
    with tempfile.NamedTemporaryFile("w", prefix="mta_rviz_", suffix=".rviz", delete=False, encoding="utf-8") as out:
        yaml.safe_dump(data, out, sort_keys=False)
    return out.name
