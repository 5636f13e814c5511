"""What a field worked cost (field/coverage.py), against closed forms: a rectangle worked in straight
swaths with perfect tracking, then with planted errors of known size (a lateral shift of every other
swath, the implement off the line at each swath start, passes that stop short of the boundary, an
obstacle driven over), each of which must show up as the skip, overlap, excursion or figure it
causes. The traces are built from the route directly (fieldroutes.trace_along): no dynamics."""
from __future__ import annotations

import math

import numpy as np
import pytest

from mta_sim_ros.config import resolve_config_path
from mta_sim_ros.field import coverage
from mta_sim_ros.physics import loader

import fieldroutes as fr

DEFAULT = loader.load_train(resolve_config_path("trains/default.yaml"))
WIDTH = DEFAULT.implement.width  # 12 m
FIELD_W, FIELD_H, HEADLAND = 200.0, 100.0, 20.0
LENGTH = FIELD_W - 2 * HEADLAND  # every swath's length, 160 m
SWATHS = 5  # (100 - 40) / 12


@pytest.fixture(scope="module")
def plan():
    return fr.swath_plan(fr.rectangle(FIELD_W, FIELD_H), WIDTH, HEADLAND)


def test_perfect_tracking_works_the_inner_field_once(plan):
    """Worked area = field minus headland (160 x 60 m), nothing skipped, twice or outside."""
    trace = fr.trace_along(plan, DEFAULT)
    cov = coverage.coverage(trace, DEFAULT)
    assert len(plan.swaths) == SWATHS
    assert cov.worked.area == pytest.approx(LENGTH * (FIELD_H - 2 * HEADLAND), rel=1e-12)
    assert cov.skipped.area < 1e-6
    assert cov.double.area < 1e-6
    assert cov.outside.area < 1e-6
    assert [len(p.exterior.coords) for p in cov.pieces] == [5] * SWATHS  # simplified to rectangles


def shift_per_swath(plan, shifts):
    """Per route vertex: shifts[i] on swath i, 0 elsewhere."""
    out = np.zeros(plan.route.s.shape[0])
    for seg in plan.segments:
        if seg.kind == "swath":
            out[seg.first:seg.last + 1] = shifts[seg.index]
    return out


@pytest.mark.parametrize("error", [0.05, 0.3, 1.0])
def test_a_lateral_error_on_every_other_swath_skips_and_overlaps_its_own_area(plan, error):
    """Each odd swath moved ``error`` m to the left of its travel (south, travelling west): it
    overlaps the swath below by error x length and leaves as much unworked above it (the last one
    against the inner field's edge): both error x 160 m per odd swath, every skip the tracking's."""
    trace = fr.trace_along(plan, DEFAULT, shift=shift_per_swath(plan, [0.0, error] * 3))
    cov = coverage.coverage(trace, DEFAULT)
    odd = SWATHS // 2
    assert cov.skipped.area == pytest.approx(odd * error * LENGTH, rel=1e-9)
    assert cov.double.area == pytest.approx(odd * error * LENGTH, rel=1e-9)
    assert cov.skipped_by["tracking"].area == pytest.approx(cov.skipped.area, rel=1e-12)
    assert cov.skipped_by["turns"].area == 0.0 and cov.skipped_by["boundary"].area == 0.0
    assert cov.worked.area == pytest.approx(LENGTH * (FIELD_H - 2 * HEADLAND) - odd * error * LENGTH, rel=1e-12)


def test_off_the_line_at_each_swath_start_is_a_skip_of_the_turns(plan):
    """W comes out of every turn e0 = 0.4 m left of the line and reaches it linearly over D = 8 m
    (the bar square to the swath): a triangle e0 D / 2 unworked on its right and as much worked
    twice on its left, at every swath start (the last swath's left is the headland: outside the
    target, not twice); the skip is the turns' (in the swath's end zone)."""
    e0, D = 0.4, 8.0
    shift = np.zeros(plan.route.s.shape[0])
    for seg in plan.segments:
        if seg.kind == "swath":
            along = plan.route.s[seg.first:seg.last + 1] - plan.route.s[seg.first]
            shift[seg.first:seg.last + 1] = e0 * np.clip(1.0 - along / D, 0.0, None)
    cov = coverage.coverage(fr.trace_along(plan, DEFAULT, shift=shift), DEFAULT)
    triangle = e0 * D / 2
    assert cov.skipped.area == pytest.approx(SWATHS * triangle, rel=1e-9)
    assert cov.skipped_by["turns"].area == pytest.approx(SWATHS * triangle, rel=1e-9)
    assert cov.double.area == pytest.approx((SWATHS - 1) * triangle, rel=1e-9)


def test_lowered_late_skips_the_width_times_the_delay_in_turns(plan):
    """The implement lowered 5 m after every swath's start: 12 m x 5 m unworked per swath."""
    lowered = plan.route.working.copy()
    for seg in plan.segments:
        if seg.kind == "swath":
            lowered[seg.first:seg.first + 10] = False  # 10 vertices of 0.5 m
    cov = coverage.coverage(fr.trace_along(plan, DEFAULT, lowered=lowered), DEFAULT)
    assert cov.skipped.area == pytest.approx(SWATHS * WIDTH * 5.0, rel=1e-9)
    assert cov.skipped_by["turns"].area == pytest.approx(cov.skipped.area, rel=1e-12)


def test_passes_short_of_the_boundary_skip_the_boundary_and_turns_leave_the_field():
    """No headland: 8 swaths of 12 m in a 200 x 100 m field end 4 m short of its north edge, a
    skip of 4 x 200 m the boundary's; the turns, outside the field, put the carts outside it."""
    field = fr.rectangle(FIELD_W, FIELD_H, headlands=0)
    plan = fr.swath_plan(field, WIDTH, 0.0, swaths=8)
    trace = fr.trace_along(plan, DEFAULT)
    result = coverage.metrics(trace, DEFAULT)
    cov = result.coverage
    assert cov.skipped.area == pytest.approx(4.0 * FIELD_W, rel=1e-9)
    assert cov.skipped_by["boundary"].area == pytest.approx(4.0 * FIELD_W, rel=1e-9)
    assert cov.outside.area < 1e-6  # the strips end on the boundary
    kinds = {e.kind for e in result.excursions}
    assert kinds == {"outside the boundary"}
    turning = [(trace.t[s.first], trace.t[s.last]) for s in plan.segments if s.kind == "turn"]
    turning += [(0.0, 0.0), (trace.t[-1], trace.t[-1])]  # the seeder's box reaches behind W on the edge
    assert len(result.excursions) >= len(turning)
    for e in result.excursions:  # every excursion while turning, the train's length around it
        assert any(a - 10.0 <= e.first and e.last <= b + 10.0 for a, b in turning), e.line()
        assert e.where[0] < 0.0 or e.where[0] > FIELD_W


def test_an_obstacle_driven_over_is_worked_outside_and_an_excursion():
    """A 4 x 4 m pond on swath 2's line: 16 m^2 worked outside the field, every cart over it."""
    y = HEADLAND + 2.5 * WIDTH
    pond = [[100, y - 2], [100, y + 2], [104, y + 2], [104, y - 2]]  # clockwise: a hole
    field = fr.rectangle(FIELD_W, FIELD_H, holes=[pond])
    plan = fr.swath_plan(field, WIDTH, HEADLAND)
    result = coverage.metrics(fr.trace_along(plan, DEFAULT), DEFAULT)
    assert result.coverage.outside.area == pytest.approx(16.0, rel=1e-9)
    assert result.coverage.skipped.area < 1e-6  # the pond is not the plan's target
    over = [e for e in result.excursions if e.kind == "in an obstacle"]
    assert sorted(e.cart for e in over) == sorted(c.name for c in DEFAULT.carts)
    for e in over:
        assert 96.0 < e.where[0] < 108.0 and abs(e.where[1] - y) < 8.0


def test_the_figures_of_a_known_run(plan):
    """Time, working and turn time, efficiency, energy and fuel of a trace of known power; the
    tracking statistics of errors planted +-e."""
    speed, power = 2.5, 1.2e5
    error = 0.07
    shift = shift_per_swath(plan, [error, -error, error, -error, error])
    trace = fr.trace_along(plan, DEFAULT, speed=speed, shift=shift, power=power)
    trace.power[::7] = -5.0e4  # braking now and then: energy falls, fuel does not
    v = coverage.metrics(trace, DEFAULT).values
    route = plan.route
    total = route.s[-1] / speed
    swath_length = sum(route.s[s.last] - route.s[s.first] for s in plan.segments if s.kind == "swath")
    turn_length = sum(route.s[s.last] - route.s[s.first] for s in plan.segments if s.kind == "turn")
    assert v["total_time_h"] * 3600 == pytest.approx(total, rel=1e-12)
    assert v["working_time_h"] * 3600 == pytest.approx(swath_length / speed, rel=1e-12)
    assert v["turn_time_h"] * 3600 == pytest.approx(turn_length / speed, rel=1e-12)
    assert v["field_efficiency_pct"] == pytest.approx(100 * swath_length / route.s[-1], rel=1e-12)
    t, p = trace.t, trace.power
    energy = sum(0.5 * (p[i] + p[i + 1]) * (t[i + 1] - t[i]) for i in range(t.size - 1)) / 3.6e6
    assert v["energy_kWh"] == pytest.approx(energy, rel=1e-12)
    positive = sum(0.5 * (max(p[i], 0) + max(p[i + 1], 0)) * (t[i + 1] - t[i]) for i in range(t.size - 1)) / 3.6e6
    fuel_kg = 240.0 * positive / 0.75 / 1000.0  # the default train: 240 g/kWh, 75 % drive train
    assert v["fuel_kg"] == pytest.approx(fuel_kg, rel=1e-12)
    assert v["fuel_l"] == pytest.approx(fuel_kg / 0.835, rel=1e-12)
    assert v["energy_per_ha_kWh"] == pytest.approx(energy / v["worked_area_ha"], rel=1e-12)
    assert v["tracking_rms_m"] == pytest.approx(error, rel=1e-12)
    assert v["tracking_max_m"] == pytest.approx(error, rel=1e-12)
    assert v["tracking_p95_m"] == pytest.approx(error, rel=1e-12)
    assert v["excursions"] == 0.0
    assert math.isclose(v["min_jackknife_margin_deg"], 80.0)


def test_the_markdown_table_names_every_figure(plan):
    result = coverage.metrics(fr.trace_along(plan, DEFAULT), DEFAULT)
    text = coverage.markdown(result)
    for name in result.values:
        assert coverage.LABELS[name].strip() in text
    assert "Verdict: ok" in text
