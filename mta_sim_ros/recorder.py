"""The node's run log: one MCAP per run, named ``<UTC start>_<run id>.mcap`` in the bag dir.

No ROS imports: the node hands over topic names, types and CDR bytes. Writing never takes the
simulator down: the first error (disk full, a dir that cannot be written) closes the bag so that
what reached it stays readable (``mta recover`` rebuilds it if even the footer could not be
written), stops recording, and is reported through ``error``.

With ``background=True`` (the node) the MCAP work happens on a thread of its own: ``write`` and
``write_batch`` only append the bytes to a deque and return, so building the records (~10 us a
message in the mcap library) and compressing each chunk stay off the simulation's tick. The tick
never wakes that thread: it looks at the deque every POLL_SECONDS by itself. Signalling it from
the tick (a queue put per tick) let the scheduler run the
woken thread in the middle of the tick: in the node's benchmark the slowest 0.1 % of ticks then
lost ~1 ms inside that put, off the CPU. ``start`` and ``close`` first wait until everything
handed over is written, so a closed bag holds every message handed over before. After SIGKILL
what was still waiting (at most POLL_SECONDS of messages) is lost with the open chunk.
"""
from __future__ import annotations

import collections
import datetime
import threading
import time
import uuid
from pathlib import Path

from .bag import BagError, BagWriter

#: How often the background thread looks for messages to write, s.
POLL_SECONDS = 0.02


class RunRecorder:
    def __init__(self, bag_dir: str, topics: dict[str, str], metadata: dict[str, str], background: bool = False,
                 rename: dict[str, str] | None = None):
        """``topics``: fully qualified name -> type (pkg/msg/Name); ``metadata``: the run's
        description (files, parameters, version), stored as the metadata record mta_sim_ros;
        ``background``: write on a thread of its own (see the module docstring); ``rename``: names
        the caller writes under -> their topic in the bag (the node's relative names -> names
        qualified in its namespace), resolved on the writing thread."""
        self.bag_dir = Path(bag_dir)
        self.topics = dict(topics)
        self.rename = dict(rename or {})
        self.metadata = dict(metadata)
        self.writer: BagWriter | None = None
        self.path: Path | None = None
        self.error: str = ""
        self.messages = 0
        self.thread_cpu = 0.0  # s of CPU the writing took on the background thread (this bag)
        self._pending: collections.deque | None = None  # handed over, not yet written (background)
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
            self.writer = BagWriter(str(self.path), metadata={"mta_sim_ros": self.metadata})
            for topic, type_name in self.topics.items():
                self.writer.add_topic(topic, type_name)
        except (BagError, OSError) as err:
            self._fail(err)
            return None
        self.error = ""
        return self.path

    @property
    def recording(self) -> bool:
        return self.writer is not None

    def write(self, topic: str, cdr: bytes, log_time_ns: int) -> None:
        self.write_batch(((topic, cdr),), log_time_ns)

    def write_batch(self, messages, log_time_ns: int) -> None:
        """Log messages, all at ``log_time_ns``: a dict topic -> CDR bytes, or (topic, bytes)
        pairs. With ``background`` the container is handed over as it is: do not change it."""
        if self.writer is None:
            return
        if self._pending is not None:
            self._pending.append((self.writer, messages, log_time_ns))  # no wake-up: the thread polls
        else:
            self._write(self.writer, messages, log_time_ns)

    def _write(self, writer: BagWriter, messages, log_time_ns: int) -> None:
        if writer is not self.writer:  # queued for a bag that has failed since
            return
        rename = self.rename
        try:
            for topic, cdr in (messages.items() if isinstance(messages, dict) else messages):
                writer.write_raw(rename.get(topic, topic), cdr, log_time_ns)
                self.messages += 1
        except BagError as err:
            self._fail(err)

    def _drain(self) -> None:
        """The background thread: every POLL_SECONDS, write what was handed over, in order; an
        Event among it is set once everything before it is written (``_sync``)."""
        pending = self._pending
        while True:
            time.sleep(POLL_SECONDS)
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
        self.error = f"recording stopped: {err}"
        if self.writer is not None:
            try:
                self.writer.close()
            except BagError:
                pass  # already reported; the writer aborted and keeps what it had written
        self.writer = None
