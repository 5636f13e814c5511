"""Controllers in the loop, in process with a set clock: the command conventions (cmd_vel,
ackermann_cmd) against the bicycle relation and the actuator law of docs/model.md, the one
precedence rule, and the lockstep protocol (session.py's docstring). No DDS, no sleeping:
test_controllers_dds.py runs the same over real DDS."""
from __future__ import annotations

import math

import numpy as np
import pytest
from geometry_msgs.msg import Twist, TwistStamped
from rclpy.serialization import serialize_message
from test_session import SCENE, TICK, Run

from mta_sim_ros.analysis import resimulate
from mta_sim_ros.bag import read_messages
from mta_sim_ros.bag.cdr import encode
from mta_sim_ros.messages.decode import CommandDecodeError, decode_ackermann, decode_twist, decode_twist_stamped
from mta_sim_ros.node.commands import SPEED_LIMIT, ackermann_setting, twist_setting
from mta_sim_ros.node.pacing import LOCKSTEP_TIMER_PERIOD, REPUBLISH_EVERY
from mta_sim_ros.node.run_session import message_commands
from mta_sim_ros.node.status import OK, WARN
from mta_sim_ros.physics.loader import load_scene
from mta_sim_ros.run.simulation import Simulation

TRAIN = load_scene(str(SCENE)).train
L1, MAX_ANGLE, MAX_RATE = TRAIN.carts[0].length, TRAIN.actuator.max_angle, TRAIN.actuator.max_rate


@pytest.fixture
def ackermann_installed():
    """ackermann_msgs is a dependency (package.xml): without it these checks fail, not skip."""
    if "ackermann_cmd" not in message_commands():
        pytest.fail("ackermann_msgs is not installed (its .msg files and Python package)")


needs_ackermann = pytest.mark.usefixtures("ackermann_installed")


def twist(v: float, omega: float, **other) -> bytes:
    """A geometry_msgs/Twist as CDR bytes (our serializer; rclpy's is compared below)."""
    return encode("geometry_msgs/msg/Twist", {"linear": {"x": v, "y": other.get("vy", 0.0), "z": 0.0},
                                              "angular": {"x": 0.0, "y": 0.0, "z": omega}})


def twist_stamped(v: float, omega: float, frame_id: str = "base_link") -> bytes:
    """A geometry_msgs/TwistStamped as CDR bytes (our serializer; rclpy's is compared below)."""
    return encode("geometry_msgs/msg/TwistStamped", {
        "header": {"stamp": {"sec": 12, "nanosec": 345}, "frame_id": frame_id},
        "twist": {"linear": {"x": v, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": omega}}})


def ackermann(steering: float, speed: float, rate: float = 0.0, frame_id: str = "base_link") -> bytes:
    return encode("ackermann_msgs/msg/AckermannDriveStamped", {
        "header": {"stamp": {"sec": 12, "nanosec": 345}, "frame_id": frame_id},
        "drive": {"steering_angle": steering, "steering_angle_velocity": rate, "speed": speed,
                  "acceleration": 0.5, "jerk": 0.25}})


# -- the conventions, as numbers -----------------------------------------------------------------

@pytest.mark.parametrize("v, omega", [(3.0, 0.1), (3.0, -0.25), (0.5, 0.05), (-1.5, 0.2), (-2.0, -0.1), (3.0, 0.0)])
def test_cmd_vel_gives_the_steering_and_speed_whose_steady_motion_is_the_command(v, omega):
    """On the bicycle relation of the tractor (docs/model.md: th'_1 = V sin psi_1 / l_1 and
    s'_B1 = V cos psi_1), the held psi_cmd and V give exactly the yaw rate and rear-axle speed
    asked for, forward and in reverse (a left yaw rate in reverse is a right steering angle)."""
    s = twist_setting(v, omega, L1, MAX_ANGLE)
    assert not s.problem and s.rate is None
    assert s.speed * math.sin(s.steering) / L1 == pytest.approx(omega, rel=1e-14, abs=1e-16)
    assert s.speed * math.cos(s.steering) == pytest.approx(v, rel=1e-14)
    assert math.copysign(1.0, s.steering * v * omega) >= 0  # psi has the sign of omega / v


def test_cmd_vel_at_standstill_sets_the_speed_and_keeps_the_steering():
    s = twist_setting(0.0, 0.3, L1, MAX_ANGLE)
    assert s.steering is None and s.speed == 0.0 and not s.refused


def test_cmd_vel_out_of_reach_is_clamped_and_refused_when_not_finite():
    s = twist_setting(0.1, 1.0, L1, MAX_ANGLE)  # atan(30) = 88 deg: beyond the 40 deg lock
    assert s.steering == MAX_ANGLE and "clamped" in s.problem and "cmd_vel" in s.problem
    assert s.speed == 0.1 / math.cos(MAX_ANGLE)  # B_1 still runs at v; it turns less than asked
    s = twist_setting(200.0, 0.0, L1, MAX_ANGLE)
    assert s.speed == SPEED_LIMIT and "speed" in s.problem
    for bad in ((math.nan, 0.1), (1.0, math.inf)):
        s = twist_setting(*bad, L1, MAX_ANGLE)
        assert s.refused and s.steering is None and s.speed is None and "not finite" in s.problem


def test_ackermann_steering_rate_is_the_actuators_limit_from_zero_to_its_own():
    s = ackermann_setting(0.2, 0.0, 2.0, MAX_ANGLE, MAX_RATE)
    assert (s.steering, s.rate, s.speed, s.problem) == (0.2, None, 2.0 / math.cos(0.2), "")
    assert ackermann_setting(0.2, -0.1, 2.0, MAX_ANGLE, MAX_RATE).rate == 0.1
    s = ackermann_setting(0.2, 10.0, 2.0, MAX_ANGLE, MAX_RATE)
    assert s.rate == MAX_RATE and "clamped" in s.problem
    assert ackermann_setting(0.2, math.nan, 2.0, MAX_ANGLE, MAX_RATE).refused


@pytest.mark.parametrize("v, omega, vy", [(1.25, -0.5, 0.0), (-3.0, 1e-300, 7.0), (0.0, 0.0, 0.0)])
def test_twist_bytes_are_read_as_rclpy_writes_them(v, omega, vy):
    msg = Twist()
    msg.linear.x, msg.linear.y, msg.angular.z = v, vy, omega
    data = serialize_message(msg)
    assert data == twist(v, omega, vy=vy)
    assert decode_twist(data) == (v, omega)


@pytest.mark.parametrize("frame_id", ["", "a", "abc", "odom", "base_link", "x" * 17])
def test_twist_stamped_bytes_are_read_as_rclpy_writes_them(frame_id):
    """Every length of frame_id moves the twist's 8-byte alignment: rclpy's bytes, ours, both read."""
    msg = TwistStamped()
    msg.header.frame_id = frame_id
    msg.twist.linear.x, msg.twist.angular.z = -2.75, 0.125
    data = serialize_message(msg)
    assert decode_twist_stamped(data) == (-2.75, 0.125)
    assert decode_twist_stamped(twist_stamped(-2.75, 0.125, frame_id)) == (-2.75, 0.125)
    for cut in (0, 4, 15, len(data) - 1):
        with pytest.raises(CommandDecodeError, match="TwistStamped"):
            decode_twist_stamped(data[:cut])


@needs_ackermann
@pytest.mark.parametrize("frame_id", ["", "a", "abc", "base_link", "x" * 17])
def test_ackermann_bytes_are_read_as_rclpy_writes_them(frame_id):
    from ackermann_msgs.msg import AckermannDriveStamped

    msg = AckermannDriveStamped()
    msg.header.frame_id = frame_id
    msg.drive.steering_angle, msg.drive.steering_angle_velocity, msg.drive.speed = 0.25, -0.125, 2.5
    data = serialize_message(msg)
    assert decode_ackermann(data) == (0.25, -0.125, 2.5)  # exact in float32
    assert decode_ackermann(ackermann(0.25, 2.5, -0.125, frame_id)) == (0.25, -0.125, 2.5)


# -- one rule, in the session ------------------------------------------------------------------

def test_the_latest_command_of_any_source_sets_what_it_sets(tmp_path):
    """steering_angle sets psi_cmd, speed_setpoint V, cmd_vel both (or V alone at v = 0); each
    tick holds what the latest ones set."""
    r = Run(tmp_path)
    r.s.command("steering_angle", 0.1)
    r.s.command("speed_setpoint", 2.0)
    r.ticks(1)
    assert (r.s.sim.command, r.s.sim.v_set) == (0.1, 2.0)
    r.s.command_message("cmd_vel", twist(3.0, 0.2))
    r.ticks(1)
    expected = twist_setting(3.0, 0.2, L1, MAX_ANGLE)
    assert (r.s.sim.command, r.s.sim.v_set) == (expected.steering, expected.speed)
    r.s.command("speed_setpoint", 1.0)  # the speed only
    r.ticks(1)
    assert (r.s.sim.command, r.s.sim.v_set) == (expected.steering, 1.0)
    r.s.command_message("cmd_vel", twist(0.0, 0.5))  # standstill: the speed only
    r.ticks(1)
    assert (r.s.sim.command, r.s.sim.v_set) == (expected.steering, 0.0)
    r.s.command_message("cmd_vel", twist(math.nan, 0.5))  # refused: nothing
    r.s.command("steering_angle", -0.05)
    r.ticks(1)
    assert (r.s.sim.command, r.s.sim.v_set) == (-0.05, 0.0)
    d = r.s.diagnostics()
    assert d.values["cmd_vel_commands"] == 3 and d.values["cmd_vel_rejected"] == 1
    assert d.level == WARN and "cmd_vel: linear.x = nan is not finite" in d.message
    r.s.command_message("cmd_vel", twist(1.0, 0.0))  # a good one clears what is said
    assert r.s.diagnostics().level == OK
    r.s.close()
    [bag] = r.bags()
    recorded = [(m.linear.x, m.angular.z) for _, _, m in read_messages(str(bag), ["/cmd_vel"])]
    assert len(recorded) == 4 and recorded[:2] == [(3.0, 0.2), (0.0, 0.5)] and recorded[3] == (1.0, 0.0)
    assert math.isnan(recorded[2][0]) and recorded[2][1] == 0.5  # the refused one too, as received


def test_cmd_vel_at_standstill_keeps_the_watchdog_off_the_steering_it_holds(tmp_path):
    """A cmd_vel at v = 0 leaves the steering as it is, and says so afresh: the watchdog (a
    steering command older than its timeout) does not take a talking controller for a lost one."""
    r = Run(tmp_path, watchdog_timeout=0.5, watchdog_action="straight")
    r.s.command("steering_angle", 0.2)
    for _ in range(10):
        r.ticks(10)  # 0.2 s
        r.s.command_message("cmd_vel", twist(0.0, 0.1))
    assert r.s.sim.command == 0.2 and not r.s.watchdog.straight
    r.ticks(30)  # 0.6 s of silence
    assert r.s.sim.command == 0.0 and r.s.watchdog.straight
    r.s.close()


def test_cmd_vel_steers_exactly_as_the_equivalent_float64_commands(tmp_path):
    """The same numbers held, the same outputs, byte for byte."""
    a, b = Run(tmp_path / "a"), Run(tmp_path / "b")
    for k, (v, omega) in enumerate([(3.0, 0.0), (3.0, 0.15), (2.5, -0.2), (-1.0, 0.1)]):
        s = twist_setting(v, omega, L1, MAX_ANGLE)
        a.s.command_message("cmd_vel", twist(v, omega))
        b.s.command("steering_angle", s.steering)
        b.s.command("speed_setpoint", s.speed)
        a.ticks(100)
        b.ticks(100)
    assert a.topic("hitch_poses") == b.topic("hitch_poses") and len(a.topic("hitch_poses")) == 400
    a.s.close()
    b.s.close()


def test_a_stamped_cmd_vel_steers_as_the_twist_and_resimulates(tmp_path):
    """cmd_vel_stamped: the node takes cmd_vel as TwistStamped (nav2's enable_stamped_cmd_vel): the
    same twists give the same outputs, byte for byte, the bag's cmd_vel channel is TwistStamped as
    received, and the bag re-simulates exactly."""
    a, b = Run(tmp_path / "a"), Run(tmp_path / "b", cmd_vel_stamped=True)
    for v, omega in [(3.0, 0.0), (3.0, 0.15), (2.5, -0.2), (0.0, 0.1)]:
        a.s.command_message("cmd_vel", twist(v, omega))
        b.s.command_message("cmd_vel", twist_stamped(v, omega, "base_link"))
        a.ticks(50)
        b.ticks(50)
    assert a.topic("hitch_poses") == b.topic("hitch_poses") and len(a.topic("hitch_poses")) == 200
    a.s.close()
    b.s.close()
    [bag] = b.bags()
    received = [m for _, _, m in read_messages(str(bag), ["/cmd_vel"])]
    assert [m.header.frame_id for m in received] == ["base_link"] * 4
    assert [(m.twist.linear.x, m.twist.angular.z) for m in received] == [(3.0, 0.0), (3.0, 0.15), (2.5, -0.2),
                                                                              (0.0, 0.1)]
    assert resimulate(str(bag)).identical


@pytest.mark.parametrize("kwargs, tol", [
    ({}, 1e-12),  # compiled kernels, the actuator in closed form (kinks split)
    ({"compiled": False}, 1e-12),  # the same source as plain Python
    ({"split_kinks": False}, 1e-12),  # the actuator stepped by RK4: a straight line is exact
    ({"fidelity": "slip"}, 1e-6),  # the slip level's own right-hand side, LSODA at its tolerances
])
def test_a_steering_rate_limit_moves_the_applied_steering_at_that_rate(kwargs, tol):
    """The actuator law psi' = clip((psi_cmd - psi) / tau, +-rate): while (psi_cmd - psi) / tau
    exceeds the rate, psi moves at the rate exactly; back to the train's own at None. On every
    path a run can take (each reads the rate where it reads max_rate)."""
    sim = Simulation(load_scene(str(SCENE)), rate=50.0, **kwargs)
    psi0, rate = sim.outputs().steering, 0.05
    sim.set_rate_limit(rate)
    for k in range(1, 21):
        sim.advance(0.3, sim.v_set)
        assert sim.outputs().steering == pytest.approx(psi0 + rate * k * TICK, abs=tol)
    sim.set_rate_limit(None)
    before = sim.outputs().steering
    sim.advance(0.3, sim.v_set)
    assert sim.outputs().steering - before == pytest.approx(MAX_RATE * TICK, abs=tol)


@needs_ackermann
def test_ackermann_cmd_sets_steering_speed_and_rate_and_a_float64_steering_gives_the_rate_back(tmp_path):
    r = Run(tmp_path)
    psi0 = r.s.sim.outputs().steering
    r.s.command_message("ackermann_cmd", ackermann(0.3, 2.0, rate=0.05))
    r.ticks(10)
    assert r.s.sim.command == pytest.approx(0.3, abs=1e-7)  # float32 on the wire
    assert r.s.sim.v_set == pytest.approx(2.0 / math.cos(0.3), rel=1e-6)
    assert r.s.sim.outputs().steering == pytest.approx(psi0 + 0.05 * 10 * TICK, abs=1e-9)
    r.s.command("steering_angle", 0.3)  # the actuator's own rate again
    before = r.s.sim.outputs().steering
    r.ticks(1)
    assert r.s.sim.outputs().steering - before == pytest.approx(MAX_RATE * TICK, abs=1e-12)
    r.s.close()
    [bag] = r.bags()
    [(_, _, m)] = list(read_messages(str(bag), ["/ackermann_cmd"]))
    assert m.header.frame_id == "base_link" and m.drive.jerk == 0.25  # as received
    assert resimulate(str(bag)).identical


def test_a_cmd_vel_bag_resimulates_exactly(tmp_path):
    """mta replay --resimulate holds what the node held, also when two sources of the steering
    arrive in one tick (in either order: the later one holds)."""
    r = Run(tmp_path)
    r.s.command_message("cmd_vel", twist(2.5, 0.2))
    r.ticks(50)
    r.s.command("steering_angle", -0.1)
    r.ticks(20)
    r.s.command_message("cmd_vel", twist(0.0, 0.2))
    r.ticks(20)
    r.s.command("steering_angle", 0.15)
    r.s.command_message("cmd_vel", twist(2.0, -0.1))
    r.ticks(20)
    r.s.command_message("cmd_vel", twist(2.0, 0.1))
    r.s.command("steering_angle", -0.15)
    r.ticks(20)
    assert r.s.sim.command == -0.15
    r.s.close()
    [bag] = r.bags()
    assert resimulate(str(bag)).identical


# -- lockstep --------------------------------------------------------------------------------------

def lockstep_run(tmp_path, **overrides):
    return Run(tmp_path, **{"lockstep": True, "lockstep_timeout": 2.0, **overrides})


def fire(r: Run, n: int, wall: float = LOCKSTEP_TIMER_PERIOD) -> int:
    """n firings ``wall`` apart; the ticks they ran."""
    return sum(r.firings(n, wall))


def test_lockstep_ticks_once_per_answer_and_never_without_one(tmp_path):
    r = lockstep_run(tmp_path, real_time_factor=1.0)
    assert r.s.timer_period == LOCKSTEP_TIMER_PERIOD
    assert fire(r, 1) == 1  # step 1: the first firing ticks
    assert fire(r, 10, wall=0.15) == 0  # no answer, no tick, however late it gets
    assert r.s.sim.ticks == 1
    r.s.command("steering_angle", 0.1)
    assert fire(r, 5, wall=0.0) == 1  # an answer: exactly one tick
    r.s.command("steering_angle", 0.2)
    r.s.command("speed_setpoint", 2.0)  # two answers before a firing: still one tick
    assert fire(r, 3) == 1 and (r.s.sim.command, r.s.sim.v_set) == (0.2, 2.0)
    r.s.command("steering_angle", math.nan)  # refused, but an answer
    assert fire(r, 3) == 1 and r.s.sim.command == 0.2
    r.s.command_message("cmd_vel", twist(3.0, 0.1))
    assert fire(r, 3) == 1 and r.s.sim.ticks == 5
    assert r.s.diagnostics().values["deadline_misses"] == 0  # nothing paced, nothing late


def test_lockstep_republishes_unanswered_outputs_and_records_them_once(tmp_path):
    r = lockstep_run(tmp_path, lockstep_timeout=100.0)
    fire(r, 1)
    first = r.topic("hitch_poses")
    assert len(first) == 1
    quarter = REPUBLISH_EVERY / 4  # exact in binary: the fake clock adds up to the interval exactly
    fire(r, 3, wall=quarter)  # under the interval
    assert len(r.topic("hitch_poses")) == 1
    fire(r, 1, wall=quarter)
    assert r.topic("hitch_poses") == first * 2  # the same bytes again
    fire(r, 8, wall=quarter)
    assert r.topic("hitch_poses") == first * 4 and r.s.sim.ticks == 1
    assert r.s.diagnostics().values["lockstep_republished"] == 3
    r.s.close()
    [bag] = r.bags()
    assert len(list(read_messages(str(bag), ["/hitch_poses"]))) == 1


def test_lockstep_says_who_stalled_after_the_timeout_keeps_waiting_and_recovers(tmp_path):
    r = lockstep_run(tmp_path, lockstep_timeout=2.0)
    fire(r, 1)
    t = r.s.now
    r.firings(1, wall=1.99)
    assert r.s.diagnostics().level == OK and r.log.count("warning", "lockstep") == 0
    r.firings(1, wall=0.02)
    d = r.s.diagnostics()
    assert d.level == WARN and d.values["lockstep_stalls"] == 1
    for topic in ("/steering_angle", "/speed_setpoint", "/cmd_vel"):
        assert topic in d.message
    assert f"t = {t:.3f} s" in d.message and "still waiting" in d.message
    fire(r, 100, wall=1.0)  # keeps waiting, said once in the log
    assert r.s.sim.ticks == 1 and r.log.count("warning", f"answering the outputs at t = {t:.3f} s") == 1
    r.s.command("steering_angle", 0.1)
    assert fire(r, 1) == 1
    assert r.s.diagnostics().level == OK and r.log.count("info", "lockstep: answered") == 1
    r.s.close()


def test_lockstep_pause_reset_and_no_watchdog(tmp_path):
    """Pause holds an answered tick back; a reset starts again at step 1; the watchdog never
    takes over in lockstep (a missing answer stops time instead)."""
    r = lockstep_run(tmp_path, watchdog_timeout=0.5, watchdog_action="straight")
    fire(r, 1)
    r.s.command("steering_angle", 0.2)
    r.s.pause(True)
    assert fire(r, 5) == 0
    r.s.pause(False)
    assert fire(r, 5) == 1
    fire(r, 40, wall=1.0)  # 40 s after the last command
    r.s.command("speed_setpoint", 2.0)
    assert fire(r, 1) == 1 and r.s.sim.command == 0.2 and not r.s.watchdog.straight
    r.s.reset()
    assert fire(r, 1) == 1 and fire(r, 5) == 0
    r.s.close()


def test_a_lockstep_run_is_a_function_of_its_commands_not_of_the_wall_clock(tmp_path):
    """The same answers at any wall timing: the same published bytes, and bags whose messages
    but /diagnostics are the same records (topic, log time, bytes)."""
    runs = []
    for name, wall in (("quick", 0.0), ("slow", 0.7)):
        r = lockstep_run(tmp_path / name, lockstep_timeout=1.0)
        r.firings(1)
        for k in range(60):
            r.s.command("steering_angle", 0.2 * math.sin(0.1 * k))
            r.firings(1, wall=wall)
            if k % 7 == 0:
                r.s.publish_diagnostics()
        r.s.close()
        [bag] = r.bags()
        records = [(topic, t, bytes(m)) for topic, t, m in raw_messages(bag)
                   if topic not in ("/diagnostics", "/run_metadata")]  # the run's record names its bag folder
        runs.append((r.topic("hitch_poses")[:61], records))
    assert runs[0] == runs[1] and len(runs[0][1]) > 300


def raw_messages(bag):
    from mcap.reader import make_reader

    with open(bag, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            yield channel.topic, message.log_time, message.data


def test_lockstep_is_fixed_at_start(tmp_path):
    r = lockstep_run(tmp_path)
    assert "fixed at start" in r.s.set_parameters({"lockstep": False})
    assert r.s.set_parameters({"lockstep_timeout": 9.0}) == "" and r.s.cfg["lockstep_timeout"] == 9.0
    r.s.close()


def test_free_running_is_unchanged_by_the_lockstep_machinery(tmp_path):
    """Without lockstep, commands do not make ticks: the wall clock does (pacing.py)."""
    r = Run(tmp_path, real_time_factor=1.0)
    r.s.command("steering_angle", 0.1)
    assert r.firings(3, wall=0.0) == [0, 0, 0]
    assert r.firings(3) == [1, 1, 1]
    r.s.close()
    np.testing.assert_equal(r.s.sim.ticks, 3)


def test_a_report_of_a_run_that_measured_nothing_is_strict_json():
    """An example controller interrupted before its first sample has figures of NaN (max, RMS of
    nothing): the --report writer makes them null, so any JSON reader takes the file."""
    import json

    from mta_sim_ros.writing import json_text

    figures = {"samples": 0, "max_m": math.nan, "rms_m": math.nan, "gain": [1.0, math.inf], "centre": None}
    text = json_text(figures)

    def refuse(constant):
        raise ValueError(f"not JSON: {constant}")

    parsed = json.loads(text, parse_constant=refuse)  # NaN, Infinity are not JSON
    assert parsed == {"samples": 0, "max_m": None, "rms_m": None, "gain": [1.0, None], "centre": None}
