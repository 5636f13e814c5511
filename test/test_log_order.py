"""Log times never go back, in every bag the project writes: on each channel and across the file,
in the order the records stand in the file (what ``mcap doctor --strict-message-order`` checks;
the Go ``mcap`` CLI is not on PyPI or in Debian, so the check is done here, record by record,
with mcap's stream reader, which reads the file in file order and sorts nothing).

Writers: ``mta run`` (offline), the node's session (commands between ticks, the watchdog, pause,
diagnostics, a reset: two bags), ``recover``. BagWriter itself refuses a message stamped before
the latest one, so a writer that breaks the order fails loudly instead of writing it.
"""
from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import pytest
from bagcheck import assert_never_back, log_times

from mta_sim_ros import cli
from mta_sim_ros.bag import BagError, BagWriter, float64, recover
from mta_sim_ros.node.params import PARAMS
from mta_sim_ros.node.run_session import RunSession

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_the_offline_run_writes_each_tick_s_commands_before_its_outputs(tmp_path):
    bag = tmp_path / "run.mcap"
    done = subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", "run", "--scene", "scenes/lane_change.yaml",
                           "--bag", str(bag)], capture_output=True, text=True, cwd=REPO)
    assert done.returncode == 0, done.stderr
    assert assert_never_back(bag) > 1000


class Clock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


class Log:
    def info(self, line):
        pass

    warning = error = info


def test_the_node_s_session_bags_keep_the_order_through_commands_pause_and_reset(tmp_path):
    cfg = {p.name: p.default for p in PARAMS}
    cfg.update(bag_dir=str(tmp_path / "bags"), publish_rate=50.0, watchdog_timeout=0.5, watchdog_action="straight")
    clock = Clock()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        s = RunSession(cfg, clock=clock, publish=lambda msgs: None, log=Log(), background=False,
                       compute_clock=clock, cpu_clock=clock)
    for i in range(300):
        clock.t += 0.02
        if i % 3 == 0 and i < 100:  # commands between ticks, then none: the watchdog takes over
            s.command("steering_angle", 0.1)
            s.command("speed_setpoint", 2.0)
        if i == 150:
            s.pause(True)
        if i == 170:
            s.pause(False)
        if i % 50 == 0:
            s.publish_diagnostics()
        s.fire()
        if i == 200:
            s.reset()
    s.close()
    bags = sorted((tmp_path / "bags").glob("*.mcap"))
    assert len(bags) == 2
    for bag in bags:
        assert_never_back(bag)


def test_a_recovered_bag_keeps_the_order(tmp_path):
    crashed = tmp_path / "crashed.mcap"
    with BagWriter(crashed, chunk_size=1024) as bag:
        bag.add_topic("/a", "std_msgs/msg/Float64")
        bag.add_topic("/b", "std_msgs/msg/Float64")
        for i in range(600):
            bag.write("/a" if i % 2 else "/b", float64(float(i)), log_time_ns=(i // 2) * 10**7)
    data = crashed.read_bytes()
    crashed.write_bytes(data[:len(data) * 2 // 3])
    report = recover(crashed, tmp_path / "recovered.mcap")
    assert assert_never_back(tmp_path / "recovered.mcap") == report["total_messages"] > 100


def test_the_writer_refuses_a_message_stamped_before_the_latest(tmp_path):
    with BagWriter(tmp_path / "x.mcap") as bag:
        bag.add_topic("/a", "std_msgs/msg/Float64")
        bag.add_topic("/b", "std_msgs/msg/Float64")
        bag.write("/a", float64(1.0), log_time_ns=2000)
        bag.write("/b", float64(1.0), log_time_ns=2000)  # the same time: kept
        with pytest.raises(BagError, match=r"log time 1999 ns of a message on /a must be >= 2000 ns"):
            bag.write("/a", float64(2.0), log_time_ns=1999)
        bag.write("/a", float64(3.0), log_time_ns=3000)  # the writer goes on
    assert [t for _, t in log_times(tmp_path / "x.mcap")] == [2000, 2000, 3000]


def test_recovering_a_bag_whose_log_times_go_back_drops_those_messages_only(tmp_path, capsys):
    """A bag no writer of the project made (raw mcap: MCAP allows log times in any order):
    recover copies in file order, drops each message whose log time goes back, says how many, and
    recovers the rest (once it refused the whole bag: one message lost everything)."""
    from mcap.writer import Writer

    crafted = tmp_path / "crafted.mcap"
    with open(crafted, "wb") as f:
        w = Writer(f)
        w.start(profile="ros2")
        schema = w.register_schema("std_msgs/msg/Float64", "ros2msg", b"float64 data")
        channel = w.register_channel("/a", "cdr", schema)
        for t in (10, 20, 5, 25, 15, 40):
            w.add_message(channel, log_time=t, data=b"\x00\x01\x00\x00" + bytes(8), publish_time=t)
        w.finish()
    code = cli.main(["recover", str(crafted), "-o", str(tmp_path / "out.mcap")])
    out = capsys.readouterr().out
    assert code == 0 and "4 messages in" in out and "2 messages (2 whose log time went back)" in out, out
    assert [t for _, t in log_times(tmp_path / "out.mcap")] == [10, 20, 25, 40]
