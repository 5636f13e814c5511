"""``mta session``: the main job, headless. Starts the simulator node, plays the scene's manoeuvre
into it (``mta maneuver``), stops the node when the manoeuvre ends, analyses the run's bag
(``mta analyze``) and prints where the bag and the report are.

Each piece is a separate process talking over DDS, exactly as a user would run them; DDS stays on
loopback (the children get loopback.loopback_env: discovery on this host, the Fast DDS loopback
profile).
"""
from __future__ import annotations

import argparse
import json
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ..node.params import argument
from ..validate import EXIT_INPUT, InputError, output_folder, path_arg


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", default="scenes/headland_turn.yaml", help="scene to drive (default: headland_turn)")
    p.add_argument("--real-time-factor", type=argument("real_time_factor"), default=4.0,
                   help="simulated seconds per wall second (default 4: the 70 s U-turn takes ~18 s)")
    p.add_argument("--rate", type=argument("publish_rate"), default=50.0,
                   help="node tick rate, Hz (default 50: a 5 ms wall tick at 4x, room for a 2-core machine)")
    p.add_argument("--bag-dir", type=path_arg(output_folder), default="bags",
                   help="where the node writes the run's bag (default bags/)")
    p.add_argument("--report-dir", type=path_arg(output_folder), default="reports",
                   help="where the analysis goes (default reports/)")


def _mta(*args: str, **kwargs) -> subprocess.Popen:
    from ..node.loopback import loopback_env

    return subprocess.Popen([sys.executable, "-m", "mta_sim_ros.cli", *args], env=loopback_env(), **kwargs)


def main(args: argparse.Namespace) -> int:
    # its two processes need ROS and the node the message packages built into the venv: without
    # them one line here (cli.missing_ros), before either starts
    import rclpy  # noqa: F401
    import tf2_msgs.msg  # noqa: F401

    from ..config import resolve_config_path
    from ..physics.loader import load_scene

    scene = resolve_config_path(args.scene)
    try:
        load_scene(scene)  # its faults in one line here, not from inside the node and the player
    except InputError as err:
        print(f"mta session: {err}", file=sys.stderr)
        return EXIT_INPUT
    bag_dir = Path(args.bag_dir).resolve()
    before = set(bag_dir.glob("*.mcap")) if bag_dir.is_dir() else set()
    with tempfile.TemporaryDirectory() as tmp:
        params = Path(tmp) / "params.yaml"
        params.write_text(
            "/**:\n  ros__parameters:\n"
            f"    scene_file: {json.dumps(str(Path(scene).resolve()))}\n    bag_dir: {json.dumps(str(bag_dir))}\n"
            f"    real_time_factor: {args.real_time_factor}\n    publish_rate: {args.rate}\n"
        )
        print(f"mta session: node on '{scene}' at {args.real_time_factor:g}x real time", flush=True)
        # the player first: it counts sim time from the first /clock it hears, so starting it
        # before the node keeps the manoeuvre aligned with the scene's start
        player = _mta("maneuver", "--scene", scene)
        node = _mta("node", "--params-file", str(params))
        try:
            while player.poll() is None:
                if node.poll() is not None:
                    print(f"mta session: the node exited early (code {node.returncode})", file=sys.stderr)
                    return 1
                time.sleep(0.1)
            if player.returncode != 0:
                print(f"mta session: the manoeuvre player failed (code {player.returncode})", file=sys.stderr)
                return 1
        finally:
            for proc in (player, node):
                if proc.poll() is None:
                    proc.send_signal(signal.SIGINT)
            for proc in (player, node):
                try:
                    proc.wait(timeout=60)
                except subprocess.TimeoutExpired:
                    proc.kill()
    new = sorted(set(bag_dir.glob("*.mcap")) - before)
    if not new:
        print(f"mta session: no bag was written in {bag_dir}", file=sys.stderr)
        return 1
    bag = new[-1]
    report = Path(args.report_dir) / bag.stem
    analysis = _mta("analyze", str(bag), "-o", str(report))
    if analysis.wait() != 0:
        print("mta session: the analysis failed", file=sys.stderr)
        return 1
    print(f"bag:    {bag}\nreport: {report}/summary.md (plots and CSV beside it)")
    return 0
