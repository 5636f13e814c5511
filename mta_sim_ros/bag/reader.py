"""Reading MCAP bags written by :class:`~mta_sim_ros.bag.writer.BagWriter`, and crash recovery.

Pure Python (``mcap`` + ``mcap_ros2``), no rclpy.  ``read_messages``,
``read_metadata`` and ``summary`` need a complete file (with summary and
footer); a file left behind by a killed writer must go through
:func:`recover` first.
"""

import os
import stat
import struct
import tempfile
from collections import Counter
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field, replace
from typing import Any, BinaryIO, Iterable, Iterator

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, DataEnd, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap_ros2.decoder import DecoderFactory

from ..validate import one_line, stream_kind
from .schemas import BagError
from .writer import DEFAULT_CHUNK_SIZE, BagWriter

PathLike = str | os.PathLike


@contextmanager
def _mcap_reader(path: PathLike, decode: bool = False):
    """Open ``path`` with mcap's seeking reader; errors become BagError naming the file."""
    path = str(path)
    if stream_kind(path):
        raise BagError(f"cannot open bag file {path}: {stream_kind(path)}, not an MCAP file")
    try:
        f = open(path, "rb")
    except OSError as exc:
        raise BagError(f"cannot open bag file {path}: {exc.strerror or exc}") from exc
    with f:
        try:  # every chunk's CRC checked: a flipped bit is refused, not read as a number
            yield make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()] if decode else ())
        except BagError:
            raise
        except Exception as exc:  # McapError, struct.error, ... on damaged files
            what = one_line(f"{type(exc).__name__}: {exc}")
            raise BagError(f"cannot read bag file {path}: {what[:200]}{'...' if len(what) > 200 else ''}; "
                           f"if it was cut short or damaged, `mta recover {path} -o OUT.mcap` rebuilds what is "
                           "intact") from exc


def read_messages(path: PathLike,
                  topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, Any]]:
    """Yield ``(topic, log_time_ns, message)`` in log-time order.

    Messages are decoded with mcap_ros2 into attribute objects
    (``msg.header.stamp.sec``, ``msg.poses[0].position.x``, ...).

    Args:
        path: MCAP file.
        topics: only these topics (all when None).
    """
    with _mcap_reader(path, decode=True) as reader:
        for _, channel, message, decoded in reader.iter_decoded_messages(topics=topics):
            yield channel.topic, message.log_time, decoded


def read_metadata(path: PathLike) -> dict[str, dict[str, str]]:
    """All metadata records as ``{name: {key: value}}``."""
    with _mcap_reader(path) as reader:
        return {record.name: dict(record.metadata) for record in reader.iter_metadata()}


def summary(path: PathLike) -> dict[str, dict[str, Any]]:
    """Per topic: ``{"type": "pkg/msg/Name", "count": n_messages}`` from the summary section."""
    with _mcap_reader(path) as reader:
        info = reader.get_summary()
        if info is None or info.statistics is None:
            raise BagError(f"bag file {path} has no summary statistics")
        result: dict[str, dict[str, Any]] = {}
        for channel_id, channel in info.channels.items():
            schema = info.schemas.get(channel.schema_id)
            entry = result.setdefault(channel.topic, {"type": schema.name if schema else "",
                                                      "count": 0})
            entry["count"] += info.statistics.channel_message_counts.get(channel_id, 0)
        return result


# -- recovery ------------------------------------------------------------------

#: A chunk claiming more uncompressed bytes than this is dropped as damaged (the writers' chunks
#: are ~1 MiB: BagWriter's DEFAULT_CHUNK_SIZE, rosbag2's 768 KiB), not decompressed.
MAX_CHUNK_BYTES = 1 << 30
#: ... and one claiming more than this many times its compressed size (the node's bags: ~6; a
#: chunk of zeros, a decompression bomb: ~20 000): parsing a gigabyte of tiny records out of a
#: few kilobytes would take minutes of CPU for nothing.
MAX_CHUNK_RATIO = 1000


def _chunk_data(chunk: Chunk) -> bytes | None:
    """The chunk's records decompressed, never more than it claims (mcap's own lz4 path ignores
    the claim); None when they are not exactly what it claims, or it claims too much
    (MAX_CHUNK_BYTES, MAX_CHUNK_RATIO), or its compression is unknown."""
    claim = chunk.uncompressed_size
    if claim > MAX_CHUNK_BYTES or claim > MAX_CHUNK_RATIO * max(len(chunk.data), 1):
        return None
    if chunk.compression == "":
        data = bytes(chunk.data)
    elif chunk.compression == "zstd":
        import zstandard

        parts, total = [], 0
        with zstandard.ZstdDecompressor().stream_reader(bytes(chunk.data)) as reader:
            while total <= claim:
                part = reader.read(claim + 1 - total)
                if not part:
                    break
                parts.append(part)
                total += len(part)
        data = b"".join(parts)
    elif chunk.compression == "lz4":
        import lz4.frame

        data = lz4.frame.LZ4FrameDecompressor().decompress(bytes(chunk.data), max_length=claim + 1)
    else:
        return None
    return data if len(data) == claim else None


class _TruncatedTail(Exception):
    """The source file ends inside a record."""


class _ExactReader:
    """Read-only file wrapper whose reads return exactly the bytes asked for.

    mcap's StreamReader trusts short reads; with this wrapper a record cut by
    the end of the file raises ``_TruncatedTail`` instead of being parsed from
    partial data.  ``offset`` is the number of bytes consumed so far.  A read
    longer than what is left of the file is refused before anything is read:
    a record claiming more bytes than the file has (a damaged length field, a
    crafted file) must not make Python allocate what it claims.
    """

    def __init__(self, f: BinaryIO):
        self._f = f
        self.offset = 0
        self.size = os.fstat(f.fileno()).st_size

    def read(self, size: int) -> bytes:
        if size > self.size - self.offset:
            raise _TruncatedTail()
        data = self._f.read(size)
        if len(data) < size:
            raise _TruncatedTail()
        self.offset += size
        return data


@dataclass
class _Copier:
    """Copies the data records of a source file into a BagWriter."""

    out: BagWriter
    schemas: dict[int, Schema] = field(default_factory=dict)
    topics: dict[int, str] = field(default_factory=dict)
    messages: Counter = field(default_factory=Counter)
    messages_dropped: int = 0
    messages_out_of_order: int = 0  # log time before one already copied: a bag's log times never go back
    last_log_time: int | None = None  # ns, the latest log time copied
    chunks: int = 0
    chunks_dropped: int = 0

    def copy(self, record: Any) -> None:
        """Copy one top-level record (chunks are unpacked)."""
        if isinstance(record, Chunk):
            self._copy_chunk(record)
        elif isinstance(record, Schema):
            self.schemas[record.id] = record
        elif isinstance(record, Channel):
            self._copy_channel(record)
        elif isinstance(record, Message):
            self._copy_message(record)
        elif isinstance(record, Metadata):
            self.out.add_metadata(record.name, record.metadata)
        # Other records (indexes, statistics, attachments) are not copied;
        # BagWriter rebuilds the indexes and statistics.

    def _copy_chunk(self, chunk: Chunk) -> None:
        try:
            data = _chunk_data(chunk)
            records = None if data is None else breakup_chunk(replace(chunk, compression="", data=data),
                                                              validate_crc=True)
        except Exception:  # bad CRC or undecompressable data: skip this chunk
            records = None
        if records is None:
            self.chunks_dropped += 1
            return
        self.chunks += 1
        for record in records:
            self.copy(record)

    def _copy_channel(self, channel: Channel) -> None:
        schema = self.schemas.get(channel.schema_id)
        if channel.schema_id != 0 and schema is None:
            return  # schema lost: the channel's messages are counted as dropped
        self.out.add_channel(channel.topic, schema.name if schema else "",
                             schema.data if schema else b"", channel.metadata,
                             schema.encoding if schema else "", channel.message_encoding)
        self.topics[channel.id] = channel.topic

    def _copy_message(self, message: Message) -> None:
        topic = self.topics.get(message.channel_id)
        if topic is None:
            self.messages_dropped += 1
            return
        if self.last_log_time is not None and message.log_time < self.last_log_time:
            self.messages_out_of_order += 1  # MCAP allows it, BagWriter's bags do not: dropped, counted
            return
        self.out.write_raw(topic, message.data, message.log_time, message.publish_time,
                           message.sequence)
        self.messages[topic] += 1
        self.last_log_time = max(message.log_time, self.last_log_time or 0)


def holds_a_message(path: PathLike) -> bool:
    """Whether the file at ``path``, complete or cut short, holds a message :func:`recover`
    would copy: one on a channel it copies (its schema known), loose or in a complete, valid
    chunk, read from the start up to the first such message (so a long bag costs one chunk).
    False for a file that cannot be read."""
    seen = _Seen()
    try:
        with open(path, "rb") as f:
            for record in StreamReader(_ExactReader(f), emit_chunks=True).records:
                if isinstance(record, DataEnd):
                    return False
                if seen.holds_a_message(_chunk_records(record) if isinstance(record, Chunk) else (record,)):
                    return True
    except (OSError, _TruncatedTail, McapError, ValueError, struct.error):
        return False
    return False


@dataclass
class _Seen:
    """The schemas and channels read so far, as recover() keeps them."""

    schemas: set = field(default_factory=set)
    channels: set = field(default_factory=set)

    def holds_a_message(self, records) -> bool:
        """Take ``records`` in order; whether one is a message recover() would copy."""
        for record in records:
            if isinstance(record, Schema):
                self.schemas.add(record.id)
            elif isinstance(record, Channel) and (record.schema_id == 0 or record.schema_id in self.schemas):
                self.channels.add(record.id)
            elif isinstance(record, Message) and record.channel_id in self.channels:
                return True
        return False


def _chunk_records(chunk: Chunk) -> list:
    """The records of ``chunk`` if recover() copies it (its data valid), else none."""
    try:
        data = _chunk_data(chunk)
        return [] if data is None else list(breakup_chunk(replace(chunk, compression="", data=data), validate_crc=True))
    except Exception:  # noqa: BLE001 - bad CRC or undecompressable data: recover skips it too
        return []


class PathRefused(BagError):
    """:func:`recover` refused its paths before reading or writing anything."""


def output_target(src: PathLike, dst: PathLike) -> str:
    """The file :func:`recover` writes for ``dst``: ``dst`` with its symlinks followed.

    Refused (:class:`PathRefused`, one line): ``src`` missing or not a regular file; ``dst``
    that is ``src`` however the path reaches it (a symlink, a hard link, a path through ``..``,
    the same path: same device and inode); ``dst`` a directory, a device, a FIFO or a socket;
    ``dst``'s folder missing. The
    comparison is by device and inode, not by name, because every one of those names is the
    one copy of a crashed bag.
    """
    src, dst = str(src), str(dst)
    try:
        src_stat = os.stat(src)
    except OSError as exc:
        raise PathRefused(f"cannot open bag file {src}: {exc.strerror or exc}") from exc
    if not stat.S_ISREG(src_stat.st_mode):
        raise PathRefused(f"{src} is not a file")
    target = os.path.realpath(dst)
    try:
        dst_stat = os.stat(target)
    except FileNotFoundError:
        folder = os.path.dirname(target)
        if not os.path.isdir(folder):
            raise PathRefused(f"cannot write {dst}: folder {os.path.dirname(dst) or '.'} does not exist") from None
        return target
    except OSError as exc:
        raise PathRefused(f"cannot write {dst}: {exc.strerror or exc}") from exc
    if os.path.samestat(src_stat, dst_stat):
        raise PathRefused(f"{dst} is {src} itself (the same file): refusing to write over the only copy of the bag")
    if stat.S_ISDIR(dst_stat.st_mode):
        raise PathRefused(f"{dst} is a directory: name the file to write")
    if not stat.S_ISREG(dst_stat.st_mode):  # renaming over it would replace a device or a FIFO
        raise PathRefused(f"{dst} is not a regular file (a device, a FIFO or a socket): name a file to write")
    return target


def recover(src: PathLike, dst: PathLike, chunk_size: int = DEFAULT_CHUNK_SIZE) -> dict[str, Any]:
    """Rebuild a complete, indexed MCAP file ``dst`` from a damaged or truncated ``src``.

    ``src`` is read record by record from the start; a record cut by the end
    of the file (e.g. a writer killed with SIGKILL mid-chunk) ends the scan.
    The profile, schemas, channels (with their metadata), metadata records and
    every message of every complete chunk (and every complete loose message)
    are written with :class:`BagWriter`, in the original order.
    A chunk failing its CRC or decompression, or claiming more than MAX_CHUNK_BYTES or
    MAX_CHUNK_RATIO times its size, is skipped; a message whose log time is before one already
    copied is dropped (counted: MCAP allows it, this package's bags do not).  Attachments are
    not copied.

    ``src`` is never written: :func:`output_target` refuses a ``dst`` that reaches it, and the
    new file is written under a temporary name in ``dst``'s folder and renamed over ``dst`` only
    once complete, so a failure (a full disk, a damaged ``src``) leaves ``dst`` as it was.

    Returns:
        ``{"messages": {topic: n}, "total_messages": n, "chunks": n_chunks_copied,
        "chunks_dropped": n, "messages_dropped": n_without_channel_or_out_of_order,
        "messages_out_of_order": n_whose_log_time_went_back,
        "bytes_dropped": n_unparsed_tail_bytes, "complete": src_had_a_data_end_record,
        "last_log_time_ns": latest_log_time_recovered_or_None}``

    Raises:
        PathRefused: see :func:`output_target`.
        BagError: ``src`` is unreadable or not an MCAP file, ``dst`` is not
            writable, or ``src`` has one topic on channels of different types.
    """
    src = str(src)
    target = output_target(src, dst)
    try:
        f = open(src, "rb")
    except OSError as exc:
        raise BagError(f"cannot open bag file {src}: {exc.strerror or exc}") from exc
    try:
        with f, _replacing(target) as partial:
            stream = _ExactReader(f)
            size = stream.size
            records = StreamReader(stream, emit_chunks=True).records
            profile = _read_profile(src, records)
            try:
                with BagWriter(partial, chunk_size=chunk_size, profile=profile) as out:
                    copier = _Copier(out)
                    good_end, complete = _copy_records(records, stream, copier)
            except BagError as err:  # the writer names its file: the temporary one, which is gone
                raise BagError(f"cannot recover {src}: {str(err).replace(partial, target)}") from None
    except MemoryError:  # one record of the file larger than the memory this process may have
        raise BagError(f"cannot recover {src}: a record of it does not fit in this process's memory") from None
    return {
        "messages": dict(copier.messages),
        "total_messages": sum(copier.messages.values()),
        "chunks": copier.chunks,
        "chunks_dropped": copier.chunks_dropped,
        "messages_dropped": copier.messages_dropped + copier.messages_out_of_order,
        "messages_out_of_order": copier.messages_out_of_order,
        "bytes_dropped": 0 if complete else size - good_end,
        "complete": complete,
        "last_log_time_ns": copier.last_log_time,
    }


@contextmanager
def _replacing(target: str):
    """A temporary path beside ``target``, renamed over it when the block ends without an
    exception, removed otherwise. The new file keeps ``target``'s mode if it existed."""
    folder, name = os.path.split(target)
    try:
        fd, partial = tempfile.mkstemp(prefix=f".{name}.", suffix=".part", dir=folder)
    except OSError as exc:
        raise BagError(f"cannot write in {folder}: {exc.strerror or exc}") from exc
    os.close(fd)
    try:
        yield partial
        try:
            mode = stat.S_IMODE(os.stat(target).st_mode)
        except FileNotFoundError:
            mode = 0o644
        os.chmod(partial, mode)
        os.replace(partial, target)
    except BaseException:
        with suppress(FileNotFoundError):
            os.unlink(partial)
        raise


def _read_profile(src: str, records: Iterator[Any]) -> str:
    """Profile of the Header record that must open every MCAP file."""
    try:
        header = next(records)
    except (_TruncatedTail, McapError, StopIteration) as exc:
        raise BagError(f"cannot recover {src}: not an MCAP file or no complete header") from exc
    if not isinstance(header, Header):
        raise BagError(f"cannot recover {src}: first record is "
                       f"{type(header).__name__}, not Header")
    return header.profile


def _copy_records(records: Iterator[Any], stream: _ExactReader,
                  copier: _Copier) -> tuple[int, bool]:
    """Copy records until DataEnd or the damaged tail.

    Returns the offset just after the last complete record and whether the
    DataEnd record (end of the data section) was reached.
    """
    good_end = stream.offset
    while True:
        try:
            record = next(records)
        except StopIteration:
            return good_end, False
        except (_TruncatedTail, McapError, ValueError, struct.error):
            return good_end, False  # the tail cannot be parsed: keep what was read so far
        if isinstance(record, DataEnd):
            return stream.offset, True
        copier.copy(record)
        good_end = stream.offset
