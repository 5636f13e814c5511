"""The standard simulator services (simulation_interfaces; mta_sim_ros/node/sim_services.py).

In process first, time set (test_session.Run): a step runs exactly the ticks asked, the same
ticks the running node would have run (byte for byte), only while paused; the services' answers
with simulation_interfaces' own message classes. Then over real DDS: the node in another process
in a namespace, its services called by the test's node, the steps counted in what it publishes,
QUITTING ends it with a complete bag.
"""
from __future__ import annotations

import pytest
from dds import Probe, bags_in, read_bag, start_node, stop, write_params
from geometry_msgs.msg import PoseArray
from simulation_interfaces.msg import Result, SimulationState, SimulatorFeatures
from simulation_interfaces.srv import (GetSimulationState, GetSimulatorFeatures, ResetSimulation, SetSimulationState,
                                       StepSimulation)
from test_session import SCENE, TICK, Run, run  # noqa: F401 (run: the fixture)

from mta_sim_ros.bag import read_messages
from mta_sim_ros.node.run_session import MAX_STEPS
from mta_sim_ros.node.sim_services import Answers

PLAYING, PAUSED, STOPPED, QUITTING = (SimulationState.STATE_PLAYING, SimulationState.STATE_PAUSED,
                                      SimulationState.STATE_STOPPED, SimulationState.STATE_QUITTING)


def test_a_step_runs_exactly_the_ticks_the_running_node_would_have_run(tmp_path):
    """3 ticks, pause, 7 steps: the same /hitch_poses bytes (stamps included) as 10 ticks of a
    second session, and simulated time 10 ticks on; the timer's firings run nothing after."""
    stepped, ticked = Run(tmp_path / "a"), Run(tmp_path / "b")
    try:
        for r in (stepped, ticked):
            r.s.command("steering_angle", 0.2)
        stepped.ticks(3)
        stepped.s.pause(True)
        assert stepped.s.step(7) == (7, "")
        ticked.ticks(10)
        assert stepped.topic("/hitch_poses") == ticked.topic("/hitch_poses")
        assert stepped.s.sim.ticks == 10 and stepped.s.now == ticked.s.now == pytest.approx(10 * TICK, rel=1e-12)
        assert stepped.s.paused and stepped.firings(5) == [0] * 5
    finally:
        stepped.s.close()
        ticked.s.close()
    [bag] = stepped.bags()  # every step recorded as a tick
    assert len(list(read_messages(str(bag), ["/hitch_poses"]))) == 10


def test_a_step_is_refused_running_halted_or_too_long_and_zero_steps_do_nothing(run):
    assert run.s.step(1) == (0, "the simulation is not paused: pause it first (SetSimulationState PAUSED, "
                                "or the pause service)")
    run.s.pause(True)
    done, why = run.s.step(MAX_STEPS + 1)
    assert done == 0 and why.startswith(f"steps {MAX_STEPS + 1}: at most {MAX_STEPS} a call")
    assert run.s.step(0) == (0, "") and run.s.sim.ticks == 0
    run.s.command("steering_angle", 0.45)  # no steady turn: the seeder jackknifes (test_session)
    done, why = run.s.step(5000)
    assert 0 < done < 5000 and why.startswith(f"the simulation halted after {done} of 5000 steps: jackknife")
    assert run.s.step(1) == (0, f"the simulation halted ({run.s.halted}): reset it to run again")


def test_in_lockstep_steps_need_no_answer_and_the_first_firing_after_ticks(tmp_path):
    r = Run(tmp_path, lockstep=True, lockstep_timeout=2.0)
    try:
        r.s.pause(True)
        assert r.s.step(4) == (4, "") and r.s.sim.ticks == 4  # no command came: none answered
        r.s.pause(False)
        assert sum(r.firings(3, wall=0.01)) == 1  # step 1 again, then it waits for an answer
    finally:
        r.s.close()


class Quit:
    def __init__(self):
        self.called = 0

    def __call__(self):
        self.called += 1


def answers(run, quit_=None):
    return Answers(run.s, quit_ or Quit(), Result, SimulationState, SimulatorFeatures, SetSimulationState.Response,
                   ResetSimulation.Request)


def call(handler, srv, **fields):
    request = srv.Request(**fields)
    return handler(request, srv.Response())


def set_state(a, state):
    return call(a.set_state, SetSimulationState, state=SimulationState(state=state)).result


def test_the_features_are_what_the_node_answers(run):
    a = answers(run)
    features = call(a.features, GetSimulatorFeatures).features
    F = SimulatorFeatures
    assert sorted(features.features) == sorted([F.SIMULATION_RESET, F.SIMULATION_RESET_STATE,
                                                F.SIMULATION_STATE_GETTING, F.SIMULATION_STATE_SETTING,
                                                F.SIMULATION_STATE_PAUSE, F.STEP_SIMULATION_SINGLE,
                                                F.STEP_SIMULATION_MULTIPLE])
    assert f"one tick of {TICK:g} s" in features.custom_info and list(features.spawn_formats) == []


def test_states_are_set_and_got_with_the_standards_result_codes(run):
    a = answers(run)
    assert call(a.get_state, GetSimulationState).state.state == PLAYING
    assert set_state(a, PLAYING).result == SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    assert set_state(a, PAUSED).result == Result.RESULT_OK and run.s.paused
    assert call(a.get_state, GetSimulationState).state.state == PAUSED
    assert set_state(a, PAUSED).result == SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    step = call(a.step, StepSimulation, steps=3).result
    assert step.result == Result.RESULT_OK and run.s.sim.ticks == 3
    assert set_state(a, PLAYING).result == Result.RESULT_OK and not run.s.paused
    refused = call(a.step, StepSimulation, steps=3).result
    assert refused.result == Result.RESULT_OPERATION_FAILED and "not paused" in refused.error_message
    for state in (SimulationState.STATE_NO_WORLD, SimulationState.STATE_LOADING_WORLD, 99):
        r = set_state(a, state)
        assert r.result == Result.RESULT_FEATURE_UNSUPPORTED and r.error_message.startswith(f"state {state}: ")


def test_stopped_is_a_reset_and_paused_and_quitting_asks_the_node_to_end(run):
    run.ticks(5)
    quit_ = Quit()
    a = answers(run, quit_)
    r = set_state(a, STOPPED)
    assert r.result == Result.RESULT_OK and r.error_message.startswith("stopped: reset to the start")
    assert run.s.paused and run.s.sim.ticks == 0 and len(list(run.bag_dir.glob("*.mcap"))) == 2  # a new run
    assert call(a.get_state, GetSimulationState).state.state == STOPPED
    assert set_state(a, STOPPED).result == SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    assert len(list(run.bag_dir.glob("*.mcap"))) == 2  # no second reset
    assert set_state(a, PAUSED).result == Result.RESULT_OK and run.s.paused
    assert call(a.get_state, GetSimulationState).state.state == PAUSED
    assert set_state(a, STOPPED).result == Result.RESULT_OK  # stopped again: reset again
    assert call(a.step, StepSimulation, steps=2).result.result == Result.RESULT_OK
    assert call(a.get_state, GetSimulationState).state.state == PAUSED and run.s.sim.ticks == 2
    set_state(a, STOPPED)
    assert set_state(a, PLAYING).result == Result.RESULT_OK and not run.s.paused
    assert call(a.get_state, GetSimulationState).state.state == PLAYING
    assert set_state(a, QUITTING).result == Result.RESULT_OK and quit_.called == 1


def test_a_halted_run_is_paused_with_its_reason_and_plays_only_after_a_reset(run):
    a = answers(run)
    run.s.command("steering_angle", 0.45)
    while not run.s.halted:
        run.ticks(1)
    got = call(a.get_state, GetSimulationState)
    assert got.state.state == PAUSED and got.result.error_message.startswith("halted (jackknife")
    r = set_state(a, PLAYING)
    assert r.result == SetSimulationState.Response.STATE_TRANSITION_ERROR and "reset_simulation" in r.error_message
    assert call(a.reset, ResetSimulation, scope=ResetSimulation.Request.SCOPE_DEFAULT).result.result == Result.RESULT_OK
    assert not run.s.halted and call(a.get_state, GetSimulationState).state.state == PLAYING


@pytest.mark.parametrize("scope, code, resets", [
    (ResetSimulation.Request.SCOPE_DEFAULT, Result.RESULT_OK, True),
    (ResetSimulation.Request.SCOPE_ALL, Result.RESULT_OK, True),
    (ResetSimulation.Request.SCOPE_STATE, Result.RESULT_OK, True),
    (ResetSimulation.Request.SCOPE_STATE | ResetSimulation.Request.SCOPE_SPAWNED, Result.RESULT_OK, True),
    (ResetSimulation.Request.SCOPE_SPAWNED, Result.RESULT_OK, False),
    (ResetSimulation.Request.SCOPE_TIME, Result.RESULT_FEATURE_UNSUPPORTED, False),
    (ResetSimulation.Request.SCOPE_TIME | ResetSimulation.Request.SCOPE_STATE, Result.RESULT_FEATURE_UNSUPPORTED, False),
    (8, Result.RESULT_FEATURE_UNSUPPORTED, False),
    (8 | ResetSimulation.Request.SCOPE_STATE, Result.RESULT_FEATURE_UNSUPPORTED, False),
    (254, Result.RESULT_FEATURE_UNSUPPORTED, False),
])
def test_reset_scopes(run, scope, code, resets):
    """Simulated time never goes back (the node's reset): scopes with TIME but ALL are refused."""
    run.ticks(5)
    t = run.s.now
    result = call(answers(run).reset, ResetSimulation, scope=scope).result
    assert result.result == code
    assert (run.s.sim.ticks == 0) == resets and run.s.now == t  # time runs on either way


# -- over DDS -----------------------------------------------------------------------------------------

@pytest.mark.dds
def test_the_services_over_dds_step_a_node_in_a_namespace_and_quit_it(tmp_path, probe: Probe):
    params = write_params(tmp_path / "params.yaml", scene_file=str(SCENE), bag_dir=str(tmp_path / "bags"),
                          publish_rate=50.0, real_time_factor=1.0, watchdog_timeout=0.0, record=True)
    node = start_node(params, tmp_path / "node.log", ros_args=["-r", "__ns:=/unit1"])
    base = "/unit1/mta_sim/"
    try:
        poses = probe.subscribe("/unit1/hitch_poses", PoseArray, qos=100)  # the steps come in a burst
        assert probe.spin_until(lambda: len(poses) >= 3 or node.poll() is not None, 30.0), "no output"
        features = probe.call(GetSimulatorFeatures, base + "get_simulator_features", GetSimulatorFeatures.Request())
        assert SimulatorFeatures.STEP_SIMULATION_MULTIPLE in features.features.features
        paused = probe.call(SetSimulationState, base + "set_simulation_state",
                            SetSimulationState.Request(state=SimulationState(state=PAUSED)))
        assert paused.result.result == Result.RESULT_OK
        reply = probe.call(StepSimulation, base + "step_simulation", StepSimulation.Request(steps=25))
        assert reply.result.result == Result.RESULT_OK, reply.result.error_message
        end = round(float(reply.result.error_message.split("t = ")[1].split()[0]) * 1e9)  # "25 steps, t = 3.2 s"

        def stamps():
            return [p.header.stamp.sec * 10**9 + p.header.stamp.nanosec for p in poses]

        assert probe.spin_until(lambda: end in stamps(), 10.0)
        last = stamps()[stamps().index(end) - 25:stamps().index(end) + 1]
        assert [b - a for a, b in zip(last, last[1:])] == [20_000_000] * 25  # the steps: one tick (50 Hz) each
        state = probe.call(GetSimulationState, base + "get_simulation_state", GetSimulationState.Request())
        assert state.state.state == PAUSED
        quit_ = probe.call(SetSimulationState, base + "set_simulation_state",
                           SetSimulationState.Request(state=SimulationState(state=QUITTING)))
        assert quit_.result.result == Result.RESULT_OK
        assert node.wait(timeout=20) == 0
    finally:
        stop(node)
    [bag] = bags_in(tmp_path / "bags")  # a finished bag (rosbags reads its summary), every tick in it
    recorded = [t for t, _ in read_bag(bag)["/unit1/hitch_poses"]]
    assert recorded == [20_000_000 * (i + 1) for i in range(len(recorded))] and recorded[-1] == end


def test_stopped_ends_when_anything_runs_the_train_and_a_stop_signal_ends_a_step(run):
    a = answers(run)
    set_state(a, STOPPED)
    run.s.pause(False)  # the pause service (std_srvs/SetBool), not these services
    run.ticks(3)
    run.s.pause(True)
    assert call(a.get_state, GetSimulationState).state.state == PAUSED
    assert set_state(a, STOPPED).result == Result.RESULT_OK and run.s.sim.ticks == 0  # a real reset again
    asked = []
    done, why = run.s.step(1000, interrupted=lambda: asked.append(1) or len(asked) > 10)
    assert (done, why) == (10, "interrupted after 10 of 1000 steps: the node is stopping")


def test_a_step_first_hands_the_session_the_commands_waiting(run):
    """The node's hook (sim_node: _take_commands) runs before the step: a command published just
    before the call steers its first tick."""
    order = []
    a = Answers(run.s, Quit(), Result, SimulationState, SimulatorFeatures, SetSimulationState.Response,
                ResetSimulation.Request, before_step=lambda: order.append(("taken", run.s.sim.ticks)))
    run.s.pause(True)
    call(a.step, StepSimulation, steps=2)
    assert order == [("taken", 0)] and run.s.sim.ticks == 2


@pytest.mark.dds
def test_sigterm_ends_a_long_step_at_once_with_a_complete_bag(tmp_path, probe: Probe):
    params = write_params(tmp_path / "params.yaml", scene_file=str(SCENE), bag_dir=str(tmp_path / "bags"),
                          publish_rate=50.0, real_time_factor=1.0, watchdog_timeout=0.0, record=True)
    node = start_node(params, tmp_path / "node.log")
    try:
        poses = probe.subscribe("/hitch_poses", PoseArray, qos=100)
        assert probe.spin_until(lambda: len(poses) >= 3 or node.poll() is not None, 30.0), "no output"
        paused = probe.call(SetSimulationState, "/mta_sim/set_simulation_state",
                            SetSimulationState.Request(state=SimulationState(state=PAUSED)))
        assert paused.result.result == Result.RESULT_OK
        client = probe.node.create_client(StepSimulation, "/mta_sim/step_simulation")
        assert client.wait_for_service(timeout_sec=10)
        client.call_async(StepSimulation.Request(steps=MAX_STEPS))  # ~20-40 s of work
        before = len(poses)
        assert probe.spin_until(lambda: len(poses) > before + 200, 30.0), "the steps did not start"
        assert stop(node, timeout=10.0) == 0  # the step stops at the signal, the bag is finished
    finally:
        stop(node)
    [bag] = bags_in(tmp_path / "bags")
    recorded = len(read_bag(bag)["/hitch_poses"])
    assert before + 200 < recorded < MAX_STEPS, recorded
