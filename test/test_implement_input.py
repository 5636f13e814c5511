"""The implement lowered or lifted, an input of the simulator (implement_lowered, std_msgs/Bool):
the run switches between two constant levels built once (physics.levels.lifted: the implement
cart's draft off), held like the other commands (node/commands.py), recorded, re-simulated, a
lockstep answer; and lockstep answers made of several topics (lockstep_answer). In process, with
a set clock (test_session.Run)."""
from __future__ import annotations

import numpy as np
import pytest
from test_session import SCENE, Run

from mta_sim_ros.analysis import resimulate
from mta_sim_ros.bag import read_messages
from mta_sim_ros.bag.cdr import encode
from mta_sim_ros.messages.decode import CommandDecodeError, decode_bool
from mta_sim_ros.node.params import ConfigError
from mta_sim_ros.physics.levels import lifted
from mta_sim_ros.physics.loader import load_scene
from mta_sim_ros.physics.spec import GRAVITY
from mta_sim_ros.run.simulation import Simulation

TRAIN = load_scene(str(SCENE)).train


def boolean(value: bool) -> bytes:
    return encode("std_msgs/msg/Bool", {"data": value})


def test_bool_bytes_are_read_as_rclpy_writes_them():
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Bool

    for value in (True, False):
        assert decode_bool(serialize_message(Bool(data=value))) is value
        assert decode_bool(boolean(value)) is value
    with pytest.raises(CommandDecodeError):
        decode_bool(b"\x00\x01\x00\x00")
    assert decode_bool(b"\x00\x01\x00\x00\x07") is True  # any byte but 0, as rclpy reads it


def test_lifted_takes_the_implement_carts_draft_off_and_nothing_else():
    up = lifted(TRAIN)
    assert up is not TRAIN and up.draft == tuple(d for d in TRAIN.draft if d.cart != TRAIN.implement.cart)
    assert up.carts == TRAIN.carts and up.rolling == TRAIN.rolling and up.implement == TRAIN.implement
    assert lifted(up) is up  # nothing left to lift: the train itself


def test_a_simulation_lifts_the_implement_between_two_levels_built_once():
    """Lifted, the steady traction power is the rolling resistance times the speed; lowered again,
    the draft comes back; the levels are the same two objects throughout (the lifted one built when
    first held), a reset lowers it."""
    sim = Simulation(load_scene(str(SCENE)), fidelity="dynamic")
    lowered = sim.levels[True]
    assert sim.model is lowered and False not in sim.levels  # a run never lifted builds no second level
    rolling = sum(r.coefficient * TRAIN.carts[TRAIN.cart_index(r.cart)].mass for r in TRAIN.rolling) * GRAVITY
    draft = sum(d.A * d.width * d.depth * d.soil_factor for d in TRAIN.draft)
    v = sim.v_set
    for _ in range(300):
        sim.advance(0.0, v)
    assert sim.outputs().power == pytest.approx((rolling + draft) * v, rel=2e-3)
    sim.set_lowered(False)
    up = sim.levels[False]
    assert up is not lowered and up.train.draft != lowered.train.draft
    for _ in range(1500):
        sim.advance(0.0, v)
    assert sim.model is up and sim.outputs().power == pytest.approx(rolling * v, rel=2e-3)
    sim.set_lowered(True)
    assert sim.model is lowered and sim.levels[False] is up
    sim.set_lowered(False)
    sim.reset()
    assert sim.lowered and sim.model is lowered


def test_implement_lowered_is_held_recorded_said_and_resimulated(tmp_path):
    """Lowered until commanded; each Bool sets it, a malformed one is refused (counted, said); the
    bag holds the bytes as received and mta replay --resimulate holds what the node held."""
    r = Run(tmp_path)
    r.ticks(5)
    assert r.s.sim.lowered and r.s.diagnostics().values["implement_lowered"] is True
    r.s.command_message("implement_lowered", boolean(False))
    r.ticks(30)
    assert not r.s.sim.lowered and r.s.sim.model is r.s.sim.levels[False]
    r.s.command_message("implement_lowered", boolean(True))
    r.ticks(30)
    assert r.s.sim.lowered
    r.s.reset()
    assert r.s.inputs.lowered and r.s.sim.lowered
    r.s.close()
    first = r.bags()[0]
    values = [m.data for _, _, m in read_messages(str(first), ["/implement_lowered"])]
    assert values == [False, True]
    assert resimulate(str(first)).identical


def test_a_truncated_implement_lowered_is_refused_and_said(tmp_path):
    r = Run(tmp_path)
    r.s.command_message("implement_lowered", boolean(False))
    r.s.command_message("implement_lowered", b"\x00\x01\x00\x00")  # refused: nothing set
    r.ticks(1)
    d = r.s.diagnostics()
    assert not r.s.sim.lowered and d.values["implement_lowered_rejected"] == 1 and "std_msgs/msg/Bool" in d.message
    r.s.close()


def test_a_lockstep_answer_of_three_topics_ticks_once_all_have_come(tmp_path):
    """lockstep_answer = steering_angle,speed_setpoint,implement_lowered: a tick once a message has
    come on each, whatever their order; a repeated one holds the latest and completes nothing."""
    r = Run(tmp_path, lockstep=True, lockstep_timeout=2.0,
            lockstep_answer="steering_angle,speed_setpoint,implement_lowered")
    assert sum(r.firings(1)) == 1
    orders = [("steering_angle", "speed_setpoint", "implement_lowered"),
              ("implement_lowered", "steering_angle", "steering_angle", "speed_setpoint")]
    for k, order in enumerate(orders):
        for i, topic in enumerate(order):
            assert sum(r.firings(2)) == 0
            if topic == "implement_lowered":
                r.s.command_message(topic, boolean(k % 2 == 1))
            else:
                r.s.command(topic, 0.01 * (k + i + 1))
        assert sum(r.firings(3)) == 1
        assert r.s.sim.lowered is (k % 2 == 1)
    assert r.s.sim.ticks == 3 and r.s.sim.command == pytest.approx(0.01 * (1 + 2 + 1))


@pytest.mark.parametrize("value", ["steering_angle,nope", "steering_angle;speed_setpoint"])
def test_lockstep_answer_names_command_topics(tmp_path, value):
    with pytest.raises(ConfigError, match="lockstep_answer"):
        Run(tmp_path, lockstep=True, lockstep_answer=value)


def test_free_running_ignores_the_lockstep_answer_and_lifts_as_commanded(tmp_path):
    r = Run(tmp_path, lockstep_answer="steering_angle,implement_lowered")
    r.s.command_message("implement_lowered", boolean(False))
    r.ticks(3)
    assert r.s.sim.ticks == 3 and not r.s.sim.lowered
    np.testing.assert_array_equal(r.s.sim.levels[True].train.draft, TRAIN.draft)
