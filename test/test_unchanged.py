"""Behaviour kept through the rewrites: ``mta run`` writes the same bags as the code before them
did, message for message.

Two rewrites are held to the code before them, each taken from this repository's history and run
in a process of its own on that commit's shipped scenes:

- ONE_PHYSICS (the last commit with three copies of the equations): the current code run with
  ``--no-split-kinks``, the option added since; the train's frames (topics.FRAME_TOPICS), added
  since, are the only new topics and ``split_kinks`` the only new metadata;
- HOUSE (the last commit with the flat package, before the rooms of docs/architecture.md): the
  current code run as it is; every topic and every metadata field the same but the run's stated
  accuracy (ACCURACY), added since, and the robot model's comment, which names the train file by
  its name since, not by its path (same_but_the_path).

Every topic's messages, in log-time order, must be equal to the byte (log time, publish time,
sequence, CDR data); of the metadata only what names versions and paths may differ. Needs the
repository's history (a clone without --depth).
"""
from __future__ import annotations

import re
import subprocess
import sys
import textwrap
from collections import defaultdict
from pathlib import Path

import pytest
from mcap.reader import make_reader

from mta_sim_ros import cli
from mta_sim_ros.messages.topics import FRAME_TOPICS, qualified

pytestmark = pytest.mark.slow  # every shipped scene run by the code of before and of now

REPO = Path(__file__).resolve().parents[1]
ONE_PHYSICS = "cecef7b730da61fa89761be26112319cd89716ad"
HOUSE = "555ebc7b202a8917f3b5f841e8b9f89b3d55bf7b"
VARYING_METADATA = {"package_version", "scene_file", "train_file"}  # versions and paths
ACCURACY = {"position_error_m", "tolerance_m", "error_estimate"}  # each run's stated accuracy, added since


def messages_by_topic(path: Path):
    """(topic -> [(log_time, publish_time, sequence, data)] in log-time order, metadata records)."""
    topics = defaultdict(list)
    with open(path, "rb") as f:
        reader = make_reader(f)
        for _, channel, message in reader.iter_messages(log_time_order=False):
            topics[channel.topic].append((message.log_time, message.publish_time, message.sequence, message.data))
        metadata = {record.name: dict(record.metadata) for record in reader.iter_metadata()}
    return {topic: sorted(rows, key=lambda row: row[0]) for topic, rows in topics.items()}, metadata


def bags_of(commit: str, root: Path, scenes: int) -> list[Path]:
    """The shipped scenes of ``commit`` (there must be ``scenes`` of them), each run by that
    commit's code into root/bags/<scene>.mcap; returns the scene files."""
    present = subprocess.run(["git", "-C", str(REPO), "cat-file", "-e", f"{commit}^{{commit}}"], capture_output=True)
    assert present.returncode == 0, f"commit {commit} is not in this clone's history (clone without --depth)"
    archive = subprocess.run(["git", "-C", str(REPO), "archive", commit, "mta_sim_ros", "config"],
                             capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(root)], input=archive, check=True)
    found = sorted((root / "config" / "scenes").glob("*.yaml"))
    assert len(found) == scenes
    code = textwrap.dedent(f"""
        import sys
        from mta_sim_ros import cli
        assert cli.__file__.startswith({str(root)!r}), cli.__file__
        for scene in sys.argv[1:]:
            name = scene.rsplit("/", 1)[1][:-5]
            assert cli.main(["run", "--scene", scene, "--bag", {str(root)!r} + "/bags/" + name + ".mcap", "--quiet"]) == 0
    """)
    subprocess.run([sys.executable, "-c", code, *map(str, found)], cwd=root, check=True, timeout=900,
                   env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin", "HOME": str(root)})
    return found


def cdr_string(data: bytes) -> str:
    """A std_msgs/String's text from its CDR bytes (little-endian: header, length, text, NUL)."""
    assert data[:4] == b"\x00\x01\x00\x00"
    return data[8:8 + int.from_bytes(data[4:8], "little") - 1].decode()


def same_but_the_path(old_rows, new_rows) -> bool:
    """The robot descriptions are the same messages but that the old one names the train file by
    its path, the new one by its name (messages/urdf.py's comment)."""
    if len(old_rows) != len(new_rows):
        return False
    for old, new in zip(old_rows, new_rows):
        old_text = re.sub(r" from (/\S*/)([^/\s]+\.yaml), made by", r" from \2, made by", cdr_string(old[3]))
        if old[:3] != new[:3] or old_text != cdr_string(new[3]) or "/" in cdr_string(new[3]).split(", made by")[0]:
            return False
    return True


def compare(old_bag: Path, new_bag: Path, scene: str, new_topics_expected=frozenset(), new_fields=frozenset()):
    """The bags hold the same messages on every topic of the old one (the new one may add
    ``new_topics_expected``) and the same metadata but for VARYING_METADATA and ``new_fields``."""
    old_topics, old_meta = messages_by_topic(old_bag)
    new_topics, new_meta = messages_by_topic(new_bag)
    assert new_topics.keys() == old_topics.keys() | set(new_topics_expected), scene
    for topic in old_topics:
        if topic == "/robot_description":
            assert same_but_the_path(old_topics[topic], new_topics[topic]), f"{scene}: {topic} differs"
            continue
        assert new_topics[topic] == old_topics[topic], f"{scene}: {topic} differs"
    assert new_meta.keys() == old_meta.keys()
    old_run, new_run = old_meta["mta_sim_ros"], dict(new_meta["mta_sim_ros"])
    for field in new_fields:
        new_run.pop(field)
    assert new_run.keys() == old_run.keys()
    assert {k for k in old_run if new_run[k] != old_run[k]} <= VARYING_METADATA, scene
    return new_meta["mta_sim_ros"]


@pytest.fixture(scope="module")
def before_one_physics(tmp_path_factory):
    root = tmp_path_factory.mktemp("one_physics")
    return root, bags_of(ONE_PHYSICS, root, 9)


@pytest.fixture(scope="module")
def before_house(tmp_path_factory):
    root = tmp_path_factory.mktemp("house")
    return root, bags_of(HOUSE, root, 10)


def test_without_kink_splitting_the_shipped_scenes_bags_are_unchanged(before_one_physics, tmp_path):
    root, scenes = before_one_physics
    for scene in scenes:
        new = tmp_path / f"{scene.stem}.mcap"
        assert cli.main(["run", "--scene", str(scene), "--bag", str(new), "--quiet", "--no-split-kinks"]) == 0
        run = compare(root / "bags" / f"{scene.stem}.mcap", new, scene.stem,
                      new_topics_expected={qualified(t) for t in FRAME_TOPICS}, new_fields={"split_kinks"} | ACCURACY)
        assert run["split_kinks"] == "False"


def test_the_rooms_left_every_shipped_scenes_bag_as_it_was(before_house, tmp_path):
    root, scenes = before_house
    for scene in scenes:
        new = tmp_path / f"{scene.stem}.mcap"
        assert cli.main(["run", "--scene", str(scene), "--bag", str(new), "--quiet"]) == 0
        compare(root / "bags" / f"{scene.stem}.mcap", new, scene.stem, new_fields=ACCURACY)
