"""The node's run log: one MCAP per run, named ``<UTC start>_<run id>.mcap`` in the bag dir.

No ROS imports: the node hands over topic names, types and CDR bytes. Writing never takes the
simulator down: the first error (disk full, a dir that cannot be written) closes the bag so that
what reached it stays readable (``mta recover`` rebuilds it if even the footer could not be
written), stops recording, and is reported through ``error``; a bag that no message of the run
reached is removed, and ``error`` says so.

With ``background=True`` (the node) the MCAP work happens on a thread of its own: ``write`` and
``write_batch`` only append the bytes to a deque and return, so building the records (~10 us a
message in the mcap library) and compressing each chunk stay off the simulation's tick. The tick
never wakes that thread: it looks at the deque by itself, every POLL_SECONDS, or again at once
(MIN_POLL_SECONDS) after a look that found half of BACKLOG_SECONDS of log time or more waiting.
Signalling it from the tick (a queue put per tick) let the scheduler run the woken thread in the
middle of the tick: in the node's benchmark the slowest 0.1 % of ticks then lost ~1 ms inside
that put, off the CPU. ``start`` and ``close`` first wait until everything
handed over is written, so a closed bag holds every message handed over before.

What a SIGKILL loses is bounded in simulated (log) time, whatever the real-time factor: the open
chunk (written once it spans FLUSH_SECONDS of log time, or 64 KiB), and what is still waiting in
the deque, which ``behind`` keeps under BACKLOG_SECONDS: the session holds its ticks while it is
true (a held firing does no I/O: it skips advancing, as when paused, and sleeps MIN_POLL_SECONDS
to leave the interpreter to the writer). So a run at real-time factor 0 goes as fast as its bag
is written, not faster.
"""
from __future__ import annotations

import collections
import datetime
import threading
import time
import uuid
from pathlib import Path

from ..bag import DEFAULT_QOS_YAML, BagError, BagWriter, holds_a_message

#: How often the background thread looks for messages to write while it finds none, s.
POLL_SECONDS = 0.02

#: The shortest look-again interval of the background thread (a run handing over log time fast), s.
MIN_POLL_SECONDS = 0.0005

#: A chunk is written once it spans this much log time (simulated s), whatever its size.
FLUSH_SECONDS = 0.5

#: At most this much log time (simulated s) handed over and not yet written: see ``behind``.
BACKLOG_SECONDS = 0.25


class RunRecorder:
    def __init__(self, bag_dir: str, topics: dict[str, str], metadata: dict[str, str], background: bool = False,
                 rename: dict[str, str] | None = None, qos: dict[str, str] | None = None,
                 bag_writer: type[BagWriter] = BagWriter):
        """``topics``: fully qualified name -> type (pkg/msg/Name); ``metadata``: the run's
        description (files, parameters, version), stored as the metadata record mta_sim_ros;
        ``background``: write on a thread of its own (see the module docstring); ``rename``: names
        the caller writes under -> their topic in the bag (the node's relative names -> names
        qualified in its namespace), resolved on the writing thread; ``qos``: fully qualified
        name -> offered_qos_profiles of a topic not published with the default QoS (a latched one);
        ``bag_writer``: the class each bag is written with (a test's subclass fails or holds a write)."""
        self.bag_dir = Path(bag_dir)
        self.topics = dict(topics)
        self.qos = dict(qos or {})
        self.rename = dict(rename or {})
        self.metadata = dict(metadata)
        self.bag_writer = bag_writer
        self.writer: BagWriter | None = None
        self.path: Path | None = None
        self.error: str = ""
        self.messages = 0
        self.thread_cpu = 0.0  # s of CPU the writing took on the background thread (this bag)
        self._pending: collections.deque | None = None  # handed over, not yet written (background)
        self._handed_ns = self._written_ns = 0  # log time of the last batch handed over, written
        if background:
            self._pending = collections.deque()
            threading.Thread(target=self._drain, name="bag writer", daemon=True).start()

    def start(self) -> Path | None:
        """Open a new bag for a new run (closing the previous one)."""
        self.close()
        self.thread_cpu = 0.0
        stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
        self.path = self.bag_dir / f"{stamp}_{uuid.uuid4().hex[:8]}.mcap"
        self.messages = 0
        try:
            self.bag_dir.mkdir(parents=True, exist_ok=True)
            self.writer = self.bag_writer(str(self.path), metadata={"mta_sim_ros": self.metadata},
                                         flush_after_ns=round(FLUSH_SECONDS * 1e9))
            for topic, type_name in self.topics.items():
                self.writer.add_topic(topic, type_name, self.qos.get(topic, DEFAULT_QOS_YAML))
        except (BagError, OSError) as err:
            self._fail(err)
            return None
        self.error = ""
        return self.path

    @property
    def recording(self) -> bool:
        return self.writer is not None

    @property
    def behind(self) -> bool:
        """More than BACKLOG_SECONDS of log time handed over and not yet written (background
        only): what a SIGKILL would lose on top of the open chunk. Read by the tick, so it only
        compares two ints that each thread sets."""
        return self.writer is not None and self._handed_ns - self._written_ns > BACKLOG_SECONDS * 1e9

    @staticmethod
    def make_way() -> None:
        """Called by a tick held because the writer is ``behind``: sleep MIN_POLL_SECONDS, so
        the writer thread gets the interpreter (GIL) the held ticks would otherwise keep."""
        time.sleep(MIN_POLL_SECONDS)

    def write(self, topic: str, cdr: bytes, log_time_ns: int) -> None:
        self.write_batch(((topic, cdr),), log_time_ns)

    def write_batch(self, messages, log_time_ns: int) -> None:
        """Log messages, all at ``log_time_ns``: a dict topic -> CDR bytes, or (topic, bytes)
        pairs. With ``background`` the container is handed over as it is: do not change it."""
        if self.writer is None:
            return
        if self._pending is not None:
            self._pending.append((self.writer, messages, log_time_ns))  # no wake-up: the thread polls
            self._handed_ns = log_time_ns
        else:
            self._write(self.writer, messages, log_time_ns)

    def _write(self, writer: BagWriter, messages, log_time_ns: int) -> None:
        if writer is self.writer:  # else queued for a bag that has failed since
            rename = self.rename
            try:
                for topic, cdr in (messages.items() if isinstance(messages, dict) else messages):
                    writer.write_raw(rename.get(topic, topic), cdr, log_time_ns)
                    self.messages += 1
            except BagError as err:
                self._fail(err)
        self._written_ns = log_time_ns

    def _drain(self) -> None:
        """The background thread: write what was handed over, in order, looking again after
        ``_nap``; an Event among it is set once everything before it is written (``_sync``)."""
        pending = self._pending
        waiting_ns = 0
        while True:
            time.sleep(self._nap(waiting_ns))
            waiting_ns = self._handed_ns - self._written_ns
            started = time.thread_time()
            while pending:
                item = pending.popleft()
                if isinstance(item, threading.Event):
                    item.set()
                    continue
                try:
                    self._write(*item)
                except Exception as err:  # noqa: BLE001 - never let the thread die: stop recording, say why
                    self._fail(err)
            self.thread_cpu += time.thread_time() - started

    @staticmethod
    def _nap(waiting_ns: int) -> float:
        """Seconds to sleep after a look that found ``waiting_ns`` of log time waiting:
        POLL_SECONDS, or MIN_POLL_SECONDS when it was half of BACKLOG_SECONDS or more (the run
        hands over simulated time so fast, real-time factor 0 or high, that the session would
        otherwise wait for the writer at every look)."""
        return MIN_POLL_SECONDS if waiting_ns >= BACKLOG_SECONDS * 1e9 / 2 else POLL_SECONDS

    def _sync(self) -> None:
        """Wait until everything handed over so far is written."""
        if self._pending is not None:
            done = threading.Event()
            self._pending.append(done)
            done.wait()

    def close(self, closing_metadata: dict[str, str] | None = None) -> None:
        """Finish the bag; ``closing_metadata`` (figures known only at the end, such as the tick
        statistics) goes in as the metadata record ``mta_sim_ros.run``."""
        self._sync()
        if self.writer is not None and closing_metadata:
            try:
                self.writer.add_metadata("mta_sim_ros.run", closing_metadata)
            except BagError as err:
                self.error = str(err)
        if self.writer is not None:
            try:
                self.writer.close()
            except BagError as err:
                self.error = str(err)
            self.writer = None

    def _fail(self, err: Exception) -> None:
        """Stop recording after ``err``: close the bag as far as it can be, remove it if no
        message of the run reached it, and say both in ``error``."""
        writer, self.writer = self.writer, None
        if writer is not None:
            try:
                writer.close()
            except BagError:
                pass  # already reported; the writer aborted and keeps what it had written
        # The writer's count lags the file by the chunk whose write failed after it reached the
        # disk (mcap writes a chunk, then its message index: the disk can fill in between), so
        # a bag is removed only once the file itself shows that recover() would find nothing.
        kept = writer is not None and (writer.messages_in_file > 0 or holds_a_message(writer.path))
        self.error = f"recording stopped: {err}" + ("" if kept else self._remove_empty_bag())

    def _remove_empty_bag(self) -> str:
        """Remove this run's bag, which holds no message (a zero-message bag would pass for a
        run); what was done, as the end of the error."""
        if self.path is None or not self.path.exists():
            return ""
        try:
            self.path.unlink()
        except OSError as err:
            return f"; {self.path} holds no message of this run and could not be removed: {err.strerror or err}"
        return f"; {self.path} held no message of this run: removed"
