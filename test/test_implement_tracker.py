"""One control law, two drivers: the implement-tracking controller fed pose by pose
(controllers/implement/tracker.py, what its node runs) against the offline loop (loop.drive). Fed
the offline run's states tick by tick, the tracker answers the commands the loop held, bit for bit:
the steering, the speed set-point and whether the implement is lowered (which model the loop
stepped), compiled and as plain Python."""
from __future__ import annotations

import math

import numpy as np
import pytest

from mta_sim_ros.config import resolve_config_path
from mta_sim_ros.controllers.implement import drive, loop
from mta_sim_ros.controllers.implement.tracker import Tracker
from mta_sim_ros.physics import loader

import fieldroutes as fr

DEFAULT = loader.load_train(resolve_config_path("trains/default.yaml"))
FIELD = fr.rectangle(2000.0, 2000.0)
#: a swath, a turn, a lifted stretch and a cusp into a reversed one: every branch of the law
PIECES = [fr.line(30.0, "swath", True, index=0), fr.arc(10.0, math.pi / 2), fr.line(15.0, "turn", False),
          fr.line(10.0, "turn", False, reverse=True), fr.line(5.0, "turn", False),
          fr.line(25.0, "swath", True, index=1)]


def states(rows: np.ndarray, n: int) -> np.ndarray:
    """The state each trace row was written at, as far as the law reads it: A_1, the headings,
    the steering and V (the governor's integral, unread, 0)."""
    y = np.zeros((rows.shape[0], n + 5))
    y[:, 0], y[:, 1] = rows[:, loop.T_AX], rows[:, loop.T_AY]
    for k in range(n):
        y[:, 2 + k] = rows[:, loop.TRACE_HEAD + loop.TRACE_CART * k + loop.T_TH]
    y[:, n + 2], y[:, n + 3] = rows[:, loop.T_STEERING], rows[:, loop.T_SPEED]
    return y


@pytest.mark.parametrize("compiled", [True, False])
def test_the_tracker_fed_the_offline_states_answers_the_offline_commands_bit_for_bit(compiled):
    route, segments = fr.route_of(PIECES, (100.0, 100.0), 0.3)
    plan = fr.plan_of(FIELD, route, segments, DEFAULT.implement.width)
    run = drive.run_field(plan, DEFAULT, start_offset=0.3, compiled=compiled)
    assert run.trace.verdict == "ok", run.trace.reason
    rows = run.rows
    assert rows.shape[0] > 300 and (rows[:, loop.T_SPEED] < 0).any() and not rows[:, loop.T_LOWERED].all()
    tracker = Tracker(route, DEFAULT, compiled=compiled)
    assert tracker.compiled == compiled
    answers = [tracker.answer_state(y) for y in states(rows, DEFAULT.n)[:-1]]
    # the command at state i is held over tick i, written in row i + 1
    np.testing.assert_array_equal([a.steering for a in answers], rows[1:, loop.T_COMMAND])
    np.testing.assert_array_equal([a.speed for a in answers], rows[1:, loop.T_SET_SPEED])
    np.testing.assert_array_equal([a.lowered for a in answers], rows[:-1, loop.T_LOWERED] != 0.0)
    np.testing.assert_array_equal([a.error for a in answers], rows[:-1, loop.T_ERROR])
    np.testing.assert_array_equal([a.point[:2] for a in answers], rows[:-1, loop.T_WX:loop.T_WY + 1])
    assert answers[0].steering == rows[0, loop.T_COMMAND]
    last = tracker.answer_state(states(rows, DEFAULT.n)[-1])
    assert last.finished and tracker.done


def test_the_tracker_from_a_pose_reads_the_hitch_points_and_headings():
    """answer(points, th, psi, V) is answer_state of the state they make: A_1 is the first point."""
    route, segments = fr.route_of([fr.line(50.0, "swath", True, index=0)], (10.0, 10.0), 0.0)
    a, b = Tracker(route, DEFAULT), Tracker(route, DEFAULT)
    th = [0.01 * k for k in range(DEFAULT.n)]
    points = [(18.0 + k, 10.5, 0.0) for k in range(DEFAULT.n)]
    y = a.state(points, th, 0.02, 3.0)
    assert y[0] == 18.0 and y[1] == 10.5 and list(y[2:2 + DEFAULT.n]) == th
    assert a.answer(points, th, 0.02, 3.0) == b.answer_state(y)
