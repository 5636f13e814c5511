"""``mta recover`` at its border: whatever the output path, the crashed bag it reads is never
written, and a refusal is one line and exit 2.

Each case names the output in its own way (a symlink to the input, a hard link, a path through
``..``, the input's own path, a folder that does not exist, a directory); the input's bytes are
compared before and after, and no temporary file is left beside the output. The command runs as
a user runs it, a process of its own started in the bag's folder, so relative paths are as a user
types them.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import pytest
from hostile import mta

from mta_sim_ros.bag import BagWriter, float64, read_messages


def crashed_bag(folder: Path) -> Path:
    """A bag cut short as SIGKILL leaves it: complete chunks, then a chunk cut in the middle,
    no summary and no footer."""
    path = folder / "crashed.mcap"
    with BagWriter(path, chunk_size=1024) as bag:
        bag.add_topic("/traction_power", "std_msgs/msg/Float64")
        for i in range(600):
            bag.write("/traction_power", float64(float(i)), log_time_ns=i * 10**7)
    data = path.read_bytes()
    path.write_bytes(data[:len(data) * 2 // 3])
    return path


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def symlink_to_input(folder: Path) -> str:
    (folder / "link.mcap").symlink_to("crashed.mcap")
    return "link.mcap"


def hard_link_to_input(folder: Path) -> str:
    os.link(folder / "crashed.mcap", folder / "hard.mcap")
    return "hard.mcap"


def through_dotdot(folder: Path) -> str:
    (folder / "sub").mkdir()
    return "sub/../crashed.mcap"


def symlinked_folder(folder: Path) -> str:
    (folder / "again").symlink_to(folder)
    return "again/crashed.mcap"


def the_input_itself(folder: Path) -> str:
    return "crashed.mcap"


def folder_missing(folder: Path) -> str:
    return "nowhere/out.mcap"


def a_directory(folder: Path) -> str:
    (folder / "out.mcap").mkdir()
    return "out.mcap"


REFUSED = [
    (symlink_to_input, "itself"),
    (hard_link_to_input, "itself"),
    (through_dotdot, "itself"),
    (symlinked_folder, "itself"),
    (the_input_itself, "itself"),
    (folder_missing, "folder nowhere does not exist"),
    (a_directory, "is a directory"),
]


def run_recover(folder: Path, *args: str) -> tuple[int, str, str]:
    """``mta recover ARGS`` started in ``folder``: its exit code, stdout and stderr."""
    done = mta("recover", *args, cwd=folder)
    return done.returncode, done.stdout, done.stderr


@pytest.mark.parametrize("output,expected", REFUSED, ids=[case.__name__ for case, _ in REFUSED])
def test_an_output_that_reaches_the_input_or_cannot_be_a_file_is_refused(tmp_path, output, expected):
    bag = crashed_bag(tmp_path)
    before = digest(bag)
    code, out, err = run_recover(tmp_path, "crashed.mcap", "-o", output(tmp_path))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("mta recover: ") and expected in err, err
    assert digest(bag) == before
    assert not list(tmp_path.rglob("*.part")), "a temporary file was left behind"


def test_a_missing_input_is_refused(tmp_path):
    code, out, err = run_recover(tmp_path, "gone.mcap", "-o", "out.mcap")
    assert (code, out) == (2, "") and err.count("\n") == 1 and "gone.mcap" in err
    assert not (tmp_path / "out.mcap").exists()


def test_an_input_that_is_not_a_bag_fails_and_leaves_the_output_as_it_was(tmp_path):
    (tmp_path / "junk.mcap").write_bytes(b"not an mcap file")
    (tmp_path / "out.mcap").write_bytes(b"an earlier result")
    code, out, err = run_recover(tmp_path, "junk.mcap", "-o", "out.mcap")
    assert (code, out) == (1, "") and err.count("\n") == 1 and "junk.mcap" in err
    assert (tmp_path / "out.mcap").read_bytes() == b"an earlier result"
    assert not list(tmp_path.rglob("*.part"))


def test_another_existing_file_is_replaced_whole_and_a_symlink_to_it_kept(tmp_path):
    """An output that exists and is not the input is replaced once the new bag is complete; an
    output named through a symlink replaces the file the link points to."""
    bag = crashed_bag(tmp_path)
    before = digest(bag)
    (tmp_path / "old.mcap").write_bytes(b"an earlier result")
    (tmp_path / "latest.mcap").symlink_to("old.mcap")
    code, out, err = run_recover(tmp_path, "crashed.mcap", "-o", "latest.mcap")
    assert code == 0 and err == "" and out.startswith("latest.mcap: ")
    assert (tmp_path / "latest.mcap").is_symlink()
    values = [m.data for _, _, m in read_messages(tmp_path / "old.mcap")]
    assert values == [float(i) for i in range(len(values))] and 0 < len(values) < 600
    assert digest(bag) == before
    assert not list(tmp_path.rglob("*.part"))
