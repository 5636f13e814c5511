"""RunRecorder (the node's run log), written on its background thread as the node uses it.

- Everything handed over before ``close`` is in the bag, in order, read back by rosbags (an
  independent reader), with the closing metadata after it; a reset (``start`` again) splits the
  messages between two bags exactly where it happened.
- A failure on the background thread (the bag's write raising, as on a full disk; or an
  unexpected exception) stops recording with the error said, keeps what was written readable,
  and neither ``write`` nor ``close`` blocks or raises afterwards.
The failures come from a BagWriter subclass the recorder is given (its ``bag_writer``). No ROS
node is started.
"""
from __future__ import annotations

import itertools
import resource
import signal
import struct
import threading
from pathlib import Path

import pytest
from child import call
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader

from mta_sim_ros.bag import BagError, BagWriter, read_metadata, recover
from mta_sim_ros.node.recorder import BACKLOG_SECONDS, RunRecorder

TOPICS = {"/traction_power": "std_msgs/msg/Float64", "/applied_steering": "std_msgs/msg/Float64"}


def float64(x: float) -> bytes:
    return b"\x00\x01\x00\x00" + struct.pack("<d", x)


def read(path):
    """(topic, log time, data) of every message, by rosbags."""
    with AnyReader([path]) as reader:
        return [(c.topic, t, reader.deserialize(raw, c.msgtype).data) for c, t, raw in reader.messages()]


def failing_after(count: int, failure: Exception) -> type[BagWriter]:
    """A BagWriter whose writes raise ``failure`` after the first ``count`` (a disk filling up)."""
    calls = itertools.count(1)

    class Failing(BagWriter):
        def write_raw(self, *args, **kwargs):
            if next(calls) > count:
                raise failure
            return super().write_raw(*args, **kwargs)

    return Failing


def held_until(release: threading.Event) -> type[BagWriter]:
    """A BagWriter whose writes wait until ``release`` is set (a writer thread fallen behind)."""

    class Held(BagWriter):
        def write_raw(self, *args, **kwargs):
            release.wait()
            return super().write_raw(*args, **kwargs)

    return Held


def write_ticks(rec: RunRecorder, first: int, count: int) -> None:
    for i in range(first, first + count):
        rec.write_batch([("/traction_power", float64(1000.0 * i)), ("/applied_steering", float64(-i / 7))], i * 10**7)


def test_everything_handed_over_is_in_the_bag_in_order(tmp_path):
    rec = RunRecorder(str(tmp_path), TOPICS, {"scene": "x"}, background=True)
    first = rec.start()
    write_ticks(rec, 0, 3000)
    rec.write("/traction_power", float64(-1.0), 3000 * 10**7)
    rec.close({"tick_count": "3000"})  # returns once the thread has written all of it
    assert rec.messages == 6001 and rec.error == "" and rec.thread_cpu > 0
    got = read(first)
    want = [(t, i * 10**7, v) for i in range(3000)
            for t, v in (("/traction_power", 1000.0 * i), ("/applied_steering", -i / 7))]
    assert got == want + [("/traction_power", 3000 * 10**7, -1.0)]
    meta = read_metadata(first)
    assert meta["mta_sim_ros"] == {"scene": "x"} and meta["mta_sim_ros.run"] == {"tick_count": "3000"}


def test_a_reset_splits_the_messages_between_two_bags(tmp_path):
    rec = RunRecorder(str(tmp_path), TOPICS, {}, background=True)
    first = rec.start()
    write_ticks(rec, 0, 500)
    second = rec.start()  # what the node's reset does: close this run's bag, open the next
    write_ticks(rec, 500, 700)
    rec.close()
    assert first != second
    assert [t for _, t, _ in read(first)] == [i * 10**7 for i in range(500) for _ in range(2)]
    assert [t for _, t, _ in read(second)] == [i * 10**7 for i in range(500, 1200) for _ in range(2)]


@pytest.mark.parametrize("failure", [BagError("disk full (simulated)"), TypeError("unexpected (simulated)")])
def test_a_failure_on_the_writer_thread_stops_recording_and_keeps_the_bag(tmp_path, failure):
    """After 2000 messages every write raises. The error is reported, later writes are dropped
    without blocking, close returns, and what reached the file is readable after recover."""
    rec = RunRecorder(str(tmp_path), TOPICS, {}, background=True, bag_writer=failing_after(2000, failure))
    path = rec.start()
    write_ticks(rec, 0, 1500)  # 3000 messages
    rec._sync()
    assert "recording stopped" in rec.error and str(failure) in rec.error
    assert not rec.recording and rec.messages == 2000
    done = threading.Event()
    threading.Thread(target=lambda: (write_ticks(rec, 1500, 10), rec.close(), done.set()), daemon=True).start()
    assert done.wait(10.0), "write or close blocked after the failure"
    fixed = tmp_path / "fixed.mcap"
    recover(path, fixed)
    got = read(fixed)
    assert 0 < len(got) <= 2000
    assert got == [(t, i * 10**7, v) for i in range(1000)
                   for t, v in (("/traction_power", 1000.0 * i), ("/applied_steering", -i / 7))][:len(got)]


def test_renamed_topics_land_under_their_bag_names(tmp_path):
    """The node writes under its relative names (a dict per tick); the bag has the names it was
    given for them (qualified in the node's namespace)."""
    topics = {"/unit1/traction_power": "std_msgs/msg/Float64", "/clock_like": "std_msgs/msg/Float64"}
    rec = RunRecorder(str(tmp_path), topics, {}, background=True,
                      rename={"traction_power": "/unit1/traction_power"})
    path = rec.start()
    rec.write_batch({"traction_power": float64(5.0), "/clock_like": float64(6.0)}, 10)
    rec.close()
    assert read(path) == [("/unit1/traction_power", 10, 5.0), ("/clock_like", 10, 6.0)]


def test_a_bag_no_message_reached_is_removed_and_the_error_says_so(tmp_path):
    """The first write fails (a disk full from the start): no chunk ever reached the file, so
    the bag, which would pass for an empty run, is removed, and the error names it."""
    rec = RunRecorder(str(tmp_path), TOPICS, {}, background=True,
                      bag_writer=failing_after(0, BagError("disk full (simulated)")))
    path = rec.start()
    write_ticks(rec, 0, 10)
    rec._sync()
    assert "disk full (simulated)" in rec.error and f"{path} held no message of this run: removed" in rec.error
    assert not path.exists() and not rec.recording
    rec.close()


def record_ticks(folder: str, file_size_limit: str) -> None:
    """Record 120 ticks (1.2 s of log time: two chunks at FLUSH_SECONDS) into ``folder``, this
    process's files limited to ``file_size_limit`` bytes (0: none) as a full disk would: every
    write past it fails (EFBIG; SIGXFSZ ignored, as the node does). Prints the bag's path, then
    the recorder's error."""
    if int(file_size_limit):
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (int(file_size_limit), resource.RLIM_INFINITY))
    rec = RunRecorder(folder, TOPICS, {})
    path = rec.start()
    write_ticks(rec, 0, 120)
    rec.close()
    print(path)
    print(rec.error)


def test_a_chunk_on_disk_whose_index_could_not_be_written_keeps_the_bag(tmp_path):
    """mcap writes a chunk, then its message index: a disk that fills in between leaves the
    chunk's messages in the file though the writer's write failed. Such a bag is the run's and
    is kept (recover gets the chunk's messages); the recorder counts by the file, not by the
    write. The limit is the end of the first chunk in the same recording made without one."""
    first_out = call(record_ticks, str(tmp_path / "free"), "0").split("\n")
    with open(first_out[0], "rb") as f:
        chunk = make_reader(f).get_summary().chunk_indexes[0]
    limit = chunk.chunk_start_offset + chunk.chunk_length
    path, error = call(record_ticks, str(tmp_path / "full"), str(limit)).split("\n")[:2]
    assert "recording stopped" in error and "File too large" in error and "removed" not in error, error
    assert Path(path).stat().st_size == limit
    result = recover(path, tmp_path / "fixed.mcap")
    in_chunk = sorted(read(Path(first_out[0])), key=lambda m: m[1])[:result["total_messages"]]
    assert result["chunks"] == 1 and result["total_messages"] > 0
    assert read(tmp_path / "fixed.mcap") == in_chunk


def test_behind_says_when_more_than_the_backlog_waits_for_the_writer(tmp_path):
    """``behind`` is true while more than BACKLOG_SECONDS of log time handed over is not yet
    written (the thread is held inside its first write here), false once it is."""
    release = threading.Event()
    rec = RunRecorder(str(tmp_path), TOPICS, {}, background=True, bag_writer=held_until(release))
    rec.start()
    for i in range(int(BACKLOG_SECONDS * 100)):  # exactly BACKLOG_SECONDS at 100 Hz: not more
        rec.write("/traction_power", float64(0.0), i * 10**7)
    assert not rec.behind
    rec.write("/traction_power", float64(0.0), round(BACKLOG_SECONDS * 1e9) + 10**7)
    assert rec.behind
    release.set()
    rec._sync()
    assert not rec.behind and rec.messages == int(BACKLOG_SECONDS * 100) + 1
    rec.close()
