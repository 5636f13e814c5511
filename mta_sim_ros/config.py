"""Where the package's config files are (scenes, trains, sim.yaml), installed or in a checkout.
No ROS client library here (ament_index_python only, when present)."""
from __future__ import annotations

import sys
from pathlib import Path


def config_dir() -> Path:
    """The package's config folder: share/mta_sim_ros/config when installed by colcon, else the
    source tree's config/ (pip install -e, or running from a checkout), else the one a plain
    ``pip install .`` puts under the environment's prefix (setup.py's data_files)."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    except ImportError:  # no ROS at all (the except clause below could not even name its error)
        pass
    else:
        try:
            share = Path(get_package_share_directory("mta_sim_ros")) / "config"
            if share.is_dir():
                return share
        except (PackageNotFoundError, ValueError, OSError):  # OSError: no AMENT_PREFIX_PATH (a pip venv)
            pass
    source = Path(__file__).resolve().parent.parent / "config"
    installed = Path(sys.prefix) / "share" / "mta_sim_ros" / "config"
    return installed if not source.is_dir() and installed.is_dir() else source


def resolve_config_path(path: str) -> str:
    """A relative path as given if it exists from the working directory, else inside config_dir()
    (so 'scenes/headland_turn.yaml' works from anywhere)."""
    p = Path(path)
    if p.is_absolute() or p.exists():
        return str(p)
    for base in (config_dir(), config_dir().parent):
        if (base / p).exists():
            return str(base / p)
    return str(p)
