"""The node's run log: one MCAP per run, named ``<UTC start>_<run id>.mcap`` in the bag dir.

No ROS imports: the node hands over topic names, types and CDR bytes. Writing never takes the
simulator down: the first error (disk full, a dir that cannot be written) closes the bag so that
what reached it stays readable (``mta recover`` rebuilds it if even the footer could not be
written), stops recording, and is reported through ``error``.
"""
from __future__ import annotations

import datetime
import uuid
from pathlib import Path

from .bag import BagError, BagWriter


class RunRecorder:
    def __init__(self, bag_dir: str, topics: dict[str, str], metadata: dict[str, str]):
        """``topics``: fully qualified name -> type (pkg/msg/Name); ``metadata``: the run's
        description (files, parameters, version), stored as the metadata record mta_sim_ros."""
        self.bag_dir = Path(bag_dir)
        self.topics = dict(topics)
        self.metadata = dict(metadata)
        self.writer: BagWriter | None = None
        self.path: Path | None = None
        self.error: str = ""
        self.messages = 0

    def start(self) -> Path | None:
        """Open a new bag for a new run (closing the previous one)."""
        self.close()
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
        if self.writer is None:
            return
        try:
            self.writer.write_raw(topic, cdr, log_time_ns)
            self.messages += 1
        except BagError as err:
            self._fail(err)

    def close(self, closing_metadata: dict[str, str] | None = None) -> None:
        """Finish the bag; ``closing_metadata`` (figures known only at the end, such as the tick
        statistics) goes in as the metadata record ``mta_sim_ros.run``."""
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
