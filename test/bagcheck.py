"""Reading a bag's records in file order (mcap's stream reader sorts nothing): the log-time
order check of every bag the project writes (test_log_order.py, test_node.py)."""
from __future__ import annotations

from pathlib import Path

from mcap.records import Message
from mcap.stream_reader import StreamReader


def log_times(path: Path) -> list[tuple[int, int]]:
    """(channel id, log time) of every message, in file order."""
    with open(path, "rb") as f:
        return [(r.channel_id, r.log_time) for r in StreamReader(f).records if isinstance(r, Message)]


def assert_never_back(path: Path) -> int:
    """Assert the file's log times never go back (in the file, so on no channel either);
    returns how many messages it holds."""
    times = log_times(path)
    assert times, f"{path} holds no message"
    backs = [(i, a, b) for i, ((_, a), (_, b)) in enumerate(zip(times, times[1:])) if b < a]
    assert not backs, f"{path}: {len(backs)} log times go back, the first at message {backs[0][0] + 1}"
    return len(times)
