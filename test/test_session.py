"""The node's policy, in process (mta_sim_ros.node.run_session.RunSession): no DDS, no sleeping.

Time is set, not waited for: the session's steady clock (and the clock that times each tick's
work) is a FakeClock the test moves. The encoders are the node's own (messages.Encoders, the
session's default), so the bags written here are real; they are read back with rclpy's decoder.
"""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from visualization_msgs.msg import MarkerArray

from mta_sim_ros.analysis import resimulate
from mta_sim_ros.bag import BagError, read_messages, read_metadata
from mta_sim_ros.node.pacing import CATCH_UP, MAX_TIMER_PERIOD
from mta_sim_ros.node.params import PARAMS, ConfigError
from mta_sim_ros.node.run_session import RunSession
from mta_sim_ros.node.status import ERROR, OK, WARN
from mta_sim_ros.physics.loader import load_scene

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "config" / "scenes" / "headland_turn.yaml"
RATE = 50.0
TICK = 1.0 / RATE


class FakeClock:
    """Steady wall seconds that move only when the test says so."""

    def __init__(self, t: float = 1000.0):
        self.t = t  # set it, or advance it

    def __call__(self) -> float:
        return self.t

    def advance(self, dt: float) -> None:
        self.t += dt


class Log:
    """The session's log: (level, line) in order."""

    def __init__(self):
        self.lines: list[tuple[str, str]] = []

    def info(self, line):
        self.lines.append(("info", line))

    def warning(self, line):
        self.lines.append(("warning", line))

    def error(self, line):
        self.lines.append(("error", line))

    def count(self, level: str, text: str) -> int:
        return sum(1 for lv, line in self.lines if lv == level and text in line)


class Run:
    """A RunSession with a fake clock, its log and everything it published (dicts in order)."""

    def __init__(self, tmp_path: Path, profile=None, **overrides):
        cfg = {p.name: p.default for p in PARAMS}
        cfg.update(scene_file=str(SCENE), bag_dir=str(tmp_path / "bags"), publish_rate=RATE, watchdog_timeout=0.0)
        cfg.update(overrides)
        self.clock, self.log, self.published = FakeClock(), Log(), []
        self.bag_dir = Path(cfg["bag_dir"])
        self.s = RunSession(cfg, clock=self.clock, publish=self.published.append,
                            log=self.log, background=False, compute_clock=self.clock, cpu_clock=self.clock,
                            profile=profile)

    def ticks(self, n: int, wall: float = TICK) -> None:
        """n ticks, ``wall`` seconds apart (each, RunSession.tick)."""
        for _ in range(n):
            self.clock.advance(wall)
            self.s.tick()

    def firings(self, n: int, wall: float = TICK) -> list[int]:
        """n firings of the tick timer, ``wall`` seconds apart: the ticks each ran (RunSession.fire)."""
        ran = []
        for _ in range(n):
            self.clock.advance(wall)
            ran.append(self.s.fire())
        return ran

    def topic(self, name: str) -> list[bytes]:
        return [m[name] for m in self.published if name in m]

    def bags(self) -> list[Path]:
        return sorted(self.bag_dir.glob("*.mcap"), key=lambda p: float(read_metadata(p)["mta_sim_ros"]["clock_offset"]))


def messages(bag: Path, topic: str) -> list[tuple[int, object]]:
    return [(t, m) for _, t, m in read_messages(str(bag), [topic])]


@pytest.fixture
def run(tmp_path):
    r = Run(tmp_path)
    yield r
    r.s.close()


# -- the watchdog ----------------------------------------------------------------------------

def test_the_watchdog_steers_straight_only_once_the_command_is_older_than_the_timeout(tmp_path):
    """'straight': a command exactly timeout old still decides; older, the watchdog steers 0;
    a new command decides again at the next tick. Each change is recorded at the tick it
    applies to, and the bag re-simulates exactly."""
    r = Run(tmp_path, watchdog_timeout=1.0, watchdog_action="straight")
    r.s.command("steering_angle", 0.3)
    received = r.clock.t
    r.ticks(49)
    r.clock.t = received + 1.0
    r.s.tick()
    assert r.s.steering.age() == 1.0 and r.s.sim.command == 0.3 and not r.s.watchdog.straight
    r.clock.t = received + 1.0 + 2.0**-20  # a microsecond later
    r.s.tick()
    assert r.s.sim.command == 0.0 and r.s.watchdog.straight
    taken_at = round(r.s.now * 1e9) - round(TICK * 1e9)  # stamped at the start of the tick it holds
    r.ticks(10)
    assert r.s.sim.command == 0.0
    r.s.command("steering_angle", 0.1)
    given_at = round(r.s.now * 1e9)
    r.ticks(1)
    assert r.s.sim.command == 0.1 and not r.s.watchdog.straight
    r.ticks(5)
    r.s.close()
    [bag] = r.bags()
    assert [(t, m.data) for t, m in messages(bag, "/steering_watchdog")] == [(taken_at, 0.0), (given_at, 0.1)]
    assert resimulate(str(bag)).identical


def test_the_watchdog_holding_keeps_the_stale_command_and_records_nothing(tmp_path):
    """'hold': a stale command goes on being held; only /diagnostics says it is stale."""
    r = Run(tmp_path, watchdog_timeout=1.0, watchdog_action="hold")
    r.s.command("steering_angle", 0.3)
    r.ticks(80)
    assert r.s.sim.command == 0.3
    status = r.s.diagnostics()
    assert status.level == WARN and status.message == "steering command stale (1.6 s): hold"
    r.s.close()
    [bag] = r.bags()
    assert messages(bag, "/steering_watchdog") == []


def test_a_watchdog_timeout_of_zero_never_takes_over(tmp_path):
    r = Run(tmp_path, watchdog_timeout=0.0, watchdog_action="straight")
    r.s.command("steering_angle", 0.3)
    r.ticks(10, wall=100.0)
    assert r.s.sim.command == 0.3 and r.s.diagnostics().level == OK
    r.s.close()


def test_a_take_over_still_holding_at_a_reset_is_recorded_again_in_the_new_bag(tmp_path):
    """Each bag re-simulates alone: the new one says that the watchdog steers from its start."""
    r = Run(tmp_path, watchdog_timeout=1.0, watchdog_action="straight")
    r.ticks(60)  # no command since the start: the watchdog took over
    r.s.reset()
    r.ticks(3)
    r.s.close()
    first, second = r.bags()
    assert [m.data for _, m in messages(first, "/steering_watchdog")] == [0.0]
    assert [m.data for _, m in messages(second, "/steering_watchdog")] == [0.0]
    assert resimulate(str(second)).identical


def test_a_watchdog_change_applies_live(tmp_path):
    r = Run(tmp_path, watchdog_timeout=0.0, watchdog_action="straight")
    r.ticks(100)
    assert not r.s.watchdog.straight
    assert r.s.set_parameters({"watchdog_timeout": 1.0}) == ""
    r.ticks(1)
    assert r.s.watchdog.straight and r.s.sim.command == 0.0
    r.s.close()


# -- commands --------------------------------------------------------------------------------

def test_bad_commands_are_refused_or_clamped_counted_said_and_recorded_as_received(run):
    """Non-finite: refused, the last good command is kept; out of range: clamped to the train's
    largest steering angle. Every one is counted in /diagnostics, logged at most once a second
    per topic, and recorded as it was received."""
    a = load_scene(str(SCENE)).train.actuator.max_angle
    run.s.command("steering_angle", 0.2)
    for bad in (math.nan, math.inf, -math.inf):
        run.s.command("steering_angle", bad)
    assert run.s.steering.value == 0.2
    run.s.command("steering_angle", 10.0)
    assert run.s.steering.value == a
    run.s.command("speed_setpoint", -80.0)
    assert run.s.speed.value == -50.0
    run.ticks(1)
    assert run.s.sim.command == a
    status = run.s.diagnostics()
    values = status.values
    assert (values["steering_commands"], values["steering_rejected"], values["steering_clamped"]) == (5, 3, 1)
    assert status.level == WARN
    assert "steering_angle: 10 outside [" in status.message and "speed_setpoint: -80 outside" in status.message
    assert run.log.count("warning", "steering_angle") == 1 and run.log.count("warning", "speed_setpoint") == 1
    run.clock.advance(1.0)
    run.s.command("steering_angle", math.nan)
    assert run.log.count("warning", "steering_angle") == 2  # a second later: said again
    run.s.close()
    [bag] = run.bags()
    steering = [m.data for _, m in messages(bag, "/steering_angle")]
    assert steering[0] == 0.2 and math.isnan(steering[1]) and steering[2:5] == [math.inf, -math.inf, 10.0]


# -- pause, pacing, real-time factor and lag -------------------------------------------------

def test_the_tick_period_is_the_tick_over_the_real_time_factor(tmp_path):
    for rtf, period in ((1.0, TICK), (4.0, TICK / 4), (0.0, 0.0)):
        r = Run(tmp_path, real_time_factor=rtf, record=False)
        assert r.s.period == period
        assert r.s.diagnostics().values["tick_period_ms"] == period * 1e3


def test_real_time_factor_and_lag_for_a_known_clock(tmp_path):
    """Ticks 40 ms apart at target 1 (20 ms each): half real time, the lag grows by 0.5 s a wall
    second. Then real time again: the factor, over its 5 s window, is 1 once the window holds
    only real-time ticks, while the lag stays where it was (nothing catches up)."""
    r = Run(tmp_path, record=False)
    for second in range(1, 5):
        r.ticks(25, wall=0.04)
        rtf, lag = r.s.diagnostics().values["real_time_factor"], r.s.diagnostics().values["lag_s"]
        assert rtf == pytest.approx(0.5, rel=1e-9) and lag == pytest.approx(0.5 * second, rel=1e-9)
    for second in range(1, 7):
        r.ticks(50, wall=TICK)
        values = r.s.diagnostics().values
        assert values["lag_s"] == pytest.approx(2.0, rel=1e-9)
    assert values["real_time_factor"] == pytest.approx(1.0, rel=1e-9)


def test_a_pause_stops_simulated_time_and_counts_in_neither_factor_nor_lag(tmp_path):
    r = Run(tmp_path, record=False)
    r.ticks(50)
    t, published = r.s.now, len(r.published)
    assert r.s.pause(True) == "paused"
    r.ticks(500)  # the timer goes on firing: nothing happens
    assert r.s.now == t and len(r.published) == published
    values = r.s.diagnostics().values
    assert values["paused"] is True and values["lag_s"] == 0.0 and values["real_time_factor"] == 0.0
    assert r.s.pause(False) == "running"
    r.ticks(50)
    values = r.s.diagnostics().values
    assert r.s.now == pytest.approx(t + 1.0, abs=1e-12)
    assert values["real_time_factor"] == pytest.approx(1.0, rel=1e-9) and values["lag_s"] == pytest.approx(0.0, abs=1e-9)


def test_a_new_real_time_factor_changes_the_period_and_measures_afresh(tmp_path):
    r = Run(tmp_path, record=False)
    r.ticks(50, wall=0.1)  # far behind
    assert r.s.set_parameters({"real_time_factor": 2.0}) == ""
    assert r.s.period == TICK / 2
    r.ticks(100, wall=TICK / 2)
    values = r.s.diagnostics().values
    assert values["real_time_factor"] == pytest.approx(2.0, rel=1e-9) and values["lag_s"] == pytest.approx(0.0, abs=1e-9)
    assert values["real_time_factor_target"] == 2.0


def test_a_firing_on_time_runs_one_tick_and_simulated_time_never_runs_ahead(tmp_path):
    r = Run(tmp_path, record=False)
    assert r.firings(50) == [1] * 50
    assert r.s.now == pytest.approx(50 * TICK, abs=1e-12)
    r.clock.advance(0.5 * TICK)  # a firing before the next tick's end: nothing yet
    assert r.s.fire() == 0
    assert r.firings(1, wall=0.5 * TICK) == [1]
    assert r.s.diagnostics().values["ticks_caught_up"] == 0


def test_late_firings_are_made_up_at_most_catch_up_ticks_a_firing(tmp_path):
    """A firing a whole second late (a flood, a busy core) runs CATCH_UP ticks; the next ones run
    CATCH_UP each until the lag is gone, then one: the lag is back under a tick after
    ceil(lag / ((CATCH_UP - 1) tick)) firings, instead of staying for good."""
    r = Run(tmp_path, record=False)
    r.firings(10)
    r.clock.advance(1.0)
    assert r.s.fire() == CATCH_UP
    behind = 1.0 - CATCH_UP * TICK  # 1.0 / TICK ticks were due at the late firing
    needed = math.ceil(behind / ((CATCH_UP - 1) * TICK) - 1e-9)
    ran = r.firings(needed + 5)
    assert ran[:needed - 1] == [CATCH_UP] * (needed - 1) and ran[needed:] == [1] * 5
    assert r.s.diagnostics().values["lag_s"] < TICK
    assert r.s.now == pytest.approx(10 * TICK + 1.0 + (needed + 5) * TICK, abs=1e-9)
    assert r.s.diagnostics().values["ticks_caught_up"] == sum(ran) + CATCH_UP - len(ran) - 1


def test_firings_twice_the_period_apart_run_two_ticks_each(tmp_path):
    r = Run(tmp_path, record=False)
    assert r.firings(20, wall=2 * TICK) == [2] * 20
    assert r.s.diagnostics().values["lag_s"] == pytest.approx(0.0, abs=1e-9)


def test_as_fast_as_possible_is_one_tick_a_firing_and_pause_is_none(tmp_path):
    r = Run(tmp_path, record=False, real_time_factor=0.0)
    assert r.s.timer_period == 0.0
    assert r.firings(5, wall=0.0) == [1] * 5
    r.s.pause(True)
    assert r.firings(5, wall=1.0) == [0] * 5


@pytest.mark.parametrize("target", [1e-12, 1e-300, 5e-324])
def test_a_tiny_real_time_factor_is_a_timer_every_max_period_and_no_tick_for_ages(tmp_path, target):
    """Inside the declared range [0, 1000]: a period of TICK / 1e-12 s is no timer's (rclpy's
    overflowed and killed the node), so the timer fires every MAX_TIMER_PERIOD and ticks when due."""
    for live in (False, True):
        r = Run(tmp_path, record=False, **({} if live else {"real_time_factor": target}))
        if live:
            assert r.s.set_parameters({"real_time_factor": target}) == ""
        assert r.s.timer_period == MAX_TIMER_PERIOD and r.s.period > 1e9
        assert r.firings(100, wall=MAX_TIMER_PERIOD) == [0] * 100
        assert r.s.set_parameters({"real_time_factor": 1.0}) == "" and r.s.timer_period == TICK
        assert r.firings(3) == [1] * 3


def test_tick_statistics_and_deadline_misses(tmp_path):
    """A tick whose work (here: publishing) takes longer than the period misses its deadline;
    the statistics of the last ticks are in /diagnostics, the whole run's in the closing record."""
    r = Run(tmp_path)
    r.s.publish = lambda msgs: r.clock.advance(0.03 if "/clock" in msgs else 0.0)  # 30 ms > the 20 ms period
    r.ticks(10)
    r.s.publish = lambda msgs: r.clock.advance(0.005 if "/clock" in msgs else 0.0)
    r.ticks(30)
    values = r.s.diagnostics().values
    assert values["deadline_misses"] == 10
    assert values["tick_compute_max_ms"] == pytest.approx(30.0, rel=1e-6)
    assert values["tick_compute_p50_ms"] == pytest.approx(5.0, rel=1e-6)
    r.s.close()
    [bag] = r.bags()
    run = read_metadata(bag)["mta_sim_ros.run"]
    assert int(run["tick_count"]) == 40 and int(run["tick_deadline_misses"]) == 10
    assert float(run["tick_max"]) == pytest.approx(0.03, rel=1e-6)
    assert r.log.count("info", "40 ticks: compute p50") == 1


# -- reset -----------------------------------------------------------------------------------

def test_reset_closes_the_bag_with_its_figures_and_starts_again_at_the_time_reached(tmp_path):
    r = Run(tmp_path)
    r.s.command("steering_angle", 0.2)
    r.ticks(100)
    last_clock = deserialize_message(r.topic("/clock")[-1], Clock).clock
    first = r.s.recorder.path
    message = r.s.reset()
    second = r.s.recorder.path
    assert message == f"reset to the start of 'headland_turn' at t = 2.000 s; recording {second.name} in bag_dir"
    assert r.log.count("info", message) == 1 and second != first
    figures = read_metadata(first)["mta_sim_ros.run"]
    assert int(figures["tick_count"]) == 100 and float(figures["sim_time"]) == pytest.approx(2.0)
    assert float(figures["run_wall_time"]) == pytest.approx(2.0, rel=1e-9)
    assert r.s.clock_offset == pytest.approx(2.0) and r.s.sim.t == 0.0 and r.s.stats.count == 0
    assert r.s.steering.value == load_scene(str(SCENE)).initial.steering
    r.ticks(1)
    clock = deserialize_message(r.topic("/clock")[-1], Clock).clock
    assert (clock.sec, clock.nanosec) > (last_clock.sec, last_clock.nanosec)  # /clock goes on
    ini = load_scene(str(SCENE)).initial
    pose = deserialize_message(r.topic("hitch_poses")[-1], PoseArray).poses[0].position
    assert abs(pose.x - ini.x) < 3.0 * 2 * TICK and abs(pose.y - ini.y) < 1e-3  # one tick from the start
    r.s.close()
    assert read_metadata(second)["mta_sim_ros"]["clock_offset"] == repr(r.s.clock_offset)
    assert resimulate(str(second)).identical


def test_a_fidelity_change_applies_at_the_next_reset_only(tmp_path):
    r = Run(tmp_path)
    assert r.s.sim.level == "dynamic"
    assert r.s.set_parameters({"fidelity": "kinematic"}) == ""
    assert r.log.count("info", "fidelity kinematic: applies at the next reset") == 1
    r.ticks(5)
    values = r.s.diagnostics().values
    assert r.s.sim.level == "dynamic" and values["fidelity"] == "dynamic"
    assert values["fidelity_at_next_reset"] == "kinematic"
    r.s.reset()
    assert r.s.sim.level == "kinematic" and r.s.diagnostics().values["fidelity"] == "kinematic"
    r.ticks(5)
    r.s.close()
    first, second = r.bags()
    assert read_metadata(first)["mta_sim_ros"]["fidelity"] == "dynamic"
    meta = read_metadata(second)["mta_sim_ros"]
    assert meta["fidelity"] == "kinematic" and meta["param.fidelity"] == "kinematic"


def test_a_reset_without_recording_says_so(tmp_path):
    r = Run(tmp_path, record=False)
    r.ticks(3)
    assert r.s.reset() == "reset to the start of 'headland_turn' at t = 0.060 s"
    assert not r.bag_dir.exists()


# -- diagnostics -----------------------------------------------------------------------------

def test_diagnostics_ok_while_nothing_is_wrong(run):
    run.ticks(3)
    status = run.s.diagnostics()
    assert (status.level, status.message) == (OK, "running")
    assert status.values["sim_time_s"] == pytest.approx(3 * TICK) and status.values["bag"].endswith(".mcap")
    run.s.publish_diagnostics()
    [data] = run.topic("/diagnostics")
    msg = deserialize_message(data, DiagnosticArray).status[0]
    assert msg.name == "mta_sim: simulation" and msg.level == b"\x00" and msg.message == "running"
    assert {kv.key for kv in msg.values} == set(status.values)


def test_a_jackknife_halts_the_run_with_an_error_until_a_reset(run):
    """The model stops at the jackknife: ERROR in /diagnostics (published at once) and in the
    log; the timer's ticks do nothing more, whatever the commands; a reset starts again, back
    to OK."""
    run.s.command("steering_angle", 0.45)  # no steady turn: the seeder jackknifes (steady.py)
    for _ in range(2000):
        run.ticks(1)
        if run.s.halted:
            break
    assert "jackknife" in run.s.halted
    assert run.log.count("error", "simulation halted (call reset to start again): jackknife") == 1
    halt = deserialize_message(run.topic("/diagnostics")[-1], DiagnosticArray).status[0]
    assert halt.level == b"\x02" and halt.message.startswith("jackknife")
    t, published = run.s.now, len(run.published)
    run.s.command("steering_angle", 0.0)  # a command that could steer out of it changes nothing
    run.ticks(100)
    status = run.s.diagnostics()
    assert run.s.now == t and len(run.published) == published
    assert status.level == ERROR and status.message.startswith("jackknife")
    assert run.log.count("error", "simulation halted") == 1
    run.s.reset()
    run.ticks(5)
    assert run.s.now > t and run.s.diagnostics().level == OK


def test_a_bag_dir_that_cannot_be_written_stops_recording_not_the_run(tmp_path):
    """Said once in the log, every time in /diagnostics (WARN); the ticks go on."""
    not_a_dir = tmp_path / "file"
    not_a_dir.write_text("x")
    r = Run(tmp_path, bag_dir=str(not_a_dir))
    r.ticks(10)
    for _ in range(3):
        r.clock.advance(1.0)
        r.s.publish_diagnostics()
    assert len(r.topic("hitch_poses")) == 10
    statuses = [deserialize_message(d, DiagnosticArray).status[0] for d in r.topic("/diagnostics")]
    assert all(s.level == b"\x01" and "recording stopped" in s.message for s in statuses)
    assert r.log.count("error", "recording stopped") == 1
    r.s.close()


def test_a_write_failing_mid_run_is_logged_once_and_the_run_goes_on(tmp_path):
    r = Run(tmp_path)
    r.ticks(10)

    def full(*args, **kwargs):
        raise BagError("disk full")

    r.s.recorder.writer.write_raw = full
    r.ticks(10)
    for _ in range(3):
        r.s.publish_diagnostics()
    assert r.s.recorder.error == "recording stopped: disk full" and len(r.topic("hitch_poses")) == 20
    assert r.log.count("error", "recording stopped: disk full") == 1
    assert r.s.diagnostics().message == "recording stopped: disk full"
    r.s.close()


# -- parameters ------------------------------------------------------------------------------

def test_live_parameter_changes_are_checked_all_or_none(run):
    refused = run.s.set_parameters({"publish_rate": 20.0})
    assert refused.startswith("publish_rate cannot change while running")
    assert run.s.set_parameters({"publish_rate": RATE}) == ""  # the value it has: nothing changes
    assert run.s.set_parameters({"real_time_factor": -1.0}) == "real_time_factor: -1.0 must be in [0, 1000]"
    assert run.s.set_parameters({"watchdog_action": "left"}) == \
        "watchdog_action: 'left' must be one of 'hold', 'straight'"
    assert run.s.set_parameters({"frame_id": 3}) == "frame_id: 3 must be of type str"
    assert run.s.set_parameters({"real_time_factor": 3.0, "watchdog_action": "left"}).startswith("watchdog_action")
    assert run.s.cfg["real_time_factor"] == 1.0 and run.s.period == TICK  # none of the two applied
    assert run.s.set_parameters({"use_sim_time": True}) == ""  # not the simulator's: ignored
    assert "use_sim_time" not in run.s.cfg


def test_a_fidelity_level_the_train_cannot_run_is_refused(tmp_path):
    train = (REPO / "config" / "trains" / "default.yaml").read_text()
    start = train.index("  traction:\n")
    end = train.index("  rolling:")
    (tmp_path / "train.yaml").write_text(train[:start] + "  traction: {law: constant, force: 60000}\n" + train[end:])
    (tmp_path / "scene.yaml").write_text("name: constant_force\ntrain: train.yaml\nduration: 10\n"
                                         "initial: {x: 0, y: 0, heading: 0, speed: 3.0, steering: 0}\n"
                                         "steering: {table: {time: [0], angle: [0]}}\n"
                                         "integrator: {method: rk4, step: 0.01}\npublish_rate: 50\n")
    r = Run(tmp_path, scene_file=str(tmp_path / "scene.yaml"))
    assert "does not command a speed" in r.s.set_parameters({"fidelity": "kinematic"})
    assert r.s.cfg["fidelity"] == ""
    r.s.close()
    with pytest.raises(ConfigError, match="parameter fidelity: .*does not command a speed"):
        Run(tmp_path, scene_file=str(tmp_path / "scene.yaml"), fidelity="kinematic")


@pytest.mark.parametrize("frame", ["", "/map", "my map", "map\n", "\x00", "x" * 257])
def test_a_frame_id_tf2_would_refuse_is_refused_with_the_rule(run, frame):
    reason = run.s.set_parameters({"frame_id": frame})
    assert reason.startswith("frame_id: ") and "must be a frame name" in reason and "\n" not in reason
    assert run.s.cfg["frame_id"] == "map"


@pytest.mark.parametrize("frame", ["odom", "unit1/odom", "x" * 256])
def test_a_frame_id_tf2_takes_is_taken(run, frame):
    assert run.s.set_parameters({"frame_id": frame}) == ""
    run.ticks(1)
    assert deserialize_message(run.topic("hitch_poses")[-1], PoseArray).header.frame_id == frame


def test_frame_id_changes_live_in_poses_and_markers(run):
    run.ticks(5)
    assert deserialize_message(run.topic("hitch_poses")[-1], PoseArray).header.frame_id == "map"
    assert run.s.set_parameters({"frame_id": "odom"}) == ""
    run.ticks(5)
    assert deserialize_message(run.topic("hitch_poses")[-1], PoseArray).header.frame_id == "odom"
    markers = deserialize_message(run.topic("markers")[-1], MarkerArray)
    assert {m.header.frame_id for m in markers.markers} == {"odom"}


def test_markers_go_out_every_publish_rate_over_marker_rate_ticks(run):
    run.ticks(20)
    ticks = [m for m in run.published if "hitch_poses" in m]  # (at start: the latched topics)
    assert [i for i, m in enumerate(ticks) if "markers" in m] == [4, 9, 14, 19]  # 50 Hz / 10 Hz


@pytest.mark.parametrize("bad,expected", [
    (dict(publish_rate=-5.0), "parameter publish_rate: -5.0 must be in [1, 1000]"),
    (dict(integrator_method="RK99"), "parameter integrator_method: 'RK99' must be one of"),
    (dict(scene_file="/nowhere/scene.yaml"), "parameter scene_file: "),
    (dict(publish_rate=10.0, integrator_step=0.5), "parameter integrator_step: 0.5 must be in [1/publish_rate / 10000"),
    (dict(watchdog_action="left"), "parameter watchdog_action: 'left' must be one of"),
])
def test_an_invalid_configuration_is_one_config_error(tmp_path, bad, expected):
    with pytest.raises(ConfigError) as err:
        Run(tmp_path, **bad)
    assert str(err.value).startswith(expected)
    assert not (tmp_path / "bags").exists()


# -- the bag's metadata ----------------------------------------------------------------------

def test_the_bag_metadata_says_what_ran_and_how_it_ended(run):
    run.ticks(5)
    run.s.close()
    [bag] = run.bags()
    meta = read_metadata(bag)
    assert set(meta["mta_sim_ros"]) == {
        "package_version", "scene_file", "scene_yaml", "train_file", "train_yaml", "method", "step",
        "stepper_step", "stability_note", "split_kinks", "right_hand_side", "rate", "algorithm", "fidelity",
        "fidelity_reason", "clock_offset", "tolerance_m", "error_estimate", *(f"param.{p.name}" for p in PARAMS)}
    assert meta["mta_sim_ros"]["scene_yaml"] == SCENE.read_text()
    assert float(meta["mta_sim_ros"]["tolerance_m"]) == 1e-6  # the scene asks for the default
    assert meta["mta_sim_ros"]["error_estimate"] == "step halving, order 4"  # rk4's companion at half the step
    assert meta["mta_sim_ros"]["split_kinks"] == "True"  # the default: steps split at kinks
    assert meta["mta_sim_ros"]["param.publish_rate"] == "50.0" and meta["mta_sim_ros"]["clock_offset"] == "0.0"
    assert set(meta["mta_sim_ros.run"]) == {
        *(f"tick_{k}" for k in ("count", "mean", "min", "p50", "p99", "p99.9", "max", "deadline_misses")),
        *(f"tick_cpu_{k}" for k in ("p50", "p99", "p99.9", "max")),
        "recorder_thread_cpu", "sim_time", "tick_period", "run_sim_time", "run_wall_time", "position_error_m"}
    assert 0.0 < float(meta["mta_sim_ros.run"]["position_error_m"]) < 1e-6  # the companion followed the run
    topics = {t for t, _, _ in read_messages(str(bag))}
    assert topics == {"/hitch_poses", "/cart_velocities", "/traction_power", "/applied_steering", "/clock", "/markers",
                      "/tf", "/tf_static", "/joint_states", "/odom", "/robot_description", "/run_metadata"}


def test_the_session_does_not_import_ros():
    """The session runs where rclpy is not installed: nothing it imports pulls it in."""
    code = ("import sys, mta_sim_ros.node.run_session; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'rclpy' or m.split('.')[0].endswith('_msgs')))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_a_tick_profile_hears_every_stage_of_every_tick_in_order(tmp_path):
    """What ``python -m benchmarks realtime --stages`` times: start, the six stages, done, once per tick; the
    markers stage every tick (it is empty when no markers are due), nothing while paused."""
    class Profile:
        def __init__(self):
            self.events = []

        def start(self):
            self.events.append("start")

        def mark(self, stage):
            self.events.append(stage)

        def done(self):
            self.events.append("done")

    profile = Profile()
    r = Run(tmp_path, profile=profile)
    r.ticks(3)
    one = ["start", "advance", "outputs", "encode", "markers", "publish", "bag_write", "done"]
    assert profile.events == one * 3
    r.s.pause(True)
    r.ticks(2)
    assert profile.events == one * 3
    r.s.close()


def test_a_bad_command_warns_until_a_good_one_or_a_reset(tmp_path):
    """/diagnostics says the current state: WARN while the last command received was refused or
    clamped, OK again once a good one is taken (the counts remain), and a reset starts clean."""
    r = Run(tmp_path)
    r.ticks(1)
    assert r.s.diagnostics().level == OK
    r.s.command("steering_angle", math.nan)
    assert r.s.diagnostics().level == WARN and "not finite" in r.s.diagnostics().message
    r.s.command("steering_angle", 0.1)
    status = r.s.diagnostics()
    assert status.level == OK and status.values["steering_rejected"] == 1
    r.s.command("steering_angle", 10.0)  # clamped to the actuator's limit
    assert r.s.diagnostics().level == WARN and "clamped" in r.s.diagnostics().message
    r.s.command("speed_setpoint", math.inf)
    r.s.reset()
    assert r.s.diagnostics().level == OK
    r.s.close()
