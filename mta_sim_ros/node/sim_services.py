"""The standard simulator services of ROS 2 (simulation_interfaces, REP 2017's draft; Gazebo, O3DE
and Isaac Sim offer them), answered by the node's RunSession.

Offered under the node's name, as Gazebo offers them under ``/gzserver`` (``/mta_sim/...``; in
a namespace ``/unit1/mta_sim/...``):

    get_simulator_features   GetSimulatorFeatures: what follows, and the tick in custom_info
    get_simulation_state     GetSimulationState: PLAYING, PAUSED, STOPPED (a halted run is PAUSED,
                             its reason in result.error_message: only a reset runs it again)
    set_simulation_state     SetSimulationState: PLAYING and PAUSED as the pause service;
                             STOPPED = reset and paused (read back STOPPED until it is played,
                             paused or stepped); QUITTING = the node finishes its bag and exits 0
                             once it has answered
    step_simulation          StepSimulation: ``steps`` ticks (1/publish_rate each) while paused, each
                             published and recorded as a tick of the running node, at once (no
                             wall clock; in lockstep no answer awaited); at most
                             run_session.MAX_STEPS a call; not paused: RESULT_OPERATION_FAILED
    reset_simulation         ResetSimulation: as the reset service: the train back at the scene's
                             start, a new bag; simulated time runs on (the /clock never goes
                             back: tf and every node on sim time would break), so scopes with
                             TIME (but DEFAULT and ALL) are RESULT_FEATURE_UNSUPPORTED; SPAWNED
                             alone has nothing to do

Nothing else of the standard applies to one train on a plane (no entities to spawn, no worlds
to load): those services are not offered and their features not listed. The node offers these
where simulation_interfaces is installed (an exec_depend; the venv of ``make venv`` builds it
from interfaces/), else its start-up log says it does not.
"""
from __future__ import annotations

from typing import Callable

from .. import __version__
from .run_session import MAX_STEPS, RunSession


def offer(node, session: RunSession, quit_: Callable[[], None], before_step: Callable[[], None] = lambda: None,
          interrupted: Callable[[], bool] = lambda: False) -> str:
    """Create the services on ``node``; returns '' or why they are not offered. ``quit_`` is
    called for SetSimulationState QUITTING (the node ends once the answer is sent),
    ``before_step`` before each StepSimulation (the node hands the session the commands waiting,
    so that a command sent before the call steers its first step), ``interrupted`` before each
    step's tick (the node's stop signal)."""
    try:
        from simulation_interfaces.msg import Result, SimulationState, SimulatorFeatures
        from simulation_interfaces.srv import (GetSimulationState, GetSimulatorFeatures, ResetSimulation,
                                               SetSimulationState, StepSimulation)
    except ImportError as err:
        return f"simulation_interfaces is not installed ({err})"
    answers = Answers(session, quit_, Result, SimulationState, SimulatorFeatures, SetSimulationState.Response,
                      ResetSimulation.Request, before_step, interrupted)
    node.sim_services = [
        node.create_service(GetSimulatorFeatures, "~/get_simulator_features", answers.features),
        node.create_service(GetSimulationState, "~/get_simulation_state", answers.get_state),
        node.create_service(SetSimulationState, "~/set_simulation_state", answers.set_state),
        node.create_service(StepSimulation, "~/step_simulation", answers.step),
        node.create_service(ResetSimulation, "~/reset_simulation", answers.reset),
    ]
    return ""


class Answers:
    """The service callbacks (request, response) -> response. The classes that hold the
    standard's constants are handed in (SetSimulationState's response, ResetSimulation's request),
    so that this module imports without simulation_interfaces."""

    def __init__(self, session: RunSession, quit_, Result, SimulationState, SimulatorFeatures,
                 SetSimulationState, ResetSimulation, before_step=lambda: None, interrupted=lambda: False):
        self.session, self.quit = session, quit_
        self.before_step, self.interrupted = before_step, interrupted
        self.R, self.S, self.F = Result, SimulationState, SimulatorFeatures
        self.Set, self.Reset = SetSimulationState, ResetSimulation
        self._stopped = False  # STOPPED asked; it holds while paused at the start (see stopped)

    @property
    def stopped(self) -> bool:
        """STOPPED was asked and nothing has run since: paused, not halted, no tick since the reset
        it made (whatever ran it: this service, the pause service, a step)."""
        s = self.session
        self._stopped = self._stopped and s.paused and not s.halted and s.sim.ticks == 0
        return self._stopped

    def _result(self, response, code: int, message: str = ""):
        response.result.result = code
        response.result.error_message = message
        return response

    def features(self, request, response):
        F = self.F
        response.features.features = [F.SIMULATION_RESET, F.SIMULATION_RESET_STATE, F.SIMULATION_STATE_GETTING,
                                      F.SIMULATION_STATE_SETTING, F.SIMULATION_STATE_PAUSE,
                                      F.STEP_SIMULATION_SINGLE, F.STEP_SIMULATION_MULTIPLE]
        response.features.spawn_formats = []
        response.features.custom_info = (
            f"mta_sim_ros {__version__}: one tractor train; a step is one tick of {self.session.sim.tick:g} s "
            f"of simulated time; at most {MAX_STEPS} steps a call; reset_simulation resets the state, "
            f"simulated time runs on; a halted run (jackknife, ...) runs again only after a reset")
        return response

    def get_state(self, request, response):
        s, S = self.session, self.S
        response.state.state = (S.STATE_STOPPED if self.stopped else S.STATE_PAUSED if s.paused or s.halted
                                else S.STATE_PLAYING)
        return self._result(response, self.R.RESULT_OK,
                            f"halted ({s.halted}): reset to run again" if s.halted else "")

    def set_state(self, request, response):
        S, s, target = self.S, self.session, request.state.state
        if target == S.STATE_QUITTING:
            self.quit()
            return self._result(response, self.R.RESULT_OK, "quitting: the bag is finished, then the node exits")
        if target == S.STATE_STOPPED:
            if self.stopped:
                return self._result(response, self.Set.ALREADY_IN_TARGET_STATE, "already stopped")
            message = s.reset()
            s.pause(True)
            self._stopped = True
            return self._result(response, self.R.RESULT_OK, f"stopped: {message}; paused")
        if target not in (S.STATE_PLAYING, S.STATE_PAUSED):
            return self._result(response, self.R.RESULT_FEATURE_UNSUPPORTED,
                                f"state {target}: this simulator can be set PLAYING (1), PAUSED (2), STOPPED (0) "
                                "or QUITTING (3); it has one world, always loaded")
        pausing = target == S.STATE_PAUSED
        if self.stopped:  # stopped -> paused (at the start) or playing
            self._stopped = False
            return self._result(response, self.R.RESULT_OK, "paused at the start" if pausing else s.pause(False))
        if target == S.STATE_PLAYING and s.halted:
            return self._result(response, self.Set.STATE_TRANSITION_ERROR,
                                f"halted ({s.halted}): reset it (reset_simulation) to run again")
        if pausing == s.paused:
            return self._result(response, self.Set.ALREADY_IN_TARGET_STATE,
                                "already paused" if pausing else "already playing")
        return self._result(response, self.R.RESULT_OK, s.pause(pausing))

    def step(self, request, response):
        self.before_step()
        done, why = self.session.step(int(request.steps), self.interrupted)
        if why:  # none ran (not paused, halted, too many), or a halt on the way
            return self._result(response, self.R.RESULT_OPERATION_FAILED, why)
        return self._result(response, self.R.RESULT_OK, f"{done} steps, t = {self.session.now:.6f} s")

    def reset(self, request, response):
        scope, Reset = request.scope, self.Reset
        known = Reset.SCOPE_TIME | Reset.SCOPE_STATE | Reset.SCOPE_SPAWNED
        if scope != Reset.SCOPE_ALL and scope & ~known:
            return self._result(response, self.R.RESULT_FEATURE_UNSUPPORTED,
                                f"scope {scope}: bits the standard does not define (SCOPE_TIME 1, SCOPE_STATE 2, "
                                "SCOPE_SPAWNED 4, or SCOPE_ALL 255)")
        if scope & Reset.SCOPE_TIME and scope != Reset.SCOPE_ALL:
            return self._result(response, self.R.RESULT_FEATURE_UNSUPPORTED,
                                f"scope {scope}: simulated time never goes back here (tf and every node on /clock "
                                "would break): reset with scope STATE, ALL or DEFAULT, and time runs on")
        if scope in (Reset.SCOPE_DEFAULT, Reset.SCOPE_ALL) or scope & Reset.SCOPE_STATE:
            return self._result(response, self.R.RESULT_OK,
                                f"{self.session.reset()}; simulated time runs on (the /clock never goes back)")
        return self._result(response, self.R.RESULT_OK, "nothing was spawned: nothing to reset")  # SCOPE_SPAWNED
