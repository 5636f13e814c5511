"""Coverage plans (mta_sim_ros/field/plan.py and its stages) against closed forms and independent
computations: a turn's reach against the path and box of a lone tractor written out here,
headland rings and the inner ground of a rectangle against their areas by hand, swaths against
the rectangle's width and length, turns against their geometry, the route's arrays against their
own points. The continuous-curvature turns themselves: test_field_turns.py."""
from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from shapely import geometry as sg

from mta_sim_ros.field.boundary import field_from_yaml
from mta_sim_ros.field.headlands import headlands, quad_segs
from mta_sim_ros.field.plan import plan_field, turn_kinds
from mta_sim_ros.field.route import SPACING, Pose, end_of, wrap
from mta_sim_ros.field.swaths import swaths_at
from mta_sim_ros.field.clothoid import Curves, bulb_moves, fishtail_moves, quarter, u_moves
from mta_sim_ros.field.route import moves_stretch
from mta_sim_ros.field.turning import STEERING_SHARE, check_path, ring_curves, turn_reach, turning
from mta_sim_ros.field.turns import dubins_paths
from mta_sim_ros.field.types import PlanOptions
from mta_sim_ros.physics.loader import load_train, load_train_text
from mta_sim_ros.physics.outline import box_of

DEFAULT = load_train("config/trains/default.yaml")

TRACTOR = """
name: tractor_with_tool
carts:
  - {name: tractor, length: 3.0, hitch_offset: 1.5, com_offset: 1.2, mass: 16000, yaw_inertia: 57000}
forces:
  traction: {law: governor, set_speed: 3.0, max_force: 125000, max_power: 250000, kp: 16000, ki: 4000}
implement: {cart: tractor, width: WIDTH, offset: OFFSET}
steering_actuator: {time_constant: TAU, max_rate: RATE, max_angle_deg: 40}
"""


def tractor(width=6.0, offset=-1.0, tau=0.2, rate=0.5):
    text = TRACTOR.replace("WIDTH", str(width)).replace("OFFSET", str(offset))
    return load_train_text(text.replace("TAU", str(tau)).replace("RATE", str(rate)), "tractor_with_tool")


def rectangle(length: float, width: float, headlands: int = 0, angle_deg: float = 0.0, **extra):
    """A rectangle length x width, turned by ``angle_deg`` about its corner (0, 0)."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    corners = [(0, 0), (length, 0), (length, width), (0, width)]
    data = {"boundary": [[x * c - y * s, x * s + y * c] for x, y in corners], "headlands": headlands, **extra}
    return field_from_yaml(data, "rectangle.yaml")


# --------------------------------------------------------------------------- the train's turning


def test_a_lone_tractor_turns_within_its_actuators_share():
    """No hitch, no guard below the actuator's angle: the feedforward of its narrowest U stays within
    STEERING_SHARE of max_angle, and its radius is at least the steady radius there."""
    tool = tractor(offset=-1.0)
    turn = turning(tool)
    assert turn.steering <= STEERING_SHARE * math.radians(40.0) + 1e-9
    assert turn.radius >= math.hypot(3.0 / math.tan(STEERING_SHARE * math.radians(40.0)), 1.0) - 1e-9


def test_a_lone_tractors_reach_is_its_boxs_farthest_corner_along_the_path():
    """A tractor whose working point is its rear axle (offset 0) runs its axle on the planned path,
    heading along it: its box's farthest corner beyond the swath end, written out here from the
    path's own samples, is turn_reach's (both U shapes: the narrowest and two quarters)."""
    tool = tractor(offset=0.0)
    turn = turning(tool)
    reach = turn_reach(tool, turn)
    centre, length, width, _ = box_of(tool, 0)
    curves = turn.curves
    far, point = -math.inf, -math.inf
    for moves in (None, u_moves(2.0 * quarter(curves), curves)):
        path = check_path(curves, 60.0, moves)
        x, y, h = path[:, 0], path[:, 1], path[:, 2]
        for along in (centre + length / 2, centre - length / 2):
            for across in (width / 2, -width / 2):
                far = max(far, float((x + along * np.cos(h) - across * np.sin(h)).max()))
        point = max(point, float(x.max()))
    assert reach.point == pytest.approx(point, abs=1e-9)
    assert reach.train == pytest.approx(far, abs=0.05)  # the chain's own headings: sampled at 0.25 m chords


def test_a_trains_u_turn_reaches_beyond_its_working_point():
    turn = turning(DEFAULT)
    reach = turn_reach(DEFAULT, turn)
    assert reach.point == pytest.approx(quarter(turn.curves), rel=1e-3)  # two quarters reach T
    assert reach.train > reach.point + 3.0  # the tractor runs outside the implement, its front ahead


# --------------------------------------------------------------------------- headlands


def rounded_rectangle_area(a: float, b: float, radius: float, segments: int) -> float:
    """An a x b rectangle whose corners are arcs of ``radius`` drawn with ``segments`` chords per
    quarter (vertices on the circle): the rectangle less each corner's square less its polygonal sector."""
    sector = 0.5 * segments * radius**2 * math.sin(0.5 * math.pi / segments)
    return a * b - 4.0 * (radius**2 - sector)


def test_headland_rings_and_inner_ground_of_a_rectangle_are_the_hand_computed_ones():
    L, W, w, R, rings = 400.0, 250.0, 12.0, 9.0, 3
    band = headlands(rectangle(L, W).polygon, rings, w, R, SPACING)
    q = quad_segs(max(R, 0.5 * w, 1.0), SPACING)
    assert len(band.rings) == rings
    for i, line in enumerate(band.rings):
        o = (i + 0.5) * w
        q = quad_segs(max(R, o, 1.0), SPACING)
        assert sg.Polygon(line.coords).area == pytest.approx(rounded_rectangle_area(L - 2 * o, W - 2 * o, R, q),
                                                              rel=1e-12)
    H, r = rings * w, R - w / 2
    q = quad_segs(max(r, H, 1.0), SPACING)
    assert band.width == H
    assert band.inner.area == pytest.approx(rounded_rectangle_area(L - 2 * H, W - 2 * H, r, q), rel=1e-12)


def test_no_headland_leaves_the_field_whole():
    field = rectangle(120.0, 60.0)
    band = headlands(field.polygon, 0, 12.0, 9.0, SPACING)
    assert band.rings == () and band.inner.equals(field.polygon)


# --------------------------------------------------------------------------- swaths


def strips(swaths, width: float):
    return shapely.union_all([sw.line.buffer(width / 2, cap_style="flat") for sw in swaths])


def test_swaths_of_a_rectangle_tile_it():
    """240 m x 120 m, 12 m: 10 swaths of 240 m whose strips are the rectangle."""
    field = rectangle(240.0, 120.0)
    found = swaths_at(field.polygon, 0.0, 12.0, 0.0)
    assert len(found.swaths) == 10
    assert all(sw.length == pytest.approx(240.0, rel=1e-12) for sw in found.swaths)
    assert strips(found.swaths, 12.0).area == pytest.approx(field.polygon.area, rel=1e-6)
    assert strips(found.swaths, 12.0).symmetric_difference(field.polygon).area < 1e-6 * field.polygon.area


@pytest.mark.parametrize("overlap", [0.0, 0.1, 0.25])
def test_swath_spacing_is_the_width_less_the_overlap(overlap):
    width, across = 12.0, 250.0
    found = swaths_at(rectangle(400.0, across).polygon, 0.0, width, overlap)
    offsets = np.array([sw.offset for sw in found.swaths])
    spacing = width * (1 - overlap)
    assert offsets[0] == pytest.approx(width / 2) and offsets[-1] == pytest.approx(across - width / 2)
    assert np.diff(offsets[:-1]) == pytest.approx(spacing, rel=1e-12)
    assert 0 < offsets[-1] - offsets[-2] <= spacing + 1e-9  # the last one overlaps more
    assert len(found.swaths) == math.ceil((across - width) / spacing) + 1


@pytest.mark.parametrize("turned", [0.0, 30.0, 115.0])
def test_the_auto_angle_runs_along_a_rectangles_long_side(turned):
    field = rectangle(400.0, 150.0, headlands=0, angle_deg=turned)
    from mta_sim_ros.field.swaths import best_angle

    found, _ = best_angle(field.polygon, field.polygon, 12.0, 0.0)
    assert math.degrees(found.angle) == pytest.approx(turned % 180.0, abs=1e-6)


# --------------------------------------------------------------------------- turns


def ends(moves, pose=Pose(0.0, 0.0, 0.0)):
    for move in moves:
        pose = end_of(pose, move)
    return pose


@pytest.mark.parametrize("offset", [13.0, -13.0, 30.0])
def test_a_u_turn_of_arcs_has_the_trains_radius_and_lands_on_the_next_swath(offset):
    """sharpness inf: the turns of arcs and straights (curvature jumps), as before CC turns."""
    R = 6.0
    moves = u_moves(offset, Curves(R))
    assert {abs(m.curvature) for m in moves} == {0.0, 1 / R}
    end = ends(moves)
    assert (end.x, end.y) == pytest.approx((0.0, offset), abs=1e-9)
    assert math.cos(end.heading) == pytest.approx(-1.0)


@pytest.mark.parametrize("offset", [2.0, 8.0, -11.0])
def test_a_bulb_of_arcs_lands_on_the_next_swath_and_reaches_its_middle_circle(offset):
    R = 6.0
    moves = bulb_moves(offset, Curves(R))
    end = ends(moves)
    assert (end.x, end.y) == pytest.approx((0.0, offset), abs=1e-9)
    assert math.cos(end.heading) == pytest.approx(-1.0)
    # the middle circle touches both end circles: its centre is 2R from (0, -R) and from (0, D + R)
    x = math.sqrt(4 * R**2 - (abs(offset) / 2 + R) ** 2)
    points = np.vstack([st.xy for st in moves_stretch("turn", Pose(0.0, 0.0, 0.0), moves, spacing=0.01)])
    assert points[:, 0].max() == pytest.approx(x + R, abs=1e-3)


def test_a_fishtail_backs_up_by_twice_its_quarter_less_the_offset():
    curves, offset = Curves(6.0, 1.0 / (6.0 * 4.0)), 8.0
    moves = fishtail_moves(offset, curves)
    back = [m for m in moves if m.reverse]
    assert len(back) == 1 and back[0].length == pytest.approx(2 * quarter(curves) - offset)
    assert [m.reverse for m in moves] == [False] * 3 + [True] + [False] * 3
    end = ends(moves)
    assert (end.x, end.y, math.cos(end.heading)) == pytest.approx((0.0, offset, -1.0), abs=1e-9)
    arcs = moves_stretch("turn", Pose(0.0, 0.0, 0.0), fishtail_moves(offset, Curves(6.0)))
    assert sum(st.reverse for st in arcs) == 1 and ends(fishtail_moves(offset, Curves(6.0))).y == pytest.approx(offset)


def test_dubins_paths_reach_their_goal_and_are_shortest_where_it_is_known():
    R = 5.0
    straight = dubins_paths(Pose(0.0, 0.0, 0.0), Pose(20.0, 0.0, 0.0), R)[0]
    assert sum(m.length for m in straight) == pytest.approx(20.0)
    half = dubins_paths(Pose(0.0, 0.0, 0.0), Pose(0.0, 2 * R, math.pi), R)[0]
    assert sum(m.length for m in half) == pytest.approx(math.pi * R)
    rng = np.random.default_rng(7)
    for _ in range(200):
        a, b = (Pose(*rng.uniform(-30, 30, 2), rng.uniform(-4, 4)) for _ in range(2))
        paths = dubins_paths(a, b, R)
        assert len(paths) >= 4  # the four circle-straight-circle words always exist
        assert sum(m.length for m in paths[0]) >= math.hypot(b.x - a.x, b.y - a.y) - 1e-9


# --------------------------------------------------------------------------- whole plans


@pytest.fixture(scope="module")
def rect_plan():
    """The default train on a rectangle whose inner ground (H = 36 m) is 15 swaths wide."""
    field = rectangle(400.0, 252.0, headlands=3, entry=[0, 0])
    return plan_field(field, DEFAULT, PlanOptions(width=12.0, angle=0.0))


def test_a_rectangles_plan_has_its_swaths_by_hand(rect_plan):
    plan = rect_plan
    assert plan.headland_width == 36.0
    corners = ring_curves(DEFAULT, turning(DEFAULT, 12.0), 3.0)  # the rings' corners (at the working speed)
    r = corners.radius - 6.0  # the inner edge of the last ring's strip: its corners of R - w/2
    q = quad_segs(max(r, 36.0, 1.0), SPACING)
    assert plan.inner.area == pytest.approx(rounded_rectangle_area(400 - 72, 252 - 72, r, q), rel=1e-12)
    assert len(plan.swaths) == 15
    assert all(line.length == pytest.approx(400 - 72, rel=1e-12) for line in plan.swaths)
    # the swaths' strips are the inner rectangle, the rounded corners' slivers too (the last ring's strip
    # and the swaths' there overlap)
    assert strips_area(plan) == pytest.approx((400 - 72) * (252 - 72), rel=1e-6)
    assert plan.target.equals(plan.field.polygon)  # headlands worked


def strips_area(plan) -> float:
    return shapely.union_all([line.buffer(plan.options.width / 2, cap_style="flat") for line in plan.swaths]).area


def test_a_rectangles_turns_are_us_no_tighter_than_the_trains_radius_inside_the_field(rect_plan):
    """12 m swaths, a narrowest U of ~20 m: auto skips one (every turn a U of 2 to 4 spacings)."""
    plan = rect_plan
    assert turn_kinds(plan) == {"u": 14}
    assert any("route skip (" in note for note in plan.notes)
    turns = np.concatenate([plan.route.curvature[s.first:s.last] for s in plan.segments if s.kind == "turn"])
    assert np.abs(turns).max() <= (1.0 + 1e-9) / plan.turn_radius
    assert not any("leave the field" in note for note in plan.notes)
    region = plan.field.polygon.buffer(1e-6)
    assert region.covers(sg.LineString(plan.route.xy))


def test_the_route_is_sampled_within_its_spacing_and_its_flags_follow_the_segments(rect_plan):
    route = rect_plan.route
    chords = np.hypot(*np.diff(route.xy, axis=0).T)
    assert chords.max() <= route.spacing + 1e-9 and chords.min() > 0
    assert np.all(np.diff(route.s) > 0) and route.s[0] == 0.0
    assert route.s[-1] == pytest.approx(chords.sum())
    for j, seg in enumerate(rect_plan.segments):
        inside = slice(seg.first, seg.last)
        assert np.all(route.segment[inside] == j)
        assert np.all(route.working[inside] == (seg.kind in ("swath", "headland")))
        assert np.all(route.reverse[inside] == seg.reverse)


def test_curvature_matches_the_routes_geometry(rect_plan):
    """On moves the heading is exact and changes by curvature x arc length: a finite difference of
    heading over s agrees to the chord's shortfall (~ (ds / R)^2 / 24); three points' circle too."""
    route = rect_plan.route
    moves = np.isin(route.segment, [j for j, s in enumerate(rect_plan.segments) if s.kind in ("swath", "turn")])
    same = (moves[:-1] & moves[1:] & (route.segment[:-1] == route.segment[1:])
            & (route.curvature[:-1] == route.curvature[1:]))
    i = np.flatnonzero(same)
    difference = wrap(route.heading[i + 1] - route.heading[i]) / np.diff(route.s)[i]
    assert difference == pytest.approx(route.curvature[i], abs=1e-3 / rect_plan.turn_radius)
    a, b, c = route.xy[i[:-1]], route.xy[i[:-1] + 1], route.xy[np.minimum(i[:-1] + 2, len(route.s) - 1)]
    cross = (b - a)[:, 0] * (c - b)[:, 1] - (b - a)[:, 1] * (c - b)[:, 0]
    circle = 2 * cross / (np.hypot(*(b - a).T) * np.hypot(*(c - b).T) * np.hypot(*(c - a).T))
    both = same[np.minimum(i[:-1] + 1, len(same) - 1)]
    assert circle[both] == pytest.approx(route.curvature[i[:-1]][both], abs=1e-3 / rect_plan.turn_radius)


def test_the_route_starts_at_the_swath_end_nearest_the_entry(rect_plan):
    swath_ends = np.array([p for line in rect_plan.swaths for p in (line.coords[0], line.coords[-1])])
    nearest = swath_ends[np.argmin(np.hypot(*swath_ends.T))]
    assert rect_plan.route.xy[0] == pytest.approx(nearest)


def test_too_close_swaths_get_bulbs_and_auto_skips_them():
    """Spacing 9.6 m, the narrowest U ~20 m: boustrophedon's turns are all bulbs; skip one (19.2 m)
    is still too narrow, skip two (28.8 m) is not: auto takes it, all U's."""
    field = rectangle(300.0, 200.0, headlands=4)
    options = dict(width=12.0, overlap=0.2, angle=0.0)
    turn = turning(DEFAULT, 9.6)
    assert 19.2 < turn.min_u < 28.8
    plan = plan_field(field, DEFAULT, PlanOptions(route="boustrophedon", **options))
    assert set(turn_kinds(plan)) == {"bulb"}
    skipped = plan_field(field, DEFAULT, PlanOptions(route="auto", **options))
    assert any("route skip2 (" in note for note in skipped.notes)
    assert set(turn_kinds(skipped)) == {"u"}
    fishtail = plan_field(field, DEFAULT, PlanOptions(route="boustrophedon", turn="fishtail", **options))
    reverse = fishtail.route.reverse
    assert set(turn_kinds(fishtail)) == {"fishtail"} and reverse.any()
    backed = [s for s in fishtail.segments if s.reverse]
    assert all(s.kind == "turn" for s in backed)
    length = fishtail.route.s[backed[0].last] - fishtail.route.s[backed[0].first]
    assert length == pytest.approx(2 * quarter(turn.curves) - 9.6, abs=1e-6)


def test_a_narrow_headland_is_widened_for_the_turns_or_said():
    field = rectangle(300.0, 200.0, headlands=1)
    widened = plan_field(field, DEFAULT, PlanOptions(width=12.0, angle=0.0))
    assert widened.headland_width > 12.0 and any("instead of 1" in note for note in widened.notes)
    kept = plan_field(field, DEFAULT, PlanOptions(width=12.0, angle=0.0, headlands=1))
    assert kept.headland_width == 12.0
    assert any("the train leaves the field" in note for note in kept.notes)


def test_an_obstacle_splits_the_swaths_into_cells_and_the_route_goes_round_it():
    from mta_sim_ros.field.boundary import load_field

    plan = plan_field(load_field("config/fields/irregular.yaml"), DEFAULT, PlanOptions(width=12.0))
    obstacle = sg.Polygon(plan.field.polygon.interiors[0])
    normal = np.array([-math.sin(plan.angle), math.cos(plan.angle)])
    rows = np.round([np.asarray(line.coords[0]) @ normal for line in plan.swaths], 6)
    assert len(set(rows)) < len(rows)  # lines the obstacle cut in two
    assert all(plan.inner.buffer(1e-6).covers(line) for line in plan.swaths)
    assert not sg.LineString(plan.route.xy).intersects(obstacle)
    assert any(s.kind == "transit" for s in plan.segments)
    assert not any("leave the field" in note for note in plan.notes)
    # the band round the obstacle is the headland's width, less the sag of arcs drawn with 0.5 m chords
    H = plan.headland_width
    assert plan.inner.distance(obstacle) >= H * math.cos(0.5 * SPACING / H) - 1e-9
    counted = dict(turn_kinds(plan))
    assert f"turns: {', '.join(f'{n} {k}' for k, n in sorted(counted.items()))}" in plan.notes


def test_a_transit_blocked_by_an_obstacle_goes_round_it_on_the_headland():
    from mta_sim_ros.field.connect import region_of, transit
    from mta_sim_ros.field.headlands import loops, opened

    obstacle = [(90, 30), (90, 70), (110, 70), (110, 30)]
    field = sg.Polygon([(0, 0), (200, 0), (200, 100), (0, 100)], [obstacle])
    ring = [line for line in loops(opened(field, 6.0, 5.0, SPACING)) if line.distance(sg.Point(100, 50)) < 30]
    here, goal = Pose(60.0, 50.0, 0.0), Pose(140.0, 50.0, 0.0)  # the obstacle lies between them
    found = transit(here, goal, Curves(5.0, 1.0 / (5.0 * 4.0)), region_of(field), ring, SPACING)
    path = sg.LineString(np.vstack([st.xy for st in found.stretches]))
    assert found.inside and not path.intersects(sg.Polygon(obstacle))
    assert path.coords[0] == pytest.approx((60.0, 50.0)) and path.coords[-1] == pytest.approx((140.0, 50.0))
