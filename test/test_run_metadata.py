"""The node's run on its latched topic ``run_metadata`` (topics.RUN_METADATA_TOPIC): a bag of any
recorder (here: the node's bag rewritten by rosbags, an independent writer that keeps messages
but not MCAP metadata records, as ros2 bag record's bags hold none of ours) is analysed and
re-simulated as the node's own bag is."""
from __future__ import annotations

import json
from pathlib import Path

from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from test_session import Run

from mta_sim_ros.analysis import load_bag, resimulate
from mta_sim_ros.analysis.bagdata import run_record
from mta_sim_ros.bag import read_messages, read_metadata
from mta_sim_ros.node.run_session import PATH_FIELDS

REPO = Path(__file__).resolve().parents[1]


def steered_run(tmp_path, **overrides) -> Run:
    r = Run(tmp_path, **overrides)
    r.ticks(40)
    r.s.command("steering_angle", 0.15)
    r.ticks(60)
    r.s.command("speed_setpoint", 2.0)
    r.ticks(50)
    return r


def rewritten_by_rosbags(bag, folder):
    """Every connection and message of ``bag`` written again by rosbags (MCAP storage) into
    ``folder``: the messages byte for byte, no metadata record of ours."""
    with AnyReader([bag]) as reader:
        with Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            out = {}
            for con in reader.connections:
                out[con.id] = writer.add_connection(con.topic, con.msgtype, typestore=reader.typestore,
                                                    offered_qos_profiles=con.ext.offered_qos_profiles)
            for con, t, raw in reader.messages():
                writer.write(out[con.id], t, raw)
    [mcap] = folder.glob("*.mcap")
    return mcap


def test_the_topic_holds_the_bags_record_from_each_runs_start(tmp_path):
    r = steered_run(tmp_path)
    r.s.reset()
    r.ticks(10)
    r.s.close()
    first, second = r.bags()
    for bag in (first, second):
        [(_, t, msg)] = list(read_messages(str(bag), ["/run_metadata"]))
        published, record = json.loads(msg.data), read_metadata(bag)["mta_sim_ros"]
        assert published.keys() == record.keys() and len(published) > 20
        for key, value in record.items():  # the same, files named without their folders
            assert published[key] == (value if key not in PATH_FIELDS else Path(value).name), key
        assert str(tmp_path) not in msg.data and str(REPO) not in msg.data and published["param.bag_dir"] == "bags"
    assert len(r.topic("run_metadata")) == 2  # published at each run's start
    assert run_record(second)["clock_offset"] != run_record(first)["clock_offset"]


def test_a_bag_of_another_recorder_is_analysed_and_resimulated(tmp_path):
    r = steered_run(tmp_path)
    r.s.close()
    [bag] = r.bags()
    other = rewritten_by_rosbags(bag, tmp_path / "other")
    assert "mta_sim_ros" not in read_metadata(other)  # what a recorder other than the node writes
    with AnyReader([bag]) as a, AnyReader([other]) as b:
        assert [(c.topic, t, raw) for c, t, raw in a.messages()] == [(c.topic, t, raw) for c, t, raw in b.messages()]
    assert run_record(other)["train_yaml"] == read_metadata(bag)["mta_sim_ros"]["train_yaml"]
    mine, theirs = load_bag(str(bag)), load_bag(str(other))
    assert theirs.train.carts == mine.train.carts and theirs.scene_name == mine.scene_name
    for series in ("poses", "power", "command", "applied"):
        a, b = getattr(mine, series), getattr(theirs, series)
        assert (a.ns == b.ns).all() and (a.values == b.values).all(), series
    again = resimulate(str(other))
    assert again.identical and again.ticks == resimulate(str(bag)).ticks > 100


def test_a_bag_without_either_says_so_in_one_line(tmp_path, capsys):
    from mta_sim_ros import cli

    r = steered_run(tmp_path)
    r.s.close()
    [bag] = r.bags()
    with AnyReader([bag]) as reader:  # the bag without its run_metadata topic, by rosbags
        with Writer(tmp_path / "bare", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            out = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=reader.typestore)
                   for c in reader.connections if c.topic != "/run_metadata"}
            for con, t, raw in reader.messages():
                if con.id in out:
                    writer.write(out[con.id], t, raw)
    [bare] = (tmp_path / "bare").glob("*.mcap")
    assert run_record(bare) is None
    assert cli.main(["analyze", str(bare), "--out", str(tmp_path / "report")]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no metadata record 'mta_sim_ros' and no run_metadata topic" in err, err
