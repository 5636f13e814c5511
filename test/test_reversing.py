"""Backing up (reversing.py, mta reverse): the LQR gain from the linear model stabilises what the
open loop cannot (every hitch mode grows at V / l_k reversing), on the simulator offline and over
DDS against the node in lockstep, with the node's bag read back independently."""
from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
import yaml

from mta_sim_ros.config import resolve_config_path
from mta_sim_ros.controllers.reversing import controller as reversing
from mta_sim_ros.controllers.reversing import envelope
from mta_sim_ros.physics import loader
from mta_sim_ros.symbolic import linear

DEFAULT = loader.load_train(resolve_config_path("trains/default.yaml"))


def reversing_scene(train, speed: float, y: float = 0.5, duration: float = 1000.0):
    data = {"name": "backing", "train": "unused.yaml", "duration": duration,
            "initial": {"y": y, "speed": speed, "hitch_angles_deg": [2, -2][:train.n - 1]},
            "steering": {"maneuver": "straight"}, "speed": speed,
            "integrator": {"method": "rk4", "step": 0.01}, "publish_rate": 50, "fidelity": "dynamic"}
    return loader.scene_from_data(data, "backing scene", train)


def test_the_gain_makes_every_mode_of_the_reversing_train_decay():
    for speed in (-0.5, -1.0, -3.0):  # the linear model's closed loop (the check, with the limits, is below)
        gains = reversing.design(DEFAULT, speed, check=False)
        open_loop = linear.linearize(DEFAULT, "straight", speed).eigenvalues
        assert sum(e.real > 1e-9 for e in open_loop) == DEFAULT.n - 1  # the hitches fold without it
        assert np.all(gains.closed_loop.real < -1e-3), gains.closed_loop


def test_the_last_axle_row_is_the_lateral_offset_to_first_order():
    """C x against the exact y of B_n for a small pose (the chain's geometry: A_1 back to B_n)."""
    rng = np.random.default_rng(3)
    C = reversing.last_axle_row(DEFAULT)
    for _ in range(5):
        x = 1e-6 * rng.standard_normal(DEFAULT.n + 2)
        heading = [x[1]]
        for phi in x[2:DEFAULT.n + 1]:
            heading.append(heading[-1] - phi)
        y = x[0]
        for k, cart in enumerate(DEFAULT.carts):
            y -= (cart.length + (cart.hitch_offset if k < DEFAULT.n - 1 else 0.0)) * math.sin(heading[k])
        assert C @ x == pytest.approx(y, rel=1e-9, abs=1e-18)


def test_the_default_unit_reverses_100_m_within_5_cm_of_the_line():
    """Offline, 0.5 m to the side and hitches at +-2 deg at the start, 1 m/s backwards: after 30 m
    the seeder's axle stays within 5 cm of the line (measured: 2.3 cm max, 0.6 cm RMS)."""
    gains = reversing.design(DEFAULT, -1.0)
    run = reversing.reverse(reversing_scene(DEFAULT, -1.0), gains, 100.0, settle=30.0)
    assert run.stopped == "" and run.distance >= 100.0
    assert run.max_error < 0.05 and run.rms_error < 0.02
    assert run.max_hitch_deg < 10.0 and run.saturated == 0.0


def curve_start(train, gains, offset: float = 0.3):
    """The initial pose on the steady reversing circle about the origin, A_1 ``offset`` m outside it."""
    from mta_sim_ros.physics.steady import steady_circle

    return {"x": gains.R_A1 + offset, "y": 0.0, "heading": float(gains.point[1]), "speed": gains.speed,
            "steering": gains.steering, "hitch_angles": [float(v) for v in steady_circle(train, gains.steering).hitch_angles]}


@pytest.mark.parametrize("radius, side, speed", [(50.0, 1.0, -1.0), (50.0, -1.0, -1.0), (30.0, 1.0, -2.0)])
def test_the_default_unit_reverses_along_a_gentle_curve(radius, side, speed):
    """About the steady reversing turn that puts the seeder's axle on the circle (its steering from
    the closed-form circles), from 0.3 m outside: after 30 m the axle stays within 5 cm of the circle
    over 100 m of arc (measured: 1.4 cm at 50 m, 1.1 cm at 30 m), every closed-loop mode decaying."""
    from mta_sim_ros.physics.steady import steady_circle

    gains = reversing.design_curve(DEFAULT, speed, radius, side)
    assert steady_circle(DEFAULT, gains.steering).R_B[-1] == pytest.approx(radius, rel=1e-9)
    assert math.copysign(1.0, gains.steering) == side
    assert np.all(gains.closed_loop.real < -1e-3)
    data = {"name": "curve", "train": "unused.yaml", "duration": 1000, "initial": curve_start(DEFAULT, gains),
            "steering": {"maneuver": "straight"}, "speed": speed, "integrator": {"method": "rk4", "step": 0.01},
            "publish_rate": 50, "fidelity": "dynamic"}
    run = reversing.reverse_curve(loader.scene_from_data(data, "curve", DEFAULT), gains, (0.0, 0.0), 100.0, settle=30.0)
    assert run.stopped == "" and run.distance >= 100.0
    assert run.max_error < 0.05 and run.rms_error < 0.02


def test_without_the_controller_the_train_folds():
    """The same start with the steering held straight jackknifes: the controller is what holds it."""
    class Straight:
        speed = -1.0

        @staticmethod
        def command(x, max_angle):
            return 0.0

    run = reversing.reverse(reversing_scene(DEFAULT, -1.0), Straight(), 100.0)
    assert "jackknife" in run.stopped and run.distance < 100.0


# -- where the loop cannot hold: refused before it starts (envelope.py) ---------------------------------

@pytest.mark.parametrize("speed", [-1.0, -3.0])
def test_a_train_the_loop_cannot_hold_is_refused_and_does_fold(speed, capsys):
    """The 5-cart road train (trains/long_train.yaml): design refuses it in one line with the reason;
    the same gain, unchecked, run on the dynamic level from the check's start, jackknifes."""
    from mta_sim_ros import cli
    from mta_sim_ros.validate import InputError

    train = loader.load_train(resolve_config_path("trains/long_train.yaml"))
    with pytest.raises(InputError, match=r"^speed: .* must be one the reversing loop holds for train 'long_train' "
                                         r".*: hitch \d reaches 9\d\.\d deg, past its 90.0 deg limit, after [\d.]+ m; "
                                         r"on the dynamic level it stops after [\d.]+ m: jackknife at t = "):
        reversing.design(train, speed)
    run = reversing.reverse(envelope.start_scene(train, speed), reversing.design(train, speed, check=False), 100.0)
    assert "jackknife" in run.stopped and run.distance < 30.0
    assert cli.main(["reverse", "--scene", "scenes/long_train_turn.yaml", "--speed", str(speed)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "must be one the reversing loop holds for train 'long_train_20'" in err[0]


@pytest.mark.parametrize("n, seed", [(2, 10), (2, 20), (3, 12), (3, 17), (4, 13)])
def test_the_check_says_what_the_dynamic_level_does_on_generated_trains(n, seed):
    """Random trains (lengths 2-7 m, hitches -1.5 to +2 m behind their axles: ahead and behind), at
    -1 and -3 m/s: the check holds the train exactly where the dynamic level's run from the same
    start holds it (envelope.run_holds: not stopped, ending the 100 m within 5 cm of the line), and
    refuses exactly where it folds."""
    from benchmarks.common import random_train

    train = random_train(n, np.random.default_rng(seed))
    for speed in (-1.0, -3.0):
        gains = reversing.design(train, speed, check=False)
        for pattern in envelope.patterns(train):  # each start of the check: its hitches bent either way
            why = envelope.unheld_from(train, gains, pattern)
            run = reversing.reverse(envelope.start_scene(train, speed, pattern=pattern), gains, 100.0, settle=30.0)
            assert (why == "") == envelope.run_holds(run, train.n), (speed, pattern, why, run.stopped, run.trace[-1])
            assert ("reaches" in why) == ("jackknife" in run.stopped)


def test_a_start_the_check_folds_but_the_dynamic_level_holds_is_not_a_refusal():
    """The envelope's one start (benchmarks/reversing.md) where the kinematic check folds a train the
    dynamic level holds: a 3-cart train (the benchmark's seed, its fifth), -1 m/s, hitches bent -2/+2
    deg. design confirms the check's fold on the dynamic level from that start before it refuses
    (unheld_on_both): it accepts the train, and the run from that start holds."""
    from benchmarks.common import random_train

    rng = np.random.default_rng(20261207 + 3)
    train = [random_train(3, rng) for _ in range(5)][-1]
    gains = reversing.design(train, -1.0)  # not refused
    assert re.search(r"^hitch 3 reaches 9\d\.\d deg, past its 90\.0 deg limit", envelope.unheld_from(train, gains, (-1, 1)))
    run = reversing.reverse(envelope.start_scene(train, -1.0, pattern=(-1, 1)), gains, 100.0)
    assert envelope.run_holds(run, 3) and run.distance >= 100.0
    assert reversing.unheld_on_both(train, gains) == ""


def test_a_circle_whose_steady_turn_bends_a_hitch_past_its_limit_is_refused(tmp_path, capsys):
    """The default unit with its hitches limited to 45 deg: a 5 m circle of the last axle needs 61 deg
    of hitch on its steady turn: design_curve and mta reverse --radius refuse it in one line."""
    from mta_sim_ros import cli

    train = yaml.safe_load(open(resolve_config_path("trains/default.yaml")))
    for cart in train["carts"][1:]:
        cart["max_hitch_angle_deg"] = 45
    (tmp_path / "t45.yaml").write_text(yaml.safe_dump(train))
    with pytest.raises(ValueError, match=r"^radius: 5 m bends hitch 3 to 61\.\d deg on its steady turn, past its "
                                         r"45\.0 deg limit"):
        reversing.design_curve(loader.load_train(str(tmp_path / "t45.yaml")), -1.0, 5.0)
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(backing_scene(train=str(tmp_path / "t45.yaml"))))
    assert cli.main(["reverse", "--scene", str(tmp_path / "s.yaml"), "--radius", "5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mta reverse: --radius: 5 m bends hitch 3"), err


@pytest.mark.parametrize("psi0, u, tau", [(0.0, 0.5, 0.2), (0.3, -0.4, 0.2), (0.1, 0.12, 0.2), (0.0, 0.7, 0.001)])
def test_the_checks_actuator_is_the_rate_limited_lag_in_closed_form(psi0, u, tau):
    """envelope.steering_at against the actuator's equation integrated by scipy (rtol 1e-12): at the
    rate limit, then the lag, or the lag alone."""
    from scipy.integrate import solve_ivp

    rate = 0.6
    sol = solve_ivp(lambda t, y: [min(max((u - y[0]) / tau, -rate), rate)], (0.0, 2.0), [psi0], rtol=1e-12,
                    atol=1e-14, dense_output=True, max_step=1e-3)
    for t in np.linspace(0.0, 2.0, 201):
        assert envelope.steering_at(psi0, u, tau, rate, t) == pytest.approx(sol.sol(t)[0], abs=1e-9)


@pytest.mark.parametrize("n, seed, speed", [(2, 10, -3.0), (3, 17, -1.0), (4, 13, -1.0), (4, 12, -3.0)])
def test_gentler_weights_hold_what_the_default_ones_cannot(n, seed, speed):
    """Generated trains the default weights fold: held_design finds weights of LADDER (the steering's
    rate weighed) that the check holds, and with them the dynamic level's run holds too (ends the 100 m
    within 5 cm of the line, envelope.run_holds), from a start they were not chosen on as well (0.3 m
    off the line, every hitch at +1 deg); the default gain, run from the nominal start, folds."""
    from benchmarks.common import random_train

    train = random_train(n, np.random.default_rng(seed))
    default = reversing.design(train, speed, check=False)
    chosen = reversing.held_design(train, speed)
    assert "rate" in chosen.weights and envelope.unheld(train, default) != ""
    start = envelope.start_scene(train, speed)
    for scene in (start, envelope.start_scene(train, speed, offset=0.3, hitch=math.radians(1.0))):
        held = reversing.reverse(scene, chosen, 100.0, settle=30.0)
        assert envelope.run_holds(held, n) and held.distance >= 100.0, (held.stopped, held.trace[-1])
    folded = reversing.reverse(start, default, 100.0, settle=30.0)
    assert "jackknife" in folded.stopped


#: the free-running node's real-time factor until the controller has answered a pose: a tick every
#: 0.4 s of wall time, so that DDS discovery between the two processes (seconds on a loaded
#: machine) leaves the reversing train unsteered for a fraction of a simulated second, not for
#: the seconds in which its hitch modes, growing at V / l_k, fold it
CREEP = 0.05


def full_speed(probe, node, controller, factor: float) -> None:
    """Once the controller has answered a pose of the node (an ackermann_cmd heard), the node's
    real_time_factor set to ``factor`` through its parameter service."""
    from ackermann_msgs.msg import AckermannDriveStamped
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    answers = probe.subscribe("/ackermann_cmd", AckermannDriveStamped)
    assert probe.spin_until(lambda: answers or controller.poll() is not None or node.poll() is not None, 120.0), \
        "the controller answered no pose"
    value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=float(factor))
    reply = probe.call(SetParameters, "/mta_sim/set_parameters",
                       SetParameters.Request(parameters=[Parameter(name="real_time_factor", value=value)]))
    assert reply.results[0].successful, reply.results[0].reason


def run_over_dds(tmp_path, probe, scene: dict, pacing: dict, *extra):
    """``mta reverse`` and then the node (recording) as two processes over DDS until either ends:
    (the controller's exit code, its output, its report); the node stopped with SIGTERM, exit 0.
    Free-running, the node creeps (CREEP) until the controller has answered, then runs at the
    factor asked for."""
    from dds import start_mta, start_node, stop, write_params

    scene_path = tmp_path / "backing.yaml"
    scene_path.write_text(yaml.safe_dump(scene))
    start = {**pacing, "real_time_factor": CREEP} if "real_time_factor" in pacing else pacing
    params = write_params(tmp_path / "p.yaml", scene_file=str(scene_path), bag_dir=str(tmp_path / "bags"),
                          publish_rate=50.0, record=True, **start)
    report = tmp_path / "reverse.json"
    # the controller first: free-running, the node reverses from its first tick on, and a train left
    # unsteered while a controller starts would fold (the hitch modes grow at V / l_k)
    controller = start_mta("reverse", "--scene", scene_path, "--distance", 45, "--settle", 20, "--report", report,
                           *extra)
    node = None
    try:
        # its gain designed and its publisher in the graph before the node's first tick
        assert probe.spin_until(lambda: probe.node.count_publishers("/ackermann_cmd") > 0 or
                                controller.poll() is not None, 120.0), "the controller did not start"
        node = start_node(params, tmp_path / "node.log")
        if "real_time_factor" in pacing:
            full_speed(probe, node, controller, pacing["real_time_factor"])
        finished = probe.spin_until(lambda: controller.poll() is not None or node.poll() is not None, 240.0)
        assert finished, "the controller did not finish: " + (tmp_path / "node.log").read_text()[-2000:]
        return controller.returncode, controller.stdout.read(), json.loads(report.read_text())
    finally:
        if controller.poll() is None:
            controller.kill()
            controller.wait()
        assert node is None or stop(node) == 0


def backing_scene(**changes) -> dict:
    scene = yaml.safe_load(open(resolve_config_path("scenes/reversing.yaml")))
    scene.update(train=str(resolve_config_path("trains/default.yaml")), steering={"maneuver": "straight"})
    scene["initial"] = {"y": 0.3, "speed": -1.0, "hitch_angles_deg": [2, -2]}
    scene.update(changes)
    return scene


@pytest.mark.dds
@pytest.mark.parametrize("lockstep, radius", [(True, None), (False, None), (True, 50.0)],
                         ids=["lockstep", "free-running", "lockstep-curve"])
def test_mta_reverse_backs_the_node_up_over_dds(tmp_path, probe, lockstep, radius):
    """The node (recording; in lockstep, or free-running at 2x real time) and ``mta reverse`` as two
    processes over DDS: the controller reports the seeder within 5 cm of the line over the last 25
    of 45 m reversed, and the node's bag, read independently (rosbags), shows the same: the largest
    |y| of B_n after 20 m."""
    from dds import bags_in, read_bag

    scene, extra = backing_scene(), []
    if radius is not None:  # on the steady reversing circle, 0.3 m outside it
        scene["initial"] = curve_start(DEFAULT, reversing.design_curve(DEFAULT, -1.0, radius))
        extra = ["--radius", radius]
    pacing = {"lockstep": True, "lockstep_timeout": 5.0} if lockstep else {"real_time_factor": 2.0}
    code, output, figures = run_over_dds(tmp_path, probe, scene, pacing, *extra)
    assert code == 0, output
    assert "lateral error of 'seeder'" in output and figures["stopped"] is None
    assert figures["reversed_m"] >= 45.0 and figures["max_m"] < 0.05, figures
    assert figures["max_hitch_deg"] < 10.0
    [bag] = bags_in(tmp_path / "bags")
    poses = [msg for _, msg in read_bag(bag)["/hitch_poses"]]
    l3 = DEFAULT.carts[-1].length
    axle = []
    for msg in poses:
        p = msg.poses[-1]
        th = 2.0 * math.atan2(p.orientation.z, p.orientation.w)
        axle.append((p.position.x - l3 * math.cos(th), p.position.y - l3 * math.sin(th)))
    axle = np.array(axle)
    if radius is None:
        after, error = axle[axle[:, 0] <= axle[0, 0] - 20.0], lambda p: p[:, 1]
    else:  # the circle the controller placed through the first pose it heard (0.3 m off the origin's)
        centre = np.array(figures["centre"])
        assert np.hypot(*centre) < 0.5
        arc = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(axle, axis=0).T))))
        after, error = axle[arc >= 20.0], lambda p: np.hypot(p[:, 0] - centre[0], p[:, 1] - centre[1]) - radius
    assert len(after) > 100
    assert np.abs(error(after)).max() < 0.05
    assert np.abs(error(after)).max() == pytest.approx(figures["max_m"], abs=0.01)


@pytest.mark.dds
def test_mta_reverse_ends_when_the_node_halts(tmp_path, probe):
    """The default unit (which the controller's check holds) started with its hitches bent +-20 deg:
    the loop saturates at once and the train folds within a few metres (benchmarks/reversing.md): the
    node halts (its jackknife guard, ERROR on /diagnostics), and ``mta reverse`` ends at once with
    what it measured and the node's reason in its report, exit 1, instead of waiting for poses that
    will not come."""
    scene = backing_scene()
    scene["initial"]["hitch_angles_deg"] = [20, -20]
    code, output, figures = run_over_dds(tmp_path, probe, scene, {"lockstep": True, "lockstep_timeout": 5.0})
    assert code == 1, output
    assert "the simulator halted: jackknife" in output, output
    assert figures["stopped"].startswith("the simulator halted: jackknife"), figures
    assert 0.0 < figures["reversed_m"] < 45.0 and 20.0 < figures["max_hitch_deg"] <= 91.0, figures
