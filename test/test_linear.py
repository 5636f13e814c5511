"""The linear model (linear.py, mta linearize) against closed forms and against the simulator:
eigenvalues about straight motion (MODEL.md: -V / l_k per hitch, 0, 0, -1 / tau; the bicycle for
one cart) and about steady turns (-Omega R_Bk / l_k, +-i Omega, -1 / tau), forward and reversing;
A against small perturbations integrated by the simulator itself."""
from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest
from scipy.linalg import expm

from mta_sim_ros import cli
from mta_sim_ros.config import resolve_config_path
from mta_sim_ros.physics import loader
from mta_sim_ros.physics.steady import steady_circle
from mta_sim_ros.run.simulation import Simulation
from mta_sim_ros.symbolic import linear

DEFAULT = loader.load_train(resolve_config_path("trains/default.yaml"))
OFFSET = loader.load_train(resolve_config_path("trains/offset_hitch.yaml"))
LONG = loader.load_train(resolve_config_path("trains/long_train.yaml"))
LONG20 = loader.load_train(resolve_config_path("trains/long_train_20.yaml"))


def random_train(rng, n: int):
    carts = [{"name": f"c{k}", "length": rng.uniform(1.5, 8.0), "hitch_offset": rng.uniform(-1.0, 2.0),
              "com_offset": rng.uniform(-1.0, 3.0), "mass": 5000.0, "yaw_inertia": 20000.0} for k in range(n)]
    data = {"name": f"random{n}", "carts": carts,
            "forces": {"traction": {"law": "governor", "set_speed": 3.0, "kp": 1e4, "ki": 1e3, "max_force": 1e5,
                                    "max_power": 3e5}, "rolling": [],
                       "draft": []},
            "steering_actuator": {"time_constant": rng.uniform(0.05, 0.5), "max_rate": 0.5, "max_angle_deg": 45}}
    return loader.train_from_data(data, "random")


@pytest.mark.parametrize("speed", [3.0, 1.0, -1.0, -3.0])
@pytest.mark.parametrize("train", [DEFAULT, OFFSET, LONG, LONG20], ids=lambda t: t.name)
def test_straight_motion_has_the_closed_form_eigenvalues(train, speed):
    model = linear.linearize(train, "straight", speed)
    np.testing.assert_allclose(np.sort(model.eigenvalues.real), linear.straight_closed_form(train, speed),
                               rtol=0, atol=1e-9)
    assert np.all(np.abs(model.eigenvalues.imag) < 1e-12)
    grows = [m for m in model.modes if "grows" in m]
    assert len(grows) == (train.n - 1 if speed < 0 else 0)  # reversing: every hitch folds


@pytest.mark.slow
def test_random_trains_straight_eigenvalues():
    rng = np.random.default_rng(14)
    for n in range(1, 6):
        for _ in range(3):
            train = random_train(rng, n)
            speed = rng.choice([-1.0, 1.0]) * rng.uniform(0.5, 5.0)
            model = linear.linearize(train, "straight", speed)
            np.testing.assert_allclose(np.sort(model.eigenvalues.real), linear.straight_closed_form(train, speed),
                                       rtol=0, atol=1e-9)


def test_one_cart_is_the_kinematic_bicycle():
    """th' = V sin(psi) / l_1 and y' = V sin(th + psi): A = [[0, V, V], [0, 0, V / l], [0, 0, -1/tau]]."""
    one = loader.load_train(resolve_config_path("trains/single_tractor.yaml"))
    V, l, tau = 2.5, one.carts[0].length, one.actuator.time_constant
    model = linear.linearize(one, "straight", V)
    assert model.states == ["y", "th", "psi"]
    np.testing.assert_allclose(model.A, [[0, V, V], [0, 0, V / l], [0, 0, -1 / tau]], rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(model.B.ravel(), [0, 0, 1 / tau], rtol=1e-14)


TURNS = [(3.0, 0.25), (3.0, -0.25), (1.0, 0.1), (-2.0, 0.2), (-1.0, -0.15)]


@pytest.mark.parametrize("train, speed, steering", [(t, v, s) for t in (DEFAULT, OFFSET) for v, s in TURNS] +
                         [(LONG20, 3.0, 0.16), (LONG20, -1.0, -0.1)], ids=lambda v: getattr(v, "name", v))
def test_a_steady_turn_has_the_closed_form_eigenvalues(train, speed, steering):
    model = linear.linearize(train, "turn", speed, steering)
    expected = linear.turn_closed_form(train, speed, steering)
    key = lambda z: (round(z.real, 6), round(z.imag, 6))  # noqa: E731
    got = sorted(model.eigenvalues, key=key)
    want = sorted(expected, key=key)
    np.testing.assert_allclose(np.array(got), np.array(want), rtol=0, atol=1e-9)
    circle = steady_circle(train, steering)
    np.testing.assert_allclose(model.point[2:-1], circle.hitch_angles, rtol=0, atol=0)


def scene_for(train, speed: float, steering: float, hitch, duration: float):
    """A scene of ``train`` at ``speed`` (the kinematic level: the speed prescribed, as the linear
    model holds it), steering command ``steering`` held, starting from the given hitch angles."""
    scene = {"name": "perturbed", "train": "unused.yaml", "duration": duration,
             "initial": {"speed": speed, "steering": steering, "hitch_angles": list(hitch)},
             "steering": {"table": {"time": [0], "angle": [steering]}}, "speed": speed,
             "integrator": {"method": "rk4", "step": 0.005}, "publish_rate": 100, "fidelity": "kinematic"}
    return loader.scene_from_data(scene, "perturbed scene", train)


def simulate(train, speed, steering, x0: np.ndarray, about: str, T: float) -> np.ndarray:
    """The simulator's state after T s from x0, both in the linear model's coordinates. About a
    turn the centre is the origin and A_1 starts on the positive x axis (alpha = 0): its position
    (R_A1 + rho, 0), its heading th_1 = alpha + eta."""
    n = train.n
    hitch = x0[2:2 + n - 1]
    sim = Simulation(scene_for(train, speed, steering, hitch, T))
    L = sim.model.layout
    y = sim.y.copy()
    R = steady_circle(train, steering).R_A[0] if about == "turn" else 0.0
    y[L.x], y[L.y] = (R + x0[0], 0.0) if about == "turn" else (0.0, x0[0])
    heading = [x0[1]]
    for phi in hitch:
        heading.append(heading[-1] - phi)
    y[L.heading] = heading
    y[L.steering] = x0[-1]
    sim.y = y
    while sim.t < T - 1e-9:
        sim.advance(steering, speed)
    y = sim.y
    th = y[L.heading]
    phis = [th[k - 1] - th[k] for k in range(1, n)]
    if about == "straight":
        return np.array([y[L.y], th[0], *phis, y[L.steering]])
    return np.array([math.hypot(y[L.x], y[L.y]) - R, th[0] - math.atan2(y[L.y], y[L.x]), *phis, y[L.steering]])


@pytest.mark.parametrize("about, speed, steering", [("straight", 3.0, 0.0), ("straight", -1.0, 0.0),
                                                     ("turn", 3.0, 0.25), ("turn", 2.0, -0.2)])
def test_a_small_perturbation_moves_as_exp_At(about, speed, steering):
    """From the operating point plus a small perturbation d (1e-5 in every state), the simulator
    (kinematic level, rk4 at 5 ms) after T = 1 s is at x0 + expm(A T) d to within 2e-3 |d|
    (the model's nonlinearity is O(|d|^2); a wrong entry of A moves it by O(|d|))."""
    train = DEFAULT
    model = linear.linearize(train, about, speed, steering)
    d = 1e-5 * np.array([1.0, -0.7, 0.5, -0.3, 0.8])
    x_eq = model.point
    T = 1.0
    base = simulate(train, speed, steering, x_eq, about, T)
    moved = simulate(train, speed, steering, x_eq + d, about, T)
    predicted = expm(model.A * T) @ d
    error = np.abs((moved - base) - predicted)
    assert error.max() < 2e-3 * np.abs(d).max(), (moved - base, predicted)
    wrong = model.A.copy()
    wrong[2, 4] *= 1.05  # a 5 % error in one entry is seen
    assert np.abs((moved - base) - expm(wrong * T) @ d).max() > 2e-3 * np.abs(d).max()


def test_mta_linearize_writes_markdown_json_and_npz(tmp_path, capsys):
    prefix = tmp_path / "lin"
    assert cli.main(["linearize", "trains/default.yaml", "--about", "turn", "--steering", "0.25", "--speed", "3",
                     "--out", str(prefix)]) == 0
    out = capsys.readouterr().out
    hitch2 = linear.turn_closed_form(DEFAULT, 3.0, 0.25)[0].real  # -Omega R_B2 / l_2, the faster hitch
    assert f"| {hitch2:.6g} | phi2: hitch 2's mode, decays |" in out
    data = json.loads((tmp_path / "lin.json").read_text())
    assert data["states"] == ["rho", "eta", "phi2", "phi3", "psi"] and len(data["eigenvalues"]) == 5
    saved = np.load(tmp_path / "lin.npz")
    np.testing.assert_array_equal(saved["A"], np.array(data["A"]))
    assert (tmp_path / "lin.md").read_text() == out.split(str(tmp_path))[0]


@pytest.mark.parametrize("args, field", [
    (["--speed", "0"], "--speed"), (["--about", "turn"], "--steering"),
    (["--about", "turn", "--steering", "0.6"], "--steering"), (["--steering", "0.1"], "--steering"),
    (["--speed", "nan"], "--speed"), (["--about", "turn", "--steering", "1.2"], "--steering")])
def test_bad_arguments_are_refused_in_one_line(args, field, capsys):
    try:
        code = cli.main(["linearize", "trains/default.yaml", *args])
    except SystemExit as done:  # argparse's own refusals
        code = done.code
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and field in err, err


@pytest.mark.parametrize("about, speed, steering", [("straight", 3.0, 0.0), ("straight", -1.0, 0.0),
                                                    ("turn", 2.0, 0.3), ("turn", -1.0, -0.2)])
def test_forward_mode_gives_the_symbolic_jacobians(about, speed, steering):
    """exact='dual' (forward-mode through chain.chain, no sympy) against sympy's Jacobian of the
    same equations, on random trains of 1 to 5 carts: the same A and B to round-off."""
    rng = np.random.default_rng(20)
    for n in range(1, 6):
        train = random_train(rng, n)
        try:
            symbolic = linear.linearize(train, about, speed, steering, exact="sympy")
        except Exception as err:  # no steady turn for this train at this steering
            assert about == "turn", err
            continue
        dual = linear.linearize(train, about, speed, steering, exact="dual")
        scale = max(1.0, float(np.abs(symbolic.A).max()))
        np.testing.assert_allclose(dual.A, symbolic.A, rtol=0, atol=1e-13 * scale)
        np.testing.assert_allclose(dual.B, symbolic.B, rtol=0, atol=1e-13 * scale)
        assert dual.states == symbolic.states and dual.modes == symbolic.modes


def test_a_wrong_derivative_in_the_dual_numbers_would_show():
    """The comparison above can fail: the dual numbers' sin with a wrong derivative sign changes A."""
    train = DEFAULT
    good = linear.linearize(train, "straight", 3.0, exact="dual")
    point, geom = [0.0] * (train.n + 2), linear.ChainGeometry.of(train)
    seeds = np.eye(train.n + 3)

    class Wrong(linear.Dual):
        @staticmethod
        def sin(a):
            a = linear.Dual.of(a)
            return linear.Dual(math.sin(a.v), -math.cos(a.v) * a.d)

    x = [linear.Dual(v, seeds[i]) for i, v in enumerate(point)]
    f = linear.equations(x, linear.Dual(0.0, seeds[-1]), 3.0, train.actuator.time_constant, 1.0, geom, "straight",
                         Wrong)
    A = np.array([linear.Dual.of(fi).d * np.ones(train.n + 3) for fi in f])[:, :-1]
    assert np.abs(A - good.A).max() > 0.1
