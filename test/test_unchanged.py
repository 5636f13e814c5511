"""Behaviour kept through the one-physics-source rewrite: with kink splitting off, ``mta run`` writes
the same bags as the code before it did, message for message.

The code before the rewrite is taken from this repository's history (BEFORE, the last commit with
the three copies of the equations) and run in a process of its own on that commit's shipped
scenes; the current code runs the same scene files with ``--no-split-kinks``. Every topic's
messages, in log-time order, must be equal to the byte (log time, publish time, sequence, CDR
data); of the metadata only what names versions and paths may differ, and the new option
``split_kinks`` is recorded. The train's frames (topics.FRAME_TOPICS), added since, are the only
new topics. Needs the repository's history (a clone without --depth).
"""
from __future__ import annotations

import subprocess
import sys
import textwrap
from collections import defaultdict
from pathlib import Path

import pytest
from mcap.reader import make_reader

from mta_sim_ros import cli
from mta_sim_ros.topics import FRAME_TOPICS, qualified

REPO = Path(__file__).resolve().parents[1]
BEFORE = "cecef7b730da61fa89761be26112319cd89716ad"
VARYING_METADATA = {"package_version", "scene_file", "train_file"}  # versions and paths


def messages_by_topic(path: Path):
    """(topic -> [(log_time, publish_time, sequence, data)] in log-time order, metadata records)."""
    topics = defaultdict(list)
    with open(path, "rb") as f:
        reader = make_reader(f)
        for _, channel, message in reader.iter_messages(log_time_order=False):
            topics[channel.topic].append((message.log_time, message.publish_time, message.sequence, message.data))
        metadata = {record.name: dict(record.metadata) for record in reader.iter_metadata()}
    return {topic: sorted(rows, key=lambda row: row[0]) for topic, rows in topics.items()}, metadata


@pytest.fixture(scope="module")
def before(tmp_path_factory):
    """The code and scenes of BEFORE, and the bags it writes for every shipped scene."""
    root = tmp_path_factory.mktemp("before")
    present = subprocess.run(["git", "-C", str(REPO), "cat-file", "-e", f"{BEFORE}^{{commit}}"], capture_output=True)
    assert present.returncode == 0, f"commit {BEFORE} is not in this clone's history (clone without --depth)"
    archive = subprocess.run(["git", "-C", str(REPO), "archive", BEFORE, "mta_sim_ros", "config"],
                             capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(root)], input=archive, check=True)
    scenes = sorted((root / "config" / "scenes").glob("*.yaml"))
    assert len(scenes) == 9
    code = textwrap.dedent(f"""
        import sys
        from mta_sim_ros import cli
        assert cli.__file__.startswith({str(root)!r}), cli.__file__
        for scene in sys.argv[1:]:
            name = scene.rsplit("/", 1)[1][:-5]
            assert cli.main(["run", "--scene", scene, "--bag", {str(root)!r} + "/bags/" + name + ".mcap", "--quiet"]) == 0
    """)
    subprocess.run([sys.executable, "-c", code, *map(str, scenes)], cwd=root, check=True, timeout=900,
                   env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin", "HOME": str(root)})
    return root, scenes


def test_without_kink_splitting_the_shipped_scenes_bags_are_unchanged(before, tmp_path):
    root, scenes = before
    for scene in scenes:
        new = tmp_path / f"{scene.stem}.mcap"
        assert cli.main(["run", "--scene", str(scene), "--bag", str(new), "--quiet", "--no-split-kinks"]) == 0
        old_topics, old_meta = messages_by_topic(root / "bags" / f"{scene.stem}.mcap")
        new_topics, new_meta = messages_by_topic(new)
        # the topics added since (the train's frames for ROS tools) come on top; the old ones are unchanged
        assert new_topics.keys() == old_topics.keys() | {qualified(t) for t in FRAME_TOPICS}, scene.stem
        for topic in old_topics:
            assert new_topics[topic] == old_topics[topic], f"{scene.stem}: {topic} differs"
        assert new_meta.keys() == old_meta.keys()
        old_run, new_run = old_meta["mta_sim_ros"], new_meta["mta_sim_ros"]
        assert new_run.pop("split_kinks") == "False"
        assert new_run.keys() == old_run.keys()
        assert {k for k in old_run if new_run[k] != old_run[k]} <= VARYING_METADATA, scene.stem
