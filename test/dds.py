"""Helpers for tests that talk to real processes over real DDS, on loopback only.

Every process, the test's own included, gets the loopback environment (loopback.loopback_env:
discovery on this host, the Fast DDS loopback profile) and this test session's own
ROS_DOMAIN_ID, so parallel runs do not cross. The test side uses a private rclpy Context and
spins an executor until a condition holds or a deadline passes (waiting is not an assertion).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rosbags.highlevel import AnyReader

from mta_sim_ros.node.loopback import loopback_env

REPO = Path(__file__).resolve().parents[1]
# A domain of this session's own (valid Linux domains: 0-101); override with MTA_TEST_DOMAIN.
DOMAIN = int(os.environ.get("MTA_TEST_DOMAIN", 1 + os.getpid() % 100))


def ros_env() -> dict[str, str]:
    env = loopback_env(domain=DOMAIN)
    env["PYTHONUNBUFFERED"] = "1"
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH", "")) if p)
    return env


# this process's own participants (Probe) too: Fast DDS reads the profile at the first one
os.environ.update(loopback_env())


def write_params(path: Path, **params) -> Path:
    """A ROS parameters file for the simulator node."""
    lines = ["/**:", "  ros__parameters:"]  # matches the node under any namespace
    for k, v in params.items():
        value = ("true" if v else "false") if isinstance(v, bool) else repr(v) if isinstance(v, str) else v
        lines.append(f"    {k}: {value}")
    path.write_text("\n".join(lines) + "\n")
    return path


def start_node(params_file: Path, log: Path | None, ros_args=(), preexec_fn=None) -> subprocess.Popen:
    """The simulator node in its own process; ``ros_args`` are passed after --ros-args. Its output
    goes to ``log``, or with ``log=None`` to a pipe (``proc.stdout``, read after it ends: a file
    the node writes is subject to its file-size limit, a pipe is not)."""
    extra = ["--ros-args", *ros_args] if ros_args else []
    out = subprocess.PIPE if log is None else log.open("w")
    return subprocess.Popen([sys.executable, "-m", "mta_sim_ros.cli", "node", "--params-file", str(params_file),
                             *extra], env=ros_env(), stdout=out, stderr=subprocess.STDOUT, cwd=REPO,
                            preexec_fn=preexec_fn, text=log is None)


def start_mta(*args) -> subprocess.Popen:
    """``mta ARGS`` in a process of its own (a player, a controller), its output to a pipe
    (``proc.stdout``, text)."""
    return subprocess.Popen([sys.executable, "-m", "mta_sim_ros.cli", *map(str, args)], env=ros_env(), cwd=REPO,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def start_python(code: str, log: Path) -> subprocess.Popen:
    """Another process running ``code`` (dedented), e.g. a steering publisher."""
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], env=ros_env(), stdout=log.open("w"),
                            stderr=subprocess.STDOUT, cwd=REPO)


def stop(proc: subprocess.Popen, sig=signal.SIGTERM, timeout=20.0) -> int:
    if proc.poll() is None:
        proc.send_signal(sig)
    return proc.wait(timeout=timeout)


def bags_in(folder: Path) -> list[Path]:
    """The bags the node wrote into ``folder``, oldest first (their names start with the UTC time)."""
    return sorted(folder.glob("*.mcap"))


def read_bag(path: Path) -> dict[str, list]:
    """topic -> [(log time, message)] of a bag, by rosbags (a reader independent of the package)."""
    out: dict[str, list] = {}
    with AnyReader([path]) as r:
        for con, log_time, raw in r.messages():
            out.setdefault(con.topic, []).append((log_time, r.deserialize(raw, con.msgtype)))
    return out


def value(diagnostics, key: str) -> str:
    """A value of the node's diagnostics (a DiagnosticArray; '0' if absent)."""
    return next((kv.value for kv in diagnostics.status[0].values if kv.key == key), "0")


class Probe:
    """The test's own node in a private Context: subscribe, publish, call services."""

    def __init__(self, name="probe"):
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=DOMAIN)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.received: dict[str, list] = {}

    def subscribe(self, topic: str, msg_type, qos=10) -> list:
        box = self.received.setdefault(topic, [])
        self.node.create_subscription(msg_type, topic, box.append, qos)
        return box

    def publisher(self, msg_type, topic: str, timeout=10.0):
        """A publisher on ``topic``, returned once the node under test has subscribed to it."""
        pub = self.node.create_publisher(msg_type, topic, 10)
        assert self.spin_until(lambda: pub.get_subscription_count() > 0, timeout), f"nobody subscribes {topic}"
        return pub

    def spin_until(self, condition, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if condition():
                return True
            self.executor.spin_once(timeout_sec=0.05)
        return condition()

    def call(self, srv_type, name: str, request, timeout=10.0):
        client = self.node.create_client(srv_type, name)
        assert client.wait_for_service(timeout_sec=timeout), f"service {name} not available"
        future = client.call_async(request)
        assert self.spin_until(future.done, timeout), f"service {name} did not answer"
        return future.result()

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)
