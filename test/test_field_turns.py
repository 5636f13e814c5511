"""Continuous-curvature turns (field/clothoid.py, turning.py, turns.py, headlands.py, order.py)
against closed forms and independent references: a clothoid's heading (kappa0 s + sigma s^2 / 2)
and its points against the Fresnel integrals (scipy.special.fresnel), a CC turn's closed-form end
against its moves integrated, turns landing on the next swath's start pose, the steering a planned
turn asks of the tractor (the chain's inverse, the controller's feedforward) against the guard,
the headland rings' corners against the turn radius and their edges against the offset, and the
skip orders' spans. The closed loop on a whole rectangle: test_field_drive.py."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import fresnel
from shapely import geometry as sg

from mta_sim_ros.field.boundary import field_from_yaml
from mta_sim_ros.field.clothoid import (Curves, bulb_moves, cc_displacement, cc_dubins_paths, cc_turn,
                                        fishtail_moves, min_u, u_moves)
from mta_sim_ros.field.headlands import headlands
from mta_sim_ros.field.order import sequence, spans
from mta_sim_ros.field.plan import plan_field
from mta_sim_ros.field.route import Move, Pose, end_of, moves_stretch, sample_move, wrap
from mta_sim_ros.field.turning import (SLACK, STEERING_ROOM, check_path, demand, guarded_steering, lead_length,
                                       ring_curves, steady_radius, turning)
from mta_sim_ros.field.turns import turn_moves
from mta_sim_ros.field.types import PlanOptions
from mta_sim_ros.physics.loader import load_train

DEFAULT = load_train("config/trains/default.yaml")
CURVES = Curves(9.0, 1.0 / (9.0 * 15.0))


def fresnel_point(phi0: float, kappa0: float, sigma: float, s: float) -> np.ndarray:
    """The point s along a clothoid from the origin (heading phi0, curvature kappa0, sharpness
    sigma > 0): the heading completed to a square, phi0 - kappa0^2 / (2 sigma) + sigma u^2 / 2 with
    u = s + kappa0 / sigma, integrated by the Fresnel integrals C, S (of pi t^2 / 2)."""
    scale = math.sqrt(math.pi / sigma)
    c = phi0 - kappa0**2 / (2.0 * sigma)
    S0, C0 = fresnel(kappa0 / sigma / scale)
    S1, C1 = fresnel((s + kappa0 / sigma) / scale)
    dC, dS = C1 - C0, S1 - S0
    return scale * np.array([math.cos(c) * dC - math.sin(c) * dS, math.sin(c) * dC + math.cos(c) * dS])


@pytest.mark.parametrize("phi0, kappa0, sigma, length", [(0.0, 0.0, 0.01, 30.0), (0.7, 0.05, 0.004, 25.0),
                                                         (-2.0, -0.11, 0.0075, 40.0), (1.0, 0.2, 0.02, 12.0)])
def test_a_clothoids_heading_is_quadratic_and_its_points_the_fresnel_integrals(phi0, kappa0, sigma, length):
    xy, heading, curvature = sample_move(Pose(0.0, 0.0, phi0), Move(length, kappa0, sharpness=sigma), 0.5)
    s = np.linspace(0.0, length, len(xy))
    assert heading == pytest.approx(phi0 + kappa0 * s + 0.5 * sigma * s**2, abs=1e-12)
    assert curvature == pytest.approx(kappa0 + sigma * s, abs=1e-12)  # linear in s
    for i in (len(xy) // 3, len(xy) - 1):
        assert xy[i] == pytest.approx(fresnel_point(phi0, kappa0, sigma, s[i]), abs=1e-9)
    pose = end_of(Pose(0.0, 0.0, phi0), Move(length, kappa0, sharpness=sigma))
    assert (pose.x, pose.y) == pytest.approx(tuple(fresnel_point(phi0, kappa0, sigma, length)), abs=1e-9)


def test_a_clothoid_driven_the_other_way_mirrors():
    a = sample_move(Pose(0.0, 0.0, 0.0), Move(20.0, 0.0, sharpness=0.01), 0.5)[0]
    b = sample_move(Pose(0.0, 0.0, 0.0), Move(20.0, 0.0, sharpness=-0.01), 0.5)[0]
    assert b == pytest.approx(a * np.array([1.0, -1.0]), abs=1e-12)


@pytest.mark.parametrize("beta", [0.05, 0.6, 1.2, 0.5 * math.pi, 2.5, math.pi, 4.5, -1.0, -math.pi])
def test_a_cc_turn_is_continuous_and_its_closed_form_end_its_moves(beta):
    moves = cc_turn(beta, CURVES)
    assert moves[0].curvature == 0.0 and moves[-1].end_curvature == pytest.approx(0.0, abs=1e-12)
    for a, b in zip(moves, moves[1:]):
        assert b.curvature == pytest.approx(a.end_curvature, abs=1e-12)  # no jump
    assert max(abs(m.curvature) for m in moves) <= 1.0 / CURVES.radius + 1e-12
    assert sum(m.turn for m in moves) == pytest.approx(beta, abs=1e-12)
    pose = Pose(0.0, 0.0, 0.0)
    for move in moves:
        pose = end_of(pose, move)
    assert cc_displacement(beta, CURVES) == pytest.approx((pose.x, pose.y), abs=1e-9)


@pytest.mark.parametrize("kind, offset, along", [("u", 24.0, 0.0), ("u", -36.0, 7.5), ("u", 60.0, -12.0),
                                                 ("bulb", 12.0, 3.0), ("fishtail", -12.0, 0.0)])
def test_a_turn_ends_exactly_on_the_next_swaths_start_pose(kind, offset, along):
    end = Pose(100.0, 50.0, 0.4)
    u, left = np.array([math.cos(0.4), math.sin(0.4)]), np.array([-math.sin(0.4), math.cos(0.4)])
    goal_xy = end.xy + along * u + offset * left
    goal = Pose(float(goal_xy[0]), float(goal_xy[1]), 0.4 + math.pi)
    moves = turn_moves(kind, end, goal, CURVES)
    pose = end
    for move in moves:
        pose = end_of(pose, move)
    assert (pose.x, pose.y) == pytest.approx((goal.x, goal.y), abs=1e-9)
    assert math.remainder(pose.heading - goal.heading, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    forward = [m for m in moves if not m.reverse]
    for a, b in zip(forward, forward[1:]):
        assert b.curvature == pytest.approx(a.end_curvature, abs=1e-12)


def test_a_u_turn_narrower_than_two_quarters_is_a_widened_half_turn():
    for width in (min_u(CURVES), 0.5 * (min_u(CURVES) + 40.0)):
        moves = u_moves(width, CURVES)
        assert max(abs(m.curvature) for m in moves) <= 1.0 / CURVES.radius + 1e-12
        assert end_of(end_of(end_of(Pose(0, 0, 0), moves[0]), moves[1]), moves[2]).y == pytest.approx(width)
    bulb = bulb_moves(5.0, CURVES)
    assert bulb[0].curvature == 0.0 and bulb[-1].end_curvature == pytest.approx(0.0, abs=1e-12)
    assert all(b.curvature == pytest.approx(a.end_curvature, abs=1e-12) for a, b in zip(bulb, bulb[1:]))
    assert sum(m.reverse for m in fishtail_moves(5.0, CURVES)) == 1


def test_cc_dubins_paths_reach_their_goal_without_a_curvature_jump():
    rng = np.random.default_rng(3)
    found = 0
    for _ in range(40):
        a, b = Pose(0.0, 0.0, 0.0), Pose(*rng.uniform(-80, 80, 2), rng.uniform(-4, 4))
        for moves in cc_dubins_paths(a, b, CURVES):
            found += 1
            pose = a
            for move in moves:
                pose = end_of(pose, move)
            assert (pose.x, pose.y) == pytest.approx((b.x, b.y), abs=1e-6)
            assert wrap(pose.heading - b.heading) == pytest.approx(0.0, abs=1e-6)
            for m0, m1 in zip(moves, moves[1:]):
                assert m1.curvature == pytest.approx(m0.end_curvature, abs=1e-12)
    assert found >= 40


# --------------------------------------------------------------------------- followable


@pytest.fixture(scope="module")
def rect_plan():
    field = field_from_yaml({"boundary": [[0, 0], [400, 0], [400, 250], [0, 250]], "headlands": 2,
                             "entry": [0, 0]}, "rectangle.yaml")
    return plan_field(field, DEFAULT, PlanOptions(width=12.0))


def test_every_planned_turn_asks_a_steering_inside_the_guard(rect_plan):
    """The chain's inverse along each turn of the plan, with the swaths before and after it: the
    feedforward stays STEERING_ROOM inside the forward guard (up to SLACK, what a shape checked after
    the bisection may pass it by)."""
    limit = (guarded_steering(DEFAULT) - STEERING_ROOM) * (1.0 + SLACK)
    route = rect_plan.route
    turns = [s for s in rect_plan.segments if s.kind == "turn"]
    assert len(turns) == 14
    for seg in turns:
        a, b = max(seg.first - 160, 0), min(seg.last + 160, len(route.s) - 1)
        found = demand(DEFAULT, np.column_stack([route.xy[a:b + 1], route.heading[a:b + 1]]))
        assert found.steering <= limit


def test_the_same_check_flags_a_u_of_arcs_at_the_steady_radius():
    """The check can fail: a U of arcs at the radius of the steady circle at the limit (curvature
    jumps) asks far more than the guard."""
    turn = turning(DEFAULT, 12.0)
    limit = guarded_steering(DEFAULT) - STEERING_ROOM
    arcs = Curves(steady_radius(DEFAULT, limit, turn.cart, turn.offset))
    found = demand(DEFAULT, check_path(arcs, lead_length(DEFAULT), u_moves(2.0 * arcs.radius + 1.0, arcs)))
    assert found.steering > guarded_steering(DEFAULT)
    at_turn = demand(DEFAULT, check_path(turn.curves, lead_length(DEFAULT)))
    assert at_turn.steering <= limit + 1e-12 and turn.radius > arcs.radius


# --------------------------------------------------------------------------- rings


def test_the_rings_corners_are_no_tighter_than_the_turns_and_their_edges_on_the_offset():
    field = sg.Polygon([(0, 0), (400, 0), (400, 250), (0, 250)])
    turn = turning(DEFAULT, 12.0)
    curves = ring_curves(DEFAULT, turn, 3.0)
    assert curves.radius >= turn.radius
    band = headlands(field, 3, 12.0, curves.radius, 0.5, curves)
    for i, ring in enumerate(band.rings):
        xy = np.asarray(ring.coords)[:-1]
        a, b, c = xy, np.roll(xy, -1, axis=0), np.roll(xy, -2, axis=0)
        cross = (b - a)[:, 0] * (c - b)[:, 1] - (b - a)[:, 1] * (c - b)[:, 0]
        circle = 2 * cross / (np.hypot(*(b - a).T) * np.hypot(*(c - b).T) * np.hypot(*(c - a).T))
        assert np.abs(circle).max() <= (1.0 + 1e-3) / turn.radius  # three points' circle: the ring's curvature
        offset = (i + 0.5) * 12.0
        assert ring.distance(field.boundary) == pytest.approx(offset, abs=1e-6)  # the edges stay on the offset
        assert ring.hausdorff_distance(field.boundary) > offset  # the corners are cut


# --------------------------------------------------------------------------- orders


@pytest.mark.parametrize("order", ["skip", "skip2", "skip3"])
def test_a_skip_orders_turns_span_at_least_its_spacings(order):
    m = spans(order)
    for count in range(1, 30):
        ranks = sequence(order, count)
        assert sorted(ranks) == list(range(count))
        gaps = [abs(b - a) for a, b in zip(ranks, ranks[1:])]
        if count >= 2 * m:
            assert min(gaps, default=m) >= m
            assert max(gaps, default=m) <= 3 * m  # no return across the cell: a block's start at most 3m on
