"""MCAP bag writer compatible with rosbag2 Jazzy (profile "ros2", CDR messages).

Pure Python (``mcap`` and the CDR serializer of :mod:`.cdr`), no rclpy: the
offline run and the ROS node both write the CDR bytes of ``mta_sim_ros.messages``
(:meth:`BagWriter.write_raw`); :meth:`BagWriter.write` encodes plain dicts
with the same serializer.

Crash safety (SIGKILL): messages are collected in a chunk that is compressed
and written when its *uncompressed* size exceeds ``chunk_size`` or, with
``flush_after_ns``, once it spans that much log time (so a slow topic, or a
run whose messages are small, does not keep minutes of them in memory); every
completed chunk is pushed to the operating system right away (no user-space
buffering is left behind).  A killed writer therefore loses at most the open
chunk: fewer than ``chunk_size`` bytes of uncompressed records and less than
``flush_after_ns`` of log time, plus the one message that would have closed
it, plus any schema/channel registered since the last chunk was written.  The
file then has no summary or footer; use
:func:`mta_sim_ros.bag.reader.recover` to rebuild a complete file.  Data
handed to the OS survives a process kill, not a power loss (no fsync).

Order: log times never go back, on any channel nor across the file (``mcap doctor
--strict-message-order``); a message stamped before the latest one written is refused
(BagError), so every writer of the project (``mta run``, the node's recorder, ``recover``)
keeps that order or fails loudly.
"""

import math
import os
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

from mcap import __version__ as _mcap_version
from mcap.exceptions import McapError
from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from .. import __version__ as _package_version
from .cdr import EncodeError, MessageEncoder
from .schemas import BagError, message_definition, type_hash
from .schemas import schema_name as _schema_name

#: Default chunk size in bytes of uncompressed records (see module docstring).
DEFAULT_CHUNK_SIZE = 64 * 1024

#: Library string stored in the MCAP header.
LIBRARY = f"mta_sim_ros/{_package_version} mcap-python/{_mcap_version}"

_COMPRESSION = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}

# rmw's "infinite" duration, as rosbag2 Jazzy records it for default QoS.
_INFINITE = (9223372036, 854775807)

_QOS_CHOICES = {
    "history": ("keep_last", "keep_all", "system_default"),
    "reliability": ("reliable", "best_effort", "system_default"),
    "durability": ("volatile", "transient_local", "system_default"),
}


def qos_profiles_yaml(reliability: str = "reliable", durability: str = "volatile",
                      history: str = "keep_last", depth: int = 10) -> str:
    """Channel metadata ``offered_qos_profiles`` for one publisher, rosbag2 Jazzy style.

    Jazzy (bag metadata version 9) serializes the policies by name
    (``keep_last``, ``reliable``, ...), durations as ``{sec, nsec}`` (rmw's
    infinite duration for unset deadline/lifespan/lease) and the whole as a
    yaml-cpp dumped YAML list, one entry per offering publisher.

    Raises:
        ValueError: unknown policy name or negative depth.
    """
    values = {"history": history, "reliability": reliability, "durability": durability}
    for policy, value in values.items():
        if value not in _QOS_CHOICES[policy]:
            raise ValueError(f"QoS {policy} must be one of {_QOS_CHOICES[policy]}, got {value!r}")
    if depth < 0:
        raise ValueError(f"QoS depth must be >= 0, got {depth}")
    sec, nsec = _INFINITE
    duration = f"\n    sec: {sec}\n    nsec: {nsec}"
    return (f"- history: {history}\n"
            f"  depth: {int(depth)}\n"
            f"  reliability: {reliability}\n"
            f"  durability: {durability}\n"
            f"  deadline:{duration}\n"
            f"  lifespan:{duration}\n"
            f"  liveliness: automatic\n"
            f"  liveliness_lease_duration:{duration}\n"
            f"  avoid_ros_namespace_conventions: false")


#: Default QoS: reliable, volatile, keep_last 10 (rclpy's default publisher QoS).
DEFAULT_QOS_YAML = qos_profiles_yaml()


@dataclass
class _Channel:
    """A registered topic: MCAP channel id plus what is needed to encode for it."""

    channel_id: int
    schema_name: str
    schema_encoding: str
    schema_data: bytes
    message_encoding: str
    metadata: dict[str, str]
    encoder: Callable[[Any], bytes] | None = field(default=None, compare=False)


def _check_str_map(what: str, data: Mapping[str, str]) -> dict[str, str]:
    """Return ``data`` as a dict after checking that keys and values are str."""
    bad = [k for k, v in data.items() if not isinstance(k, str) or not isinstance(v, str)]
    if bad:
        raise BagError(f"{what}: keys and values must be str, offending keys: {bad!r}")
    return dict(data)


class BagWriter:
    """Writes a rosbag2-compatible MCAP file (see the module docstring).

    Usage::

        with BagWriter("run.mcap", metadata={"scene": {"name": "field_a"}}) as bag:
            bag.add_topic("/traction_power", "std_msgs/msg/Float64")
            bag.write("/traction_power", float64(12.5), log_time_ns=t_ns)

    Every I/O failure (disk full, ...) raises :class:`BagError` naming the
    file; after such a failure the writer is closed and ``close()`` is a no-op.
    The partial file can then be salvaged with ``recover()``.  An existing file
    at ``path`` is overwritten.
    """

    def __init__(self, path: str | os.PathLike, metadata: Mapping[str, Mapping[str, str]] | None = None,
                 chunk_size: int = DEFAULT_CHUNK_SIZE, compression: str = "zstd",
                 profile: str = "ros2", flush_after_ns: int = 0):
        """Open ``path`` and write the MCAP header and the given metadata records.

        Args:
            path: output file path.
            metadata: metadata records to write right away, ``{name: {key: value}}``.
            chunk_size: uncompressed bytes per chunk; bounds the loss on SIGKILL.
            compression: chunk compression, "zstd", "lz4" or "none".
            profile: MCAP profile; "ros2" for rosbag2 compatibility.
            flush_after_ns: also write the open chunk once it spans this much log time (from
                its first message to the one being written); bounds the loss on SIGKILL in
                log time. 0: by size only.
        """
        self.path = str(path)
        if compression not in _COMPRESSION:
            raise ValueError(f"compression must be one of {sorted(_COMPRESSION)}, "
                             f"got {compression!r}")
        if chunk_size <= 0:
            raise ValueError(f"chunk_size must be positive, got {chunk_size}")
        if flush_after_ns < 0:
            raise ValueError(f"flush_after_ns must be >= 0, got {flush_after_ns}")
        self._flush_after_ns = flush_after_ns
        self._chunk_start_ns: int | None = None  # log time of the open chunk's first message
        self._added = 0  # messages handed to mcap
        self._last_log_ns = 0  # log times never go back, on any channel nor in the file
        #: Messages in chunks handed to the OS: what a SIGKILL now would leave for recover().
        self.messages_in_file = 0
        records = {name: _check_str_map(f"metadata {name!r}", data)
                   for name, data in (metadata or {}).items()}
        self._channels: dict[str, _Channel] = {}
        self._schema_ids: dict[tuple[str, str, bytes], int] = {}
        self._closed = False
        try:
            self._file = open(self.path, "wb")
        except OSError as exc:
            raise BagError(f"cannot create bag file {self.path}: {exc.strerror or exc}") from exc
        self._stream = _CountingStream(self._file)
        try:
            self._mcap = McapWriter(self._stream, chunk_size=chunk_size,
                                    compression=_COMPRESSION[compression], enable_crcs=True)
        except McapError as exc:  # the compression library is not installed
            self._abort()
            raise BagError(f"cannot write bag file {self.path}: {exc}") from exc
        self._io("write the header", lambda: self._mcap.start(profile=profile, library=LIBRARY))
        for name, data in records.items():
            self.add_metadata(name, data)

    # -- registration -------------------------------------------------------

    def add_topic(self, topic: str, type_name: str, qos: str = DEFAULT_QOS_YAML) -> None:
        """Register ``topic`` with message type ``type_name`` (e.g. "std_msgs/msg/Float64").

        Writes the schema (encoding "ros2msg", the full message definition) and
        a CDR channel whose metadata holds ``offered_qos_profiles`` = ``qos``
        (see :func:`qos_profiles_yaml`) and, as rosbag2 Jazzy writes it, the
        type's ``topic_type_hash`` (RIHS01; left out for a type the package does
        not vendor).  Registering a topic again with the same type and QoS is a
        no-op.
        """
        metadata = {"offered_qos_profiles": qos}
        if type_hash(type_name):
            metadata["topic_type_hash"] = type_hash(type_name)
        self.add_channel(topic, _schema_name(type_name), message_definition(type_name), metadata)

    def add_channel(self, topic: str, schema_name: str, schema_data: str | bytes,
                    channel_metadata: Mapping[str, str] | None = None,
                    schema_encoding: str = SchemaEncoding.ROS2,
                    message_encoding: str = MessageEncoding.CDR) -> None:
        """Register ``topic`` with an explicit schema and channel metadata.

        Lower-level form of :meth:`add_topic` (used by ``recover()`` to copy
        channels verbatim).  An empty ``schema_name`` registers a schemaless
        channel.

        Raises:
            BagError: the topic is already registered differently, or I/O failed.
        """
        data = schema_data.encode() if isinstance(schema_data, str) else bytes(schema_data)
        meta = _check_str_map(f"channel metadata of {topic}", channel_metadata or {})
        wanted = _Channel(0, schema_name, schema_encoding, data, message_encoding, meta)
        existing = self._channels.get(topic)
        if existing is not None:
            wanted.channel_id = existing.channel_id
            if wanted != existing:
                raise BagError(f"{self.path}: topic {topic} is already registered "
                               f"with type {existing.schema_name} and other settings")
            return

        def register() -> None:
            schema_id = self._schema_id(schema_name, schema_encoding, data) if schema_name else 0
            wanted.channel_id = self._mcap.register_channel(
                topic=topic, message_encoding=message_encoding, schema_id=schema_id, metadata=meta)

        self._io(f"register topic {topic}", register)
        self._channels[topic] = wanted

    def _schema_id(self, name: str, encoding: str, data: bytes) -> int:
        """Id of the schema (name, encoding, data), registering it on first use."""
        key = (name, encoding, data)
        if key not in self._schema_ids:
            self._schema_ids[key] = self._mcap.register_schema(
                name=name, encoding=encoding, data=data)
        return self._schema_ids[key]

    # -- writing ------------------------------------------------------------

    def write(self, topic: str, message: Mapping[str, Any], log_time_ns: int,
              publish_time_ns: int | None = None, sequence: int = 0) -> None:
        """Serialize a plain-Python message (nested dicts/lists) to CDR and write it.

        Missing fields are written with their defaults (zero / empty unless
        the definition says otherwise), as mcap_ros2 does; see :mod:`.cdr`.

        Raises:
            BagError: unknown topic, message not serializable with the topic's
                type (names the field; the writer stays usable), or I/O failure.
        """
        channel = self._channel(topic)
        try:
            data = self._encoder(channel)(message)
        except BagError:
            raise
        except EncodeError as exc:
            raise BagError(f"{self.path}: cannot serialize message for {topic}: {exc}") from exc
        self.write_raw(topic, data, log_time_ns, publish_time_ns, sequence)

    def write_raw(self, topic: str, data: bytes, log_time_ns: int,
                  publish_time_ns: int | None = None, sequence: int = 0) -> None:
        """Write an already serialized message (e.g. from ``rclpy.serialization``).

        Args:
            topic: a registered topic.
            data: the serialized message (CDR for ROS 2 topics).
            log_time_ns: receive/log time in nanoseconds (>= 0, and >= that of every message
                written before: what ``mcap doctor --strict-message-order`` asks).
            publish_time_ns: publish time in nanoseconds; defaults to ``log_time_ns``.
            sequence: optional publisher sequence number.
        """
        channel = self._channel(topic)
        publish_time_ns = log_time_ns if publish_time_ns is None else publish_time_ns
        for name, value, limit in (("log_time_ns", log_time_ns, 2**64),
                                   ("publish_time_ns", publish_time_ns, 2**64),
                                   ("sequence", sequence, 2**32)):
            if not isinstance(value, int) or not 0 <= value < limit:
                raise BagError(f"{self.path}: {name} for {topic} must be an int in [0, {limit}), "
                               f"got {value!r}")
        if log_time_ns < self._last_log_ns:
            raise BagError(f"{self.path}: log time {log_time_ns} ns of a message on {topic} must be >= "
                           f"{self._last_log_ns} ns, the latest written (log times never go back in a bag)")
        self._last_log_ns = log_time_ns
        writes = self._stream.writes
        self._io(f"write a message on {topic}", lambda: self._mcap.add_message(
            channel_id=channel.channel_id, log_time=log_time_ns, data=bytes(data),
            publish_time=publish_time_ns, sequence=sequence))
        self._added += 1
        if self._stream.writes != writes:  # the message filled the chunk: mcap wrote it
            self._chunk_written()
        elif self._chunk_start_ns is None:
            self._chunk_start_ns = log_time_ns
        elif self._flush_after_ns and log_time_ns - self._chunk_start_ns >= self._flush_after_ns:
            self.flush()

    def _chunk_written(self) -> None:
        """Every message added so far is in the file; the next one opens a chunk."""
        self.messages_in_file = self._added
        self._chunk_start_ns = None

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Write a metadata record ``name`` with string key/value pairs."""
        if not isinstance(name, str):
            raise BagError(f"metadata name must be str, got {name!r}")
        checked = _check_str_map(f"metadata {name!r}", data)
        self._io(f"write metadata {name!r}", lambda: self._mcap.add_metadata(name, checked))

    def flush(self) -> None:
        """Close the open chunk (if it holds messages) and hand it to the OS."""
        self._io("flush", self._mcap.flush)
        self._chunk_written()

    def close(self) -> None:
        """Write the summary section and footer, and close the file.

        Idempotent.  Raises :class:`BagError` at most once; the writer is
        closed afterwards in every case.
        """
        if self._closed:
            return
        self._closed = True
        try:
            self._mcap.finish()
            self._file.close()
            self.messages_in_file = self._added
        except OSError as exc:
            self._abort()
            raise BagError(f"cannot finish bag file {self.path}: {exc.strerror or exc}") from exc

    @property
    def closed(self) -> bool:
        """True once the writer is closed (explicitly or after an I/O failure)."""
        return self._closed

    def __enter__(self) -> "BagWriter":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    # -- helpers ------------------------------------------------------------

    def _channel(self, topic: str) -> _Channel:
        if self._closed:
            raise BagError(f"{self.path}: bag writer is closed")
        try:
            return self._channels[topic]
        except KeyError:
            raise BagError(f"{self.path}: topic {topic} is not registered "
                           "(call add_topic first)") from None

    def _encoder(self, channel: _Channel) -> Callable[[Any], bytes]:
        """CDR encoder for the channel's ros2msg schema (built once, on first use)."""
        if channel.encoder is None:
            if (channel.schema_encoding != SchemaEncoding.ROS2
                    or channel.message_encoding != MessageEncoding.CDR):
                raise BagError(f"{self.path}: cannot encode dict messages for schema encoding "
                               f"{channel.schema_encoding!r} / {channel.message_encoding!r}")
            try:
                channel.encoder = MessageEncoder(channel.schema_name, channel.schema_data.decode()).encode
            except EncodeError as exc:
                raise BagError(f"{self.path}: cannot encode for schema {channel.schema_name}: {exc}") from exc
        return channel.encoder

    def _io(self, action: str, operation: Callable[[], Any]) -> None:
        """Run a write operation, push the written bytes to the OS, map OSError to BagError."""
        if self._closed:
            raise BagError(f"{self.path}: bag writer is closed")
        try:
            operation()
            self._file.flush()
        except OSError as exc:
            self._abort()
            raise BagError(f"cannot {action} in bag file {self.path}: "
                           f"{exc.strerror or exc}; the writer is closed") from exc

    def _abort(self) -> None:
        """Close the file after a failure without raising; the writer becomes closed."""
        self._closed = True
        try:
            self._file.close()
        except OSError:
            pass  # the original error has been (or is being) reported


class _CountingStream:
    """The file as mcap's writer sees it, counting its writes: mcap writes to the file only
    when a record is complete, so a write during ``add_message`` means a chunk went out."""

    def __init__(self, file):
        self._file = file
        self.writes = 0

    def write(self, data) -> int:
        self.writes += 1
        return self._file.write(data)

    def tell(self) -> int:
        return self._file.tell()

    def flush(self) -> None:
        self._file.flush()

    def close(self) -> None:
        self._file.close()


# -- message builders (plain dicts for BagWriter.write) ------------------------

def stamp(t_seconds: float) -> dict[str, int]:
    """builtin_interfaces/Time for ``t_seconds`` (nanosec always in [0, 1e9))."""
    sec, nanosec = stamp_parts(t_seconds)
    return {"sec": sec, "nanosec": nanosec}


def stamp_parts(t_seconds: float) -> tuple[int, int]:
    """(sec, nanosec) of ``t_seconds``, rounded to the nanosecond (nanosec in [0, 1e9))."""
    return divmod(round(t_seconds * 1e9), 10**9)


def header(t_seconds: float, frame_id: str) -> dict[str, Any]:
    """std_msgs/Header with stamp ``t_seconds`` and ``frame_id``."""
    return {"stamp": stamp(t_seconds), "frame_id": frame_id}


def float64(x: float) -> dict[str, float]:
    """std_msgs/Float64."""
    return {"data": float(x)}


def yaw_quaternion(yaw: float) -> dict[str, float]:
    """geometry_msgs/Quaternion of a rotation by ``yaw`` radians about z."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2.0), "w": math.cos(yaw / 2.0)}


def pose_array(t_seconds: float, frame_id: str,
               points_xy_heading: Sequence[Sequence[float]]) -> dict[str, Any]:
    """geometry_msgs/PoseArray from ``(x, y, heading)`` triples (z = 0)."""
    poses = [{"position": {"x": float(x), "y": float(y), "z": 0.0},
              "orientation": yaw_quaternion(float(heading))}
             for x, y, heading in points_xy_heading]
    return {"header": header(t_seconds, frame_id), "poses": poses}


def joint_state(t_seconds: float, names: Sequence[str], positions: Sequence[float],
                velocities: Sequence[float], frame_id: str = "",
                efforts: Sequence[float] = ()) -> dict[str, Any]:
    """sensor_msgs/JointState with positions, velocities and (optionally) efforts.

    Raises:
        ValueError: the sequences differ in length.
    """
    if not len(names) == len(positions) == len(velocities) or len(efforts) not in (0, len(names)):
        raise ValueError(f"joint_state: {len(names)} names, {len(positions)} positions, "
                         f"{len(velocities)} velocities, {len(efforts)} efforts")
    return {"header": header(t_seconds, frame_id),
            "name": [str(n) for n in names],
            "position": [float(p) for p in positions],
            "velocity": [float(v) for v in velocities],
            "effort": [float(e) for e in efforts]}


def clock(t_seconds: float) -> dict[str, Any]:
    """rosgraph_msgs/Clock."""
    return {"clock": stamp(t_seconds)}
