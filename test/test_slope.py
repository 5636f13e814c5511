"""The train on a tilted plane (a scene's ``terrain``) against closed forms and balance laws: the
grade resistance m g sin(a) per cart, the energy balance with the potential energy taken from the
carts' world heights, the lateral constraint forces against m g sin(b) on a side slope, the slip
level's steady drift tan(b) / K, both algorithms and the kernel, and the level plane bit for bit."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import trains

from mta_sim_ros.physics import loader
from mta_sim_ros.physics.dynamics import Model
from mta_sim_ros.physics.geometry import cart_points
from mta_sim_ros.physics.reader import SpecError
from mta_sim_ros.physics.slip import CORNERING_COEFFICIENT, SlipModel, no_slip_tyre_forces
from mta_sim_ros.physics.terrain import Plane, PlaneFrame, Surface, orientation
from mta_sim_ros.run.simulation import Simulation, run_scene

G = 9.80665


def on(tr, grade: float, cross: float):
    return dataclasses.replace(tr, terrain=Plane(grade, cross))


def straight_state(model, heading: float, speed: float) -> np.ndarray:
    L = model.layout
    y = np.zeros(L.size)
    y[L.heading] = heading
    y[L.speed] = speed
    return y


# -- the plane's frame -------------------------------------------------------------------------
@pytest.mark.parametrize("grade, cross", [(0.05, 0.0), (0.0, 0.12), (-0.3, 0.4), (1.2, -0.9)])
def test_plane_frame_is_the_plane(grade, cross):
    """The frame's x, y lie in the plane z = grade X + cross Y and its z is the plane's normal; its
    points are on the plane at their distances along the ground; gravity's parts add up to g."""
    f = PlaneFrame.of(Plane(grade, cross))
    R = np.array([f.x, f.y, f.z]).T
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-15) and np.linalg.det(R) == pytest.approx(1.0)
    for u, v in ((3.0, 0.0), (0.0, -2.0), (5.0, 7.0)):
        X, Y, Z = f.point(u, v)
        assert Z == pytest.approx(grade * X + cross * Y, abs=1e-12)
        assert math.dist((0.0, 0.0, 0.0), (X, Y, Z)) == pytest.approx(math.hypot(u, v))
    assert f.y[0] == pytest.approx(0.0, abs=1e-15) or abs(cross) > 0  # x over the world's x axis
    assert f.x[1] == 0.0
    gx, gy, gz = f.gravity(G)
    assert math.hypot(gx, gy, gz) == pytest.approx(G)
    assert -gz == pytest.approx(G / math.sqrt(1 + grade ** 2 + cross ** 2))  # g cos(slope)


@pytest.mark.parametrize("heading", [0.0, 0.7, 2.0, -2.9])
def test_plane_roll_pitch_agree_with_the_surface_formula(heading):
    """A body on the plane: its roll and pitch from the frame's rotation equal terrain.orientation's
    closed forms at its horizontal heading."""
    plane = Plane(0.2, -0.15)
    f = PlaneFrame.of(plane)
    R = f.rotation(heading)
    horizontal = math.atan2(R[1, 0], R[0, 0])
    roll, pitch = f.roll_pitch(heading)
    expect = orientation(horizontal, Surface(0.0, plane.grade, plane.cross_slope))
    assert roll == pytest.approx(expect[0], abs=1e-12) and pitch == pytest.approx(expect[1], abs=1e-12)
    q = np.array(f.quaternion(heading))
    x, y, z, w = q
    Rq = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                   [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                   [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    assert np.allclose(Rq, R, atol=1e-14)


# -- grade resistance: m g sin(a) per cart ----------------------------------------------------
@pytest.mark.parametrize("n", [1, 3, 5])
@pytest.mark.parametrize("grade", [0.05, -0.08, 0.3])
def test_grade_resistance_straight_up_a_grade(n, grade):
    """Straight up (heading 0) a pure grade a: each cart's grade resistance is m g sin(a); across
    it (heading pi/2) zero; its power m g sin(a) V is the rise of the potential energy."""
    tr = on(trains.train(n), grade, 0.0)
    model = Model(tr)
    sin_a = grade / math.sqrt(1 + grade * grade)
    tm = model.terms(straight_state(model, 0.0, 3.0), 0.0, 3.0)
    for cart, f in zip(tr.carts, tm.grade):
        assert f == pytest.approx(cart.mass * G * sin_a, rel=1e-13)
    across = model.terms(straight_state(model, 0.5 * math.pi, 3.0), 0.0, 3.0)
    assert max(abs(f) for f in across.grade) < 1e-9 * tr.carts[0].mass
    out = model.outputs(0.0, straight_state(model, 0.0, 3.0), 0.0, 3.0)
    assert out.grade_power == pytest.approx(sum(c.mass for c in tr.carts) * G * sin_a * 3.0, rel=1e-13)


def test_extra_traction_power_on_a_grade_at_steady_speed():
    """The governor holding 3 m/s straight up a 5 % grade: the traction power exceeds the level's
    by sum m g sin(a) V less the rolling resistance's drop to f m g cos(a) (MODEL.md's closed form)."""
    grade, V = 0.05, 3.0
    base = trains.train(3)
    sin_a, cos_a = grade / math.sqrt(1 + grade ** 2), 1 / math.sqrt(1 + grade ** 2)
    powers = {}
    for tr in (base, on(base, grade, 0.0)):
        sim, err = run_scene(trains.scene(tr, duration=60.0, rate=5.0))
        assert err is None
        out = sim.outputs()
        assert out.speed == pytest.approx(V, abs=1e-6)
        powers[tr.terrain] = out.power
    mass = sum(c.mass for c in base.carts)
    rolling = sum(r.coefficient * base.carts[base.cart_index(r.cart)].mass for r in base.rolling) * G
    expect = mass * G * sin_a * V - rolling * (1 - cos_a) * V
    assert powers[Plane(grade, 0.0)] - powers[None] == pytest.approx(expect, rel=1e-6)


@pytest.mark.parametrize("grade, cross", [(0.05, 0.0), (-0.04, 0.0), (0.03, 0.12)])
def test_the_governor_starts_in_equilibrium_on_a_slope(grade, cross):
    """A scene starting at its set speed starts in equilibrium (simulation.initial_state): the
    governor's integral balances the resistances and the grade's m g sin(a), so the speed holds
    from the first tick (it dipped by a tenth before the grade was counted), the traction at t = 0
    is the closed form's and the steady one a minute later."""
    tr = on(trains.train(3, draft=False), grade, cross)
    sim = Simulation(trains.scene(tr, duration=60.0, rate=5.0))
    first = sim.outputs()
    if cross == 0.0:  # straight up (down) the grade: sum m g (f cos a + sin a), f = 0.08 for every cart
        sin_a, cos_a = grade / math.sqrt(1 + grade ** 2), 1 / math.sqrt(1 + grade ** 2)
        assert first.traction == pytest.approx(sum(c.mass for c in tr.carts) * G * (0.08 * cos_a + sin_a), rel=1e-12)
    speeds = []
    for _ in range(50):
        sim.advance(0.0, 3.0)
        speeds.append(sim.outputs().speed)
    assert first.speed == 3.0 and max(abs(v - 3.0) for v in speeds) < 1e-9
    steady, err = run_scene(trains.scene(tr, duration=60.0, rate=5.0))
    assert err is None and first.traction == pytest.approx(steady.outputs().traction, rel=1e-9)


# -- energy: traction work = kinetic + potential + resistances ---------------------------------
@pytest.mark.parametrize("law", ["governor", "constant"])
def test_energy_balance_with_the_potential_energy(law):
    """Along a slalom on a plane tilted both ways: the work of traction less the resistances' equals
    the change of the kinetic energy plus m g times the rise of every centre of mass, its height
    taken from the world positions of the plane's frame (not from the grade terms)."""
    traction = trains.GOVERNOR if law == "governor" else trains.Traction("constant", force=45000.0)
    tr = on(trains.train(3, traction=traction), 0.06, -0.1)
    model = Model(tr)
    frame = PlaneFrame.of(tr.terrain)
    y0 = Simulation(trains.scene(tr, speed=2.5)).y

    def command(t):
        return 0.25 * math.sin(0.6 * t) + 0.1 * math.sin(1.7 * t)

    def energy(y):
        com = cart_points(tr, y[0], y[1], y[2:2 + tr.n])["C"]
        heights = [frame.point(u, v)[2] for u, v in com]
        return model.kinetic_energy(y, 0.0, 3.0) + G * sum(c.mass * h for c, h in zip(tr.carts, heights))

    residual, rise, work, sol = trains.energy_balance(model, y0, command, energy)
    assert residual < 1e-8 * (rise + work + 1.0)
    for i in range(0, len(sol.t), 5):
        applied, dT = model.power_balance(sol.y[:-1, i], command(sol.t[i]), 3.0)
        assert dT == pytest.approx(applied, rel=1e-10, abs=1e-6)


# -- both algorithms, the kernel, the slip level ------------------------------------------------
@pytest.mark.parametrize("n", [1, 2, 4])
def test_both_algorithms_and_the_kernel_on_a_slope(n):
    """Algorithm 1 (gravity as G^T Q_h) equals algorithm 2 (the chain's factors) to round-off; the
    compiled kernel's y' equals the reference's to the last bit; outputs agree."""
    tr = on(trains.train(n, traction=trains.prescribed(2.0) if n == 2 else trains.GOVERNOR), 0.15, 0.25)
    alg1, alg2 = Model(tr, algorithm=1), Model(tr, algorithm=2)
    rng = np.random.default_rng(40 + n)
    for _ in range(15):
        y = trains.random_state(alg2, rng)
        command, v_set = rng.uniform(-0.5, 0.5), rng.uniform(-3, 3)
        t1, t2 = alg1.terms(y, command, v_set), alg2.terms(y, command, v_set)
        scale = sum(c.mass for c in tr.carts) * G
        assert np.allclose(t1.grade, t2.grade, rtol=0, atol=1e-12 * scale)
        assert abs(t1.acceleration - t2.acceleration) < 1e-10 * max(1.0, abs(t2.acceleration))
        assert np.array_equal(alg2.rhs(0.0, y, command, v_set), alg2.derivative(y, command, v_set)[0])
        k_out, r_out = alg2.outputs(0.0, y, command, v_set), alg1.outputs(0.0, y, command, v_set)
        assert k_out.grade_power == pytest.approx(r_out.grade_power, rel=1e-9, abs=1e-9 * scale)
        assert k_out.traction == pytest.approx(r_out.traction, rel=1e-9, abs=1e-6)


def test_level_plane_is_the_level_bit_for_bit():
    """A terrain of 0 % and 0 % runs exactly as no terrain: the same states at every tick."""
    tr = trains.train(3)
    sc = trains.scene(tr, table=((0.0, 3.0, 6.0), (0.0, 0.3, -0.2)), duration=12.0)
    runs = []
    for t in (tr, on(tr, 0.0, 0.0)):
        seen = []
        _, err = run_scene(dataclasses.replace(sc, train=t), on_output=seen.append)
        assert err is None
        runs.append(np.array([np.concatenate((o.axle.ravel(), o.heading, [o.speed, o.power])) for o in seen]))
    assert np.array_equal(runs[0], runs[1])


# -- side slope: lateral forces, drawbar pulls, drift --------------------------------------------
@pytest.mark.parametrize("cross", [0.1, -0.25])
def test_side_slope_lateral_forces_balance_gravity(cross):
    """Straight across a side slope b at steady speed: the no-slip axles' lateral forces add up to
    m g sin(b) of the whole train, pointing uphill; the pull at each hitch is still the resistances
    behind it (gravity is across the motion), rolling taking the normal load f m g cos(b)."""
    tr = on(trains.train(3, traction=trains.prescribed(3.0)), 0.0, cross)
    slip = SlipModel(tr)
    y = straight_state(slip.dynamic, 0.0, 3.0)
    front, rear = no_slip_tyre_forces(slip, y, 0.0, 3.0)
    sin_b, cos_b = cross / math.sqrt(1 + cross ** 2), 1 / math.sqrt(1 + cross ** 2)
    mass = sum(c.mass for c in tr.carts)
    assert front + rear.sum() == pytest.approx(mass * G * sin_b, rel=1e-9)
    from mta_sim_ros.physics import kernel

    cart, _ = kernel.pulls_of(slip.dynamic.P, y, 0.0, 3.0, kernel.max_rate_of(slip.dynamic.P))
    for k in range(1, tr.n):
        behind = sum(cart[j, kernel.RES] for j in range(k, tr.n))
        assert cart[k, kernel.PULL] == pytest.approx(behind, rel=1e-9)
    rolling_last = tr.rolling[-1].coefficient * tr.carts[-1].mass * G * cos_b * math.tanh(3.0 / tr.smoothing_speed)
    draft = cart[-1, kernel.RES] - rolling_last
    assert draft == pytest.approx(kernel.resistance(Model(trains.train(3)).P, 2, 3.0, kernel.NATURAL)
                                  - tr.rolling[-1].coefficient * tr.carts[-1].mass * G * math.tanh(3.0 / tr.smoothing_speed),
                                  rel=1e-9)


def test_slip_level_drifts_at_tan_b_over_k_on_a_side_slope():
    """A tractor alone, straight across a side slope b on linear tyres of C = K m g cos(b) per
    axle share: both axles take their share of m g sin(b) by the same slip angle, alpha = -tan(b) / K
    (downhill: -y, the plane rising to +y), and the heading stays (no yaw moment)."""
    cross = 0.15
    tr = on(trains.train(1, traction=trains.prescribed(3.0), draft=False), 0.0, cross)
    sc = dataclasses.replace(trains.scene(tr, duration=30.0, rate=2.0, method="LSODA", step=None, rtol=1e-9,
                                          atol=1e-9), fidelity="slip")
    sim, err = run_scene(sc)
    assert err is None
    tm = sim.model.terms(sim.y, 0.0, 3.0)
    expect = -cross / CORNERING_COEFFICIENT  # -tan(b) / K
    assert tm.slip[0] == pytest.approx(expect, rel=1e-8)
    assert tm.front_slip == pytest.approx(expect, rel=1e-8)
    assert abs(sim.y[sim.model.layout.heading][0]) < 1e-6


# -- the scene's terrain ------------------------------------------------------------------------
SCENE = """
train: ../trains/default.yaml
duration: 5
steering: {table: {time: [0], angle: [0]}}
"""


def test_scene_terrain_reaches_every_level(tmp_path):
    """A scene's terrain (percent) is the plane of its train; the levels all pack its gravity."""
    tr = loader.load_train("config/trains/default.yaml")
    sc = loader.load_scene_text(SCENE + "terrain: {grade_percent: 5, cross_slope_percent: -8}\n", "s.yaml", tr)
    assert sc.train.terrain == Plane(0.05, -0.08)
    assert loader.load_scene_text(SCENE, "s.yaml", tr).train.terrain is None


@pytest.mark.parametrize("terrain, words", [
    ("{grade_percent: 150, cross_slope_percent: 100}", ["grade_percent", "60 deg"]),
    ("{grade_percent: 200}", ["grade_percent", "173.2"]),
    ("{grade_percent: .nan}", ["grade_percent"]),
    ("{grade_percent: '5'}", ["grade_percent"]),
    ("{slope: 5}", ["slope"]),
    ("5", ["terrain"]),
])
def test_hostile_terrain_is_one_line(terrain, words):
    tr = loader.load_train("config/trains/default.yaml")
    with pytest.raises(SpecError) as err:
        loader.load_scene_text(SCENE + f"terrain: {terrain}\n", "s.yaml", tr)
    message = str(err.value)
    assert "\n" not in message
    for w in words:
        assert w in message


# -- the bag: 3D poses through tf ----------------------------------------------------------------
def test_a_run_on_a_slope_places_the_train_on_the_plane(tmp_path):
    """``mta run`` of the shipped side-slope scene, read back by rosbags: map -> odom is the plane's
    tilt, hitch_poses are in odom, and every hitch pose composed with it lies on the plane
    z = 0.04 x + 0.12 y with its body z axis the plane's normal (read by scipy's Rotation)."""
    from rosbags.highlevel import AnyReader
    from scipy.spatial.transform import Rotation

    from mta_sim_ros import cli

    bag = tmp_path / "slope.mcap"
    assert cli.main(["run", "--scene", "config/scenes/side_slope_pass.yaml", "--bag", str(bag), "--quiet"]) == 0
    normal = np.array([-0.04, -0.12, 1.0]) / math.sqrt(1 + 0.04 ** 2 + 0.12 ** 2)
    with AnyReader([bag]) as reader:
        msgs = {}
        for conn, _, raw in reader.messages([c for c in reader.connections if c.topic in ("/tf_static", "/hitch_poses")]):
            msgs.setdefault(conn.topic, []).append(reader.deserialize(raw, conn.msgtype))
    tilt = [t for t in msgs["/tf_static"][0].transforms if t.child_frame_id == "odom"]
    assert len(tilt) == 1 and tilt[0].header.frame_id == "map"
    r = tilt[0].transform.rotation
    R = Rotation.from_quat([r.x, r.y, r.z, r.w])
    assert np.allclose(R.apply([0.0, 0.0, 1.0]), normal, atol=1e-12)
    checked = 0
    for poses in msgs["/hitch_poses"][::200]:
        assert poses.header.frame_id == "odom"
        for p in poses.poses:
            world = R.apply([p.position.x, p.position.y, p.position.z])
            assert world[2] == pytest.approx(0.04 * world[0] + 0.12 * world[1], abs=1e-9)
            o = p.orientation
            body = R * Rotation.from_quat([o.x, o.y, o.z, o.w])
            assert np.allclose(body.apply([0.0, 0.0, 1.0]), normal, atol=1e-12)
            checked += 1
    assert checked >= 30


# -- the level chooser sees the slope -------------------------------------------------------------
def test_the_chooser_s_predictions_bound_the_side_slope_s_errors():
    """On the shipped side-slope scene the dynamic level's measured errors against the slip level
    (its tyres drift downhill) stay within what ``fidelity.estimate`` predicts for it, and a scene
    that needs its poses within 0.5 m gets the slip level."""
    from mta_sim_ros.physics.spec import Needs
    from mta_sim_ros.run import fidelity

    sc = dataclasses.replace(loader.load_scene("config/scenes/side_slope_pass.yaml"), duration=25.0)
    runs = {}
    for level in ("dynamic", "slip"):
        seen = []
        _, err = run_scene(dataclasses.replace(sc, fidelity=level), on_output=seen.append)
        assert err is None
        runs[level] = seen
    pairs = list(zip(runs["dynamic"], runs["slip"]))
    measured = {
        "poses": max(float(np.max(np.hypot(*(a.axle - b.axle).T))) for a, b in pairs),
        "speed": max(abs(a.speed - b.speed) for a, b in pairs),
        "power": math.sqrt(np.mean([(a.power - b.power) ** 2 for a, b in pairs]) / np.mean([b.power ** 2 for _, b in pairs])),
    }
    predicted = fidelity.estimate(sc)["dynamic"]
    assert measured["poses"] > 0.1  # the drift is there to be bounded
    for key, value in measured.items():
        assert value <= predicted[key], (key, value, predicted[key])
    choice = fidelity.choose(dataclasses.replace(sc, fidelity="auto", needs=Needs(poses=0.5)))
    assert choice.level == "slip"


# -- rollover margin ------------------------------------------------------------------------------
@pytest.mark.parametrize("track, height", [(1.8, 1.1), (2.4, 0.9)])
def test_rollover_margin_of_a_cart_across_a_side_slope(track, height):
    """A cart across a side slope b (heading along the contour): roll = b, pitch = 0 and the margin
    1 - 2 h tan(b) / t, zero where tan(b) = t / (2 h); up the grade the roll is 0 and the margin 1."""
    from mta_sim_ros.physics.terrain import Stance

    tip = track / (2 * height)
    for tan_b in (0.1, 0.3, tip):
        carts = tuple(dataclasses.replace(c, track_width=track, com_height=height) for c in trains.train(2).carts)
        st = Stance(dataclasses.replace(trains.train(2), carts=carts, terrain=Plane(0.0, tan_b)))
        roll, pitch = st.angles(np.array([0.0, 0.0]))
        assert roll == pytest.approx([math.atan(tan_b)] * 2, abs=1e-12)
        assert pitch == pytest.approx([0.0, 0.0], abs=1e-12)
        assert st.margins(np.array([0.0, 0.0])) == pytest.approx([1 - 2 * height * tan_b / track] * 2, abs=1e-12)
        up = st.margins(np.array([0.5 * math.pi, 0.5 * math.pi]))  # along +y: straight up the slope
        assert up == pytest.approx([1.0, 1.0], abs=1e-12)
    assert st.margins(np.array([0.0, 0.0])) == pytest.approx([0.0, 0.0], abs=1e-12)


def test_rollover_margin_on_a_slope_both_ways_is_the_statics_of_the_cart_in_its_own_frame():
    """On a plane tilted both ways, at any heading: gravity in the cart's frame is R^T (0, 0, -g)
    with R = PlaneFrame.rotation (the plane's axes, not the roll and pitch formulas). Its normal part
    is carried by the two wheels, its lateral part tips the cart about the downhill wheels' line:
    the wheel loads solved from those balances give the margin, the uphill load over half the total."""
    from mta_sim_ros.physics.terrain import Stance

    track, height, g = 2.2, 1.4, 9.81
    plane = Plane(0.25, -0.35)
    carts = tuple(dataclasses.replace(c, track_width=track, com_height=height) for c in trains.train(2).carts)
    st = Stance(dataclasses.replace(trains.train(2), carts=carts, terrain=plane))
    frame = PlaneFrame.of(plane)
    for heading in np.linspace(-math.pi, math.pi, 25):
        gb = frame.rotation(heading).T @ np.array([0.0, 0.0, -g])  # (along, left, normal) in the cart
        A = np.array([[1.0, 1.0], [-track / 2, track / 2]])
        loads = np.linalg.solve(A, [-gb[2], abs(gb[1]) * height])  # per kg: uphill, downhill
        assert st.margins(np.array([heading, heading])) == pytest.approx([loads[0] / (-gb[2] / 2)] * 2, abs=1e-12)


def test_the_run_report_states_roll_pitch_and_the_rollover_margin(tmp_path):
    """`mta run` on a slope reports the largest roll and pitch and the smallest rollover margin of
    the carts that give track_width and com_height; a train without them says so."""
    from mta_sim_ros import cli

    text = open("config/trains/default.yaml", encoding="utf-8").read()
    text = text.replace("  - name: seeder\n", "  - name: seeder\n    track_width: 3.0\n    com_height: 1.2\n")
    assert "track_width" in text
    (tmp_path / "trains").mkdir()
    (tmp_path / "trains" / "default.yaml").write_text(text, encoding="utf-8")
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    scene = open("config/scenes/side_slope_pass.yaml", encoding="utf-8").read().replace("duration: 40", "duration: 5")
    (scenes / "s.yaml").write_text(scene, encoding="utf-8")
    assert cli.main(["run", "--scene", str(scenes / "s.yaml"), "--bag", str(tmp_path / "s.mcap"), "--quiet"]) == 0
    report = (tmp_path / "s.md").read_text(encoding="utf-8")
    r = math.sqrt(1 + 0.04 ** 2)  # heading along x: tan(roll) = 0.12 / r
    expect = 1 - 2 * 1.2 * (0.12 / r) / 3.0
    row = [line for line in report.splitlines() if "rollover margin" in line][0]
    assert f"{expect:.3f} (seeder" in row
    assert "largest roll / pitch" in report


def test_a_sweep_run_measures_roll_pitch_and_the_rollover_margin():
    """batch.run_metrics (a sweep's run) on a straight pass along the contour of a side slope b:
    the largest roll is b, the pitch 0, the smallest margin the seeder's 1 - 2 h tan(b) / t; on the
    level roll and pitch are 0 and the margin 1; a train without track and height has no margin."""
    from mta_sim_ros.run.batch import run_metrics

    text = open("config/trains/default.yaml", encoding="utf-8").read()
    measured = text.replace("  - name: seeder\n", "  - name: seeder\n    track_width: 3.0\n    com_height: 1.2\n")
    scene = {"name": "contour", "train": "t.yaml", "duration": 4.0, "initial": {"speed": 3.0}, "speed": 3.0,
             "steering": {"maneuver": "straight"}, "integrator": {"method": "rk4", "step": 0.01},
             "fidelity": "dynamic"}
    for train_text, terrain, roll, margin in ((measured, 15.0, math.atan(0.15), 1 - 2 * 1.2 * 0.15 / 3.0),
                                              (measured, 0.0, 0.0, 1.0), (text, 15.0, math.atan(0.15), math.nan)):
        tr = loader.load_train_text(train_text, "t.yaml")
        sc = loader.scene_from_data(dict(scene, terrain={"grade_percent": 0, "cross_slope_percent": terrain}),
                                    "s.yaml", tr)
        got = run_metrics(sc).metrics
        assert got["max_roll_deg"] == pytest.approx(math.degrees(roll), abs=1e-9)
        assert got["max_pitch_deg"] == pytest.approx(0.0, abs=1e-9)
        assert got["min_rollover_margin"] == pytest.approx(margin, abs=1e-9, nan_ok=True)


def test_analyze_reads_the_terrain_from_the_bag_and_draws_the_stance(tmp_path):
    """`mta analyze` of a run on a slope takes the plane from the bag's recorded scene (no file it
    names is opened) and draws stance.png (roll, pitch, margins); the poses' headings give the
    closed-form margin of the air cart along the contour. A level run draws no stance.png."""
    import shutil

    from mta_sim_ros import analysis, cli
    from mta_sim_ros.physics.terrain import Stance

    shutil.copy("config/trains/hillside_unit.yaml", tmp_path / "hillside_unit.yaml")
    text = open("config/scenes/side_slope_pass.yaml", encoding="utf-8").read()
    text = text.replace("../trains/default.yaml", "hillside_unit.yaml").replace("duration: 40", "duration: 4")
    (tmp_path / "slope.yaml").write_text(text, encoding="utf-8")
    (tmp_path / "level.yaml").write_text(text.replace("terrain:", "# terrain:"), encoding="utf-8")
    for name in ("slope", "level"):
        assert cli.main(["run", "--scene", str(tmp_path / f"{name}.yaml"), "--bag", str(tmp_path / f"{name}.mcap"),
                         "--quiet"]) == 0
    (tmp_path / "hillside_unit.yaml").unlink()  # the bag alone
    for name in ("slope", "level"):
        assert cli.main(["analyze", str(tmp_path / f"{name}.mcap"), "-o", str(tmp_path / f"r_{name}")]) == 0
    assert (tmp_path / "r_slope" / "stance.png").stat().st_size > 10_000
    assert "stance.png" in (tmp_path / "r_slope" / "summary.md").read_text(encoding="utf-8")
    assert not (tmp_path / "r_level" / "stance.png").exists()
    data = analysis.load_bag(tmp_path / "slope.mcap")
    assert data.train.terrain == Plane(0.04, 0.12)
    first = Stance(data.train).margins(data.pose_heading.values[:1])[0]
    tan_roll = 0.12 / math.sqrt(1 + 0.04 ** 2)  # heading along x (the scene's start)
    assert first[1] == pytest.approx(1 - 2 * 1.9 * tan_roll / 2.8, abs=1e-9)


def test_track_without_height_is_one_line():
    text = open("config/trains/default.yaml", encoding="utf-8").read()
    text = text.replace("  - name: seeder\n", "  - name: seeder\n    track_width: 3.0\n")
    with pytest.raises(SpecError) as err:
        loader.load_train_text(text, "t.yaml")
    assert "\n" not in str(err.value) and "track_width" in str(err.value) and "com_height" in str(err.value)
