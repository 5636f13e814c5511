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
import resource
import stat
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from dds import ros_env
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


# -- what a bag claims ---------------------------------------------------------------------------

#: the address space the recovering process gets: far less than the records below claim
ADDRESS_SPACE = 2 << 30


def record(opcode: int, body: bytes) -> bytes:
    """One MCAP record: opcode, u64 length, body."""
    return bytes([opcode]) + struct.pack("<Q", len(body)) + body


def claimed(folder: Path, tail: bytes) -> Path:
    """A bag's header, then the crafted ``tail`` (what a damaged or hostile file holds)."""
    path = folder / "claims.mcap"
    with BagWriter(path) as bag:
        bag.add_topic("/traction_power", "std_msgs/msg/Float64")
    data = path.read_bytes()
    header_end = 8 + 9 + struct.unpack("<Q", data[9:17])[0]  # magic, then the Header record
    path.write_bytes(data[:header_end] + tail)
    return path


def recover_limited(folder: Path, bag: Path) -> subprocess.CompletedProcess:
    """``mta recover`` under an address-space limit of ADDRESS_SPACE."""
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))

    return subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", "recover", bag.name, "-o", "out.mcap"],
                          cwd=folder, capture_output=True, text=True, timeout=120, env=ros_env(), preexec_fn=limit)


def test_a_record_claiming_more_than_the_file_has_is_a_cut_tail_not_an_allocation(tmp_path):
    """A message record whose length field says 3 GB, 100 bytes after it: the tail is dropped
    (the scan stops there), nothing is allocated for it, exit 0."""
    tail = bytes([0x05]) + struct.pack("<Q", 3_000_000_000) + bytes(100)
    bag = claimed(tmp_path, tail)
    done = recover_limited(tmp_path, bag)
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr[-2000:]
    assert done.stdout.endswith(f"0 messages in 0 chunks recovered; dropped 0 chunks, 0 messages, {len(tail)} bytes\n")
    assert list(read_messages(str(tmp_path / "out.mcap"))) == []


def test_a_chunk_claiming_gigabytes_uncompressed_is_dropped_and_the_next_one_recovered(tmp_path):
    """A chunk (its record complete) that says it holds 1.5 GiB: counted as dropped (reader.py
    does not even try to decompress it: MAX_CHUNK_BYTES), and the scan goes on: the complete
    chunk after it is recovered."""
    good = tmp_path / "good.mcap"
    with BagWriter(good) as bag:
        bag.add_topic("/traction_power", "std_msgs/msg/Float64")
        bag.write("/traction_power", float64(1.0), log_time_ns=10)
    chunks = [r for _, r in records_of(good.read_bytes()) if r[0] == 0x06]
    lie = (struct.pack("<QQQI", 0, 10, 3 << 29, 0) + struct.pack("<I", 4) + b"zstd"
           + struct.pack("<Q", 64) + bytes(64))
    bag = claimed(tmp_path, record(0x06, lie) + b"".join(r for _, r in records_of(good.read_bytes())
                                                          if r[0] not in (0x01,)))
    done = recover_limited(tmp_path, bag)
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr[-2000:]
    assert f"1 messages in {len(chunks)} chunks recovered; dropped 1 chunks" in done.stdout, done.stdout
    assert [t for _, t, _ in read_messages(str(tmp_path / "out.mcap"))] == [10]


def records_of(data: bytes):
    """(offset, the whole record) of each record of an MCAP file's data, up to the footer."""
    at = 8
    while at + 9 <= len(data) - 8:
        length = struct.unpack("<Q", data[at + 1:at + 9])[0]
        yield at, data[at:at + 9 + length]
        at += 9 + length


def chunk_record(records: bytes, compression: str, claim: int, start: int = 0, end: int = 0) -> bytes:
    """A chunk record (opcode 0x06) holding ``records`` compressed as given, claiming ``claim``
    bytes uncompressed, CRC 0 (not computed: MCAP's readers then take the data as it is)."""
    return record(0x06, struct.pack("<QQQI", start, end, claim, 0) + struct.pack("<I", len(compression))
                  + compression.encode() + struct.pack("<Q", len(records)) + records)


def test_decompression_bombs_are_dropped_unparsed(tmp_path):
    """Chunks whose data is 64 MiB of zeros: zstd claiming all of it (a ratio of ~20 000: over
    MAX_CHUNK_RATIO) and lz4 claiming 100 bytes (mcap's reader ignores lz4's claim). mcap alone
    would unpack both and take them for chunks of unknown records; each is dropped undecompressed
    or cut at its claim, and the good chunk after them recovered."""
    import lz4.frame
    import zstandard

    zeros = bytes(64 << 20)
    bombs = (chunk_record(zstandard.ZstdCompressor().compress(zeros), "zstd", len(zeros))
             + chunk_record(lz4.frame.compress(zeros), "lz4", 100))
    good = tmp_path / "good.mcap"
    with BagWriter(good) as bag:
        bag.add_topic("/traction_power", "std_msgs/msg/Float64")
        bag.write("/traction_power", float64(1.0), log_time_ns=10)
    rest = b"".join(r for _, r in records_of(good.read_bytes()) if r[0] != 0x01)
    bag = claimed(tmp_path, bombs + rest)
    done = recover_limited(tmp_path, bag)
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr[-2000:]
    assert "1 messages in 1 chunks recovered; dropped 2 chunks" in done.stdout, done.stdout


def test_a_fifo_or_device_as_output_is_refused_and_left_as_it_is(tmp_path):
    bag = crashed_bag(tmp_path)
    os.mkfifo(tmp_path / "fifo")
    code, out, err = run_recover(tmp_path, bag.name, "-o", "fifo")
    assert code == 2 and err == "mta recover: fifo is not a regular file (a device, a FIFO or a socket): name a " \
                                "file to write\n", err
    assert stat.S_ISFIFO(os.stat(tmp_path / "fifo").st_mode)
