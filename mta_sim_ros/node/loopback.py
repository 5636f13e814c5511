"""The network rule in one place: DDS stays on loopback for every process the package starts.

Two settings make it. ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` keeps discovery on this host,
but the rmw (rmw_fastrtps_cpp, ROS 2 Jazzy) still binds its transports to every interface. The
Fast DDS profile config/fastdds_loopback.xml, named by FASTRTPS_DEFAULT_PROFILES_FILE (Fast DDS
2.x, which Jazzy ships) and FASTDDS_DEFAULT_PROFILES_FILE (3.x), binds the participant's UDP
transport to 127.0.0.1: its listening sockets and the locators it announces are loopback only.
What the profile cannot reach is said in the README ("The network rule")."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Mapping

from ..config import config_dir

#: The Fast DDS profile every process started by the package loads.
PROFILE_NAME = "fastdds_loopback.xml"

#: The variables Fast DDS reads the profile's path from (2.x, 3.x).
PROFILE_VARIABLES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")


def profile_path() -> Path:
    """The loopback profile, installed (share/mta_sim_ros/config) or in the checkout."""
    return (config_dir() / PROFILE_NAME).resolve()


def loopback_env(base: Mapping[str, str] | None = None, domain: int | None = None) -> dict[str, str]:
    """``base`` (default os.environ) with discovery on this host, the loopback profile, no static
    peers elsewhere and, if given, ``domain`` as ROS_DOMAIN_ID: the environment of a child process
    that talks DDS."""
    env = dict(os.environ if base is None else base)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_STATIC_PEERS", None)
    for name in PROFILE_VARIABLES:
        env[name] = str(profile_path())
    if domain is not None:
        env["ROS_DOMAIN_ID"] = str(domain)
    return env
