"""A sweep's per-run metrics (batch.py) against what cannot drift: the steady circles' closed forms,
Newton's law on a straight line, analyze.py's exact off-tracking, and the run tick by tick."""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from mta_sim_ros.config import resolve_config_path
from mta_sim_ros.physics.outline import box_of, cart_widths
from mta_sim_ros.physics import kernel, loader
from mta_sim_ros.physics.steady import steady_circle
from mta_sim_ros.run import batch
from mta_sim_ros.run import offsets, whole
from mta_sim_ros.run.simulation import Simulation, run_scene
from mta_sim_ros.analysis import distance_to_path

TRAIN = resolve_config_path("trains/default.yaml")


def scene_of(train_data: dict, **fields):
    """A scene of the default train's file (changed by the caller) with the given fields."""
    train = loader.train_from_data(copy.deepcopy(train_data), TRAIN)
    data = {"name": "test", "train": "unused.yaml", "duration": 20, "initial": {"speed": 3.0},
            "steering": {"maneuver": "straight"}, "speed": 3.0, "integrator": {"method": "rk4", "step": 0.01},
            "publish_rate": 50, "fidelity": "dynamic", **fields}
    return loader.scene_from_data(data, "test scene", train)


def steady_scene(psi: float, duration: float = 60.0, train_data: dict | None = None):
    """The train on its steady circles from t = 0: steering psi held, the hitch angles of
    steady.steady_circle, the governor at its balance (sim.initial_state)."""
    train_data = train_data or loader.read_yaml_mapping(TRAIN)
    train = loader.train_from_data(copy.deepcopy(train_data), TRAIN)
    hitch = list(steady_circle(train, psi).hitch_angles)
    return scene_of(train_data, duration=duration, initial={"speed": 3.0, "steering": psi, "hitch_angles": hitch},
                    steering={"table": {"time": [0], "angle": [psi]}})


@pytest.mark.parametrize("psi", [0.25, -0.15])
def test_steady_turn_offtracking_is_the_difference_of_the_closed_form_radii(psi):
    scene = steady_scene(psi)
    result = batch.run_metrics(scene)
    assert result.verdict == batch.OK
    circle = steady_circle(scene.train, psi)
    for k in range(1, scene.train.n):
        expected = circle.R_B[0] - circle.R_B[k]
        # B_1's polyline runs inside its circle by the chord's sagitta R (V tick / R)^2 / 8 < 1e-4 m here
        assert result.metrics[f"cart{k + 1}_offtracking_m"] == pytest.approx(expected, abs=1e-4)
    assert result.metrics["max_offtracking_m"] == pytest.approx(circle.R_B[0] - min(circle.R_B), abs=1e-4)


@pytest.mark.parametrize("psi", [0.25, -0.15])
def test_steady_turn_swept_width_is_the_circle_geometry(psi):
    """Each cart turns about the common centre, which lies on its axle's line: its box's farthest
    point is an outer corner, sqrt((R_Bk + w/2)^2 + d^2) with d the longer end of the box from
    the axle, and its nearest point the inner end of the axle, R_Bk - w/2. The tractor's samples lie
    on its circle, so the path joined by arcs is the circle: no chord's sagitta (4e-5 m here)."""
    scene = steady_scene(psi)
    train = scene.train
    circle = steady_circle(train, psi)
    outer, inner = [], []
    for k in range(train.n):
        centre, length, width, _ = box_of(train, k)
        ends = max(abs(centre + length / 2), abs(centre - length / 2))
        outer.append(math.hypot(circle.R_B[k] + width / 2, ends))
        inner.append(circle.R_B[k] - width / 2)
    assert min(inner) > 0  # the centre lies outside every box, so the envelope is a ring
    result = batch.run_metrics(scene)
    assert result.metrics["swept_width_m"] == pytest.approx(max(outer) - min(inner), abs=1e-6)
    assert cart_widths(train)[2] == 12.0  # the seeder's working width sets the inner edge here


def test_straight_pass_at_constant_speed_pulls_the_resistances_behind_each_hitch():
    train_data = loader.read_yaml_mapping(TRAIN)
    scene = scene_of(train_data, duration=30)
    result = batch.run_metrics(scene)
    tr = scene.train
    g = tr.gravity
    v0 = tr.smoothing_speed
    resist = []
    for cart in tr.carts:
        f = sum(r.coefficient for r in tr.rolling if r.cart == cart.name) * cart.mass * g
        f += sum(d.soil_factor * d.A * d.width * d.depth for d in tr.draft if d.cart == cart.name)
        resist.append(f * math.tanh(3.0 / v0))
    for k in range(1, tr.n):
        behind = sum(resist[k:])
        assert result.metrics[f"hitch{k + 1}_mean_pull_kN"] == pytest.approx(behind / 1e3, rel=1e-9)
        assert result.metrics[f"hitch{k + 1}_max_pull_kN"] == pytest.approx(behind / 1e3, rel=1e-9)


@pytest.mark.parametrize("accel_force", [20000.0, -15000.0])
def test_a_straight_train_speeding_up_pulls_mass_times_acceleration_too(accel_force):
    """On a straight line every cart moves with V and V': the hitch at A_k carries what is behind
    it, sum over j >= k of F_Bj + m_j V' (Newton on the carts behind)."""
    scene = scene_of(loader.read_yaml_mapping(TRAIN))
    model = Simulation(scene).model
    y = np.array(model_state(model, 3.0))
    y[model.layout.governor] += accel_force  # traction above (below) the balance: V' != 0
    rate = kernel.max_rate_of(model.P)
    cart, _ = kernel.pulls_of(model.P, y, 0.0, 3.0, rate)
    accel = kernel.rhs_of(model.P, y, 0.0, 3.0, rate)[model.layout.speed]
    assert abs(accel) > 0.1
    masses = [c.mass for c in scene.train.carts]
    for k in range(1, scene.train.n):
        expected = sum(cart[j, kernel.RES] + masses[j] * accel for j in range(k, scene.train.n))
        assert cart[k, kernel.PULL] == pytest.approx(expected, rel=1e-12)


def model_state(model, speed: float) -> list[float]:
    from mta_sim_ros.run.simulation import initial_state

    scene = scene_of(loader.read_yaml_mapping(TRAIN), initial={"speed": speed})
    return initial_state(scene, model).tolist()


@pytest.mark.parametrize("psi", [0.25, -0.2])
def test_the_last_cart_in_a_steady_turn_pulls_its_resistance_less_its_centripetal_share(psi):
    """On the steady circles every cart turns at Omega = V / R_A1 about one centre O on its axle
    line; the last cart's centre of mass C (c ahead of B) moves on a circle, a_C = -Omega^2 (C - O),
    whose part along the cart's axis is -c Omega^2. Newton along e_n: pull - F_Bn = m_n a_C . e_n."""
    scene = steady_scene(psi, duration=1.0)
    model = Simulation(scene).model
    from mta_sim_ros.run.simulation import initial_state

    y = initial_state(scene, model)
    cart, _ = kernel.pulls_of(model.P, y, psi, 3.0, kernel.max_rate_of(model.P))
    circle = steady_circle(scene.train, psi)
    omega = 3.0 / circle.R_A[0]
    last = scene.train.carts[-1]
    k = scene.train.n - 1
    assert cart[k, kernel.PULL] == pytest.approx(cart[k, kernel.RES] - last.mass * last.com_offset * omega ** 2,
                                                 rel=1e-9)


@pytest.mark.parametrize("steering", [
    {"file": "scenes/headland_turn.yaml"},
    # a figure of eight: each loop laps itself and crosses the other, so the nearest piece of the path
    # is often not the one nearest the point before
    {"table": {"time": [0, 30, 31, 60, 61, 90], "angle": [0.35, 0.35, -0.35, -0.35, 0.35, 0.35]}}])
def test_the_off_tracking_of_a_run_equals_analyze_exact_nearest_point_search(steering):
    if "file" in steering:
        scene = loader.load_scene(resolve_config_path(steering["file"]))
    else:
        scene = scene_of(loader.read_yaml_mapping(TRAIN), duration=90, steering=steering)
    result = batch.run_metrics(scene, fidelity="dynamic")
    assert result.verdict == batch.OK
    n = scene.train.n
    cart = result.trace[:, whole.TRACE_HEAD:].reshape(len(result.trace), n, whole.TRACE_CART)
    B = cart[:, :, whole.TR_BX:whole.TR_BY + 1]
    for k in range(1, n):
        d, at_end = offsets.path_offsets(*(np.ascontiguousarray(a) for a in (B[:, 0, 0], B[:, 0, 1], B[:, k, 0],
                                                                              B[:, k, 1])), True)
        exact, exact_end = distance_to_path(B[:, k], B[:, 0], np.arange(len(B)))
        assert np.array_equal(at_end, exact_end)
        np.testing.assert_allclose(d[~at_end], exact[~exact_end], rtol=0, atol=1e-12)
        assert result.metrics[f"cart{k + 1}_offtracking_m"] == pytest.approx(np.abs(exact[~exact_end]).max(),
                                                                            abs=1e-12)


def test_the_distances_from_a_whole_path_that_crosses_itself_are_analyze_exact_ones():
    """Not growing: every point against the whole path, a spiral of three laps whose laps cross
    a sine wave's points, repeated samples (standing still) and points beyond both ends."""
    t = np.linspace(0.0, 6 * math.pi, 900)
    path = np.column_stack([(10 + t) * np.cos(t), (10 + t) * np.sin(t)])
    path = np.concatenate([path[:1], path[:1], path, path[-1:]])
    s = np.linspace(-40.0, 40.0, 700)
    points = np.column_stack([s, 8 * np.sin(s / 3)])
    d, at_end = offsets.path_offsets(path[:, 0].copy(), path[:, 1].copy(), points[:, 0].copy(), points[:, 1].copy(),
                                     False)
    exact, exact_end = distance_to_path(points, path)
    assert np.array_equal(at_end, exact_end) and 0 < at_end.sum() < len(s)
    np.testing.assert_allclose(d, exact, rtol=0, atol=1e-12)


@pytest.mark.parametrize("fidelity", ["dynamic", "kinematic"])
def test_the_whole_run_kernel_is_run_scene_tick_for_tick(fidelity):
    """batch.run_trace steps a run in one kernel call: every row equals run_scene's Outputs bit for bit."""
    scene = loader.load_scene(resolve_config_path("scenes/headland_turn.yaml"))
    sim, trace, _, done, err = batch.run_trace(scene, fidelity=fidelity)
    outs = []
    run_scene(scene, on_output=outs.append, fidelity=fidelity)
    assert err is None and done == len(outs) - 1 == len(trace) - 1
    n = scene.train.n
    cart = trace[:, whole.TRACE_HEAD:].reshape(len(trace), n, whole.TRACE_CART)
    assert np.array_equal(trace[:, whole.TR_TRACTION], [o.traction for o in outs])
    assert np.array_equal(trace[:, whole.TR_SPEED], [o.speed for o in outs])
    assert np.array_equal(cart[:, :, whole.TR_BX], [o.axle[:, 0] for o in outs])
    assert np.array_equal(cart[:, :, whole.TR_HEADING], [o.heading for o in outs])
    assert np.array_equal(cart[:, 1:, whole.TR_PHI], [o.hitch_angle for o in outs])


def test_a_jackknife_is_a_result_with_its_reason():
    """Reversing with the default unit's hitches folds (MODEL.md: hitch angles grow backwards)."""
    data = loader.read_yaml_mapping(TRAIN)
    scene = scene_of(data, duration=60, initial={"speed": -2.0, "hitch_angles_deg": [3, -3]}, speed=-2.0)
    result = batch.run_metrics(scene)
    assert result.verdict == batch.STOPPED
    assert "jackknife" in result.reason
    assert 0 < result.simulated < 60
    assert len(result.trace) == round(result.simulated * 50) + 1
    assert math.isfinite(result.metrics["energy_kWh"])


def test_energy_per_hectare_is_the_energy_over_the_seeder_strip():
    scene = scene_of(loader.read_yaml_mapping(TRAIN), duration=30)
    m = batch.run_metrics(scene).metrics
    assert m["worked_area_ha"] == pytest.approx(12.0 * 3.0 * 30.0 / 1e4, rel=1e-9)
    assert m["energy_per_ha_kWh"] == pytest.approx(m["energy_kWh"] / m["worked_area_ha"], rel=1e-12)
    assert m["mean_power_kW"] == pytest.approx(m["energy_kWh"] * 3600.0 / 30.0, rel=1e-12)
    assert math.isnan(m["headland_width_m"])  # it never steers


def test_a_standstill_at_the_end_adds_nothing_beside_the_path():
    """A train that ends its run standing still repeats its last sample: a box corner ahead of the
    tractor is then past the path's end at every such tick, not beside it (it would widen the swept
    width by its distance from the end sample)."""
    from mta_sim_ros.run import offsets

    px = np.linspace(0.0, 10.0, 51)
    still = np.concatenate([px, np.full(20, px[-1])])  # 20 ticks standing at x = 10
    y = np.zeros_like(still)
    qx, qy = still + 2.0, y - 1.0  # a front corner 2 m ahead and 1 m right of the axle, every tick
    for run in (offsets.beside_offsets, offsets.beside_offsets.py_func):
        bend = offsets.arc_bends(still, y)
        d, at_end = run(still, y, bend, qx, qy)
        moving = qx[:51] < 10.0  # the corner beside the path while the path reaches past it
        assert at_end[51:].all() and not at_end[:51][moving].any()
        np.testing.assert_allclose(d[:51][moving], -1.0, atol=1e-12)  # 1 m right of the path


def _extent_corner_by_corner(px, py, bend, bx, by, th, corners, start, a1, e0):
    """outline_extent's figures as batch.metrics took them before it: each corner's beside_offsets
    series, reduced by numpy (NaN left out)."""
    left, right, reach = -math.inf, math.inf, -math.inf
    for k in range(bx.shape[1]):
        ex, ey = np.cos(th[:, k]), np.sin(th[:, k])
        for along, across in corners[k]:
            qx = np.ascontiguousarray(bx[:, k] + along * ex - across * ey)
            qy = np.ascontiguousarray(by[:, k] + along * ey + across * ex)
            d, at_end = offsets.beside_offsets(px, py, bend, qx, qy)
            beside = d[~at_end & ~np.isnan(d)]
            if beside.size:
                left, right = max(left, float(beside.max())), min(right, float(beside.min()))
            ahead = ((qx - a1[0]) * e0[0] + (qy - a1[1]) * e0[1])[start:]
            if start >= 0 and (~np.isnan(ahead)).any():
                reach = max(reach, float(np.nanmax(ahead)))
    return left, right, reach


@pytest.mark.parametrize("case", ["run", "a NaN row", "standing still", "never steers"])
def test_the_outline_extent_is_each_corners_offsets_taken_one_by_one(case):
    """offsets.outline_extent (one compiled pass over every corner of every cart: batch.metrics' swept
    and headland widths) equals the corners' beside_offsets series taken one by one, compiled and as
    plain Python, on a headland turn's trace with random corners."""
    scene = loader.load_scene(resolve_config_path("scenes/headland_turn.yaml"))
    _, trace, _, done, _ = batch.run_trace(scene, fidelity="dynamic")
    n = scene.train.n
    cart = trace[:done + 1:7, whole.TRACE_HEAD:].reshape(-1, n, whole.TRACE_CART)
    bx, by, th = (np.ascontiguousarray(cart[:, :, c]) for c in (whole.TR_BX, whole.TR_BY, whole.TR_HEADING))
    if case == "a NaN row":  # a cart's corners ahead of the turn, and the path beside some of them
        th[150, :] = math.nan
        bx[300, 0] = math.nan
    if case == "standing still":
        bx[:, 0], by[:, 0] = bx[0, 0], by[0, 0]
    rng = np.random.default_rng(7)
    corners = rng.uniform(-4.0, 4.0, (n, 6, 2))
    start = -1 if case == "never steers" else 120
    a1, e0 = rng.uniform(-5.0, 5.0, 2), np.array([math.cos(0.3), math.sin(0.3)])
    px, py = bx[:, 0].copy(), by[:, 0].copy()
    bend = offsets.arc_bends(px, py)
    expected = _extent_corner_by_corner(px, py, bend, bx, by, th, corners, start, a1, e0)
    assert math.isfinite(expected[0]) != (case == "standing still")
    for extent in (offsets.outline_extent, offsets.outline_extent.py_func):
        assert extent(px, py, bend, bx, by, th, corners, start, a1[0], a1[1], e0[0], e0[1]) == expected
