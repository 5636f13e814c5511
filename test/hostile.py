"""What a refusal of a bad input must look like, for test_hostile_files.py and test_hostile_cli.py:
the `mta` command run as a user runs it (its own process, loopback DDS), its exit code, and its
stderr: one line naming the field, the value and the rule, never a traceback."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Callable

from mcap.reader import make_reader

from dds import REPO, ros_env
from mta_sim_ros.bag import BagWriter

CONFIG = REPO / "config"


def mta(*args, cwd: Path | None = None, timeout: float = 120) -> subprocess.CompletedProcess:
    """``mta ARGS`` in a process of its own (ROS on loopback, this session's domain); ``bench ARGS``
    is ``python -m benchmarks ARGS`` (the checkout's benchmarks, importable from ros_env's path)."""
    module, args = (("benchmarks", args[1:]) if args and args[0] == "bench" else ("mta_sim_ros.cli", args))
    return subprocess.run([sys.executable, "-m", module, *map(str, args)], capture_output=True,
                          text=True, cwd=cwd or REPO, timeout=timeout, env=ros_env())


def assert_refused(done: subprocess.CompletedProcess, *expected: str, code: int = 2) -> str:
    """The command exited with ``code`` and said why in one line holding every ``expected``
    text; returns that line."""
    err = done.stderr.strip()
    assert "Traceback" not in done.stderr, done.stderr[-3000:]
    assert done.returncode == code, (done.returncode, err[-2000:])
    lines = err.splitlines()
    assert len(lines) == 1, err[-2000:]
    for text in expected:
        assert text in lines[0], (text, lines[0])
    return lines[0]


def forge_bag(source: Path, out: Path, change: Callable[[dict], None],
              message_time: Callable[[int], int] = lambda t: t, compression: str = "zstd") -> Path:
    """A copy of the bag ``source`` whose record mta_sim_ros is changed in place by ``change``
    and whose messages' log times go through ``message_time``, its chunks ``compression``'s."""
    with open(source, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        change(meta["mta_sim_ros"])
        with BagWriter(str(out), metadata=meta, compression=compression) as bag:
            for c in summary.channels.values():
                schema = summary.schemas[c.schema_id]
                bag.add_channel(c.topic, schema.name, schema.data, c.metadata)
            for _, channel, message in reader.iter_messages(log_time_order=False):
                bag.write_raw(channel.topic, message.data, message_time(message.log_time))
    return out


def recorded_run(folder: Path) -> Path:
    """The bag of a 2 s `mta run` of short_scene in ``folder``."""
    bag = folder / "run.mcap"
    done = mta("run", "--scene", short_scene(folder), "--bag", bag, "--quiet")
    assert done.returncode == 0, done.stderr
    return bag


def short_scene(folder: Path, duration: float = 2.0, rate: float = 50.0, train: Path | None = None,
                name: str = "short") -> Path:
    """A lane change of ``duration`` s at ``rate`` Hz on the default train (or ``train``)."""
    path = folder / f"{name}.yaml"
    path.write_text(f"name: {name}\ntrain: {train or CONFIG / 'trains' / 'default.yaml'}\nduration: {duration}\n"
                    "initial: {speed: 3.0}\nsteering:\n  maneuver: lane_change\n"
                    "  params: {t0: 0.2, amplitude: 0.1, duration: 1.0}\n"
                    f"speed: 3.0\nintegrator: {{method: rk4, step: 0.01}}\npublish_rate: {rate}\n")
    return path


def damaged_bag(source: Path, folder: Path) -> tuple[Path, Path]:
    """(intact, damaged): ``source`` rewritten with its chunks uncompressed (the same records), and
    that copy with one low bit of one /odom message flipped inside its chunk, whose CRC then fails
    (uncompressed, the message's bytes can be found in the file; the chunk stays decodable)."""
    intact = forge_bag(source, folder / "intact.mcap", lambda record: None, compression="none")
    with open(intact, "rb") as f:
        pose = next(m.data for _, _, m in make_reader(f).iter_messages(topics=["/odom"]))
    data = bytearray(intact.read_bytes())
    at = data.find(pose)
    assert at > 0 and data.find(pose, at + 1) < 0
    data[at + len(pose) - 9] ^= 0x01  # a low bit of a covariance or twist value near the end of one /odom
    damaged = folder / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    return intact, damaged
