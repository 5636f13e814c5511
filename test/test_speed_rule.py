"""One rule for a speed the train cannot follow (issue 25): a train whose traction law is constant
holds F_A1 = force whatever V is asked (physics.spec.unfollowed_speed). A scene's speed table is
refused by the loader (mta check, mta run, sweeps), the controllers that command a speed refuse the
train at start (mta reverse, mta follow on a field, mta field run, the reversing and implement
controllers as an API), and the node says once, in its log and in /diagnostics, that it ignores the
speed commands it is sent (speed_setpoint, cmd_vel, ackermann_cmd). In process, with a set clock."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from test_controllers import ackermann, twist
from test_session import REPO, Run, run  # noqa: F401 (run: the fixture)

from mta_sim_ros import cli
from mta_sim_ros.controllers.implement.design import controller
from mta_sim_ros.controllers.reversing.controller import design, design_curve
from mta_sim_ros.node.status import OK, WARN
from mta_sim_ros.physics.loader import SpecError, load_scene, load_train
from mta_sim_ros.physics.spec import Table, unfollowed_speed
from mta_sim_ros.run.batch import run_trace
from mta_sim_ros.validate import InputError

FORCE = 60000.0
SCENE = ("name: constant_force\ntrain: train.yaml\nduration: 6\n"
         "initial: {x: 0, y: 0, heading: 0, speed: -1.0, steering: 0}\n"
         "steering: {table: {time: [0], angle: [0]}}\n"
         "integrator: {method: rk4, step: 0.01}\npublish_rate: 50\n")


def write_train(folder: Path, traction: str) -> Path:
    """trains/default.yaml (it has an implement) with its traction replaced by ``traction``."""
    train = (REPO / "config" / "trains" / "default.yaml").read_text()
    start, end = train.index("  traction:\n"), train.index("  rolling:")
    path = folder / "train.yaml"
    path.write_text(train[:start] + f"  traction: {traction}\n" + train[end:])
    return path


@pytest.fixture
def constant(tmp_path) -> Path:
    """A folder with a constant-force train (train.yaml) and a scene of it without a speed (scene.yaml)."""
    write_train(tmp_path, f"{{law: constant, force: {FORCE:g}}}")
    (tmp_path / "scene.yaml").write_text(SCENE)
    return tmp_path


def refused(capsys, *args) -> str:
    """``mta ARGS`` refused: exit 2, one line on stderr, no traceback; returns the line."""
    code = cli.main(list(map(str, args)))
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_the_constant_law_ignores_the_speed_it_is_given(constant):
    """What the refusals rest on: the same run with and without a speed table is the same to the bit
    (the law never reads V's set-point), and it does not reverse at -1 m/s but drives forward."""
    scene = load_scene(str(constant / "scene.yaml"))
    asked = dataclasses.replace(scene, speed=Table(time=(0.0,), value=(-1.0,)))
    plain, with_speed = run_trace(scene)[1], run_trace(asked)[1]
    assert np.array_equal(plain, with_speed, equal_nan=True)
    assert unfollowed_speed(scene.train.traction) == f"traction law constant holds F_A1 = {FORCE:g} N whatever the speed"


@pytest.mark.parametrize("speed", ["-1.0", "{table: {time: [0, 3], speed: [-1, 2]}}"])
def test_a_scene_speed_for_a_constant_law_is_refused_in_one_line(constant, capsys, speed):
    (constant / "bad.yaml").write_text(SCENE + f"speed: {speed}\n")
    with pytest.raises(SpecError, match="^speed: .* must be left out for train 'default_seeding_unit': its traction "
                                        "law constant holds F_A1 = 60000 N whatever the speed"):
        load_scene(str(constant / "bad.yaml"))
    for command in (("check",), ("run", "--scene")):
        line = refused(capsys, *command, constant / "bad.yaml")
        assert "speed: " in line and "governor or prescribed_speed" in line
    assert not list(constant.glob("*.mcap"))
    load_scene(str(constant / "scene.yaml"))  # no speed: the law's own force, a run like any other


def test_a_governed_train_keeps_its_speed_table(tmp_path):
    (tmp_path / "train.yaml").write_text((REPO / "config" / "trains" / "default.yaml").read_text())  # a governor
    (tmp_path / "scene.yaml").write_text(SCENE + "speed: -1.0\n")
    assert load_scene(str(tmp_path / "scene.yaml")).speed.value == (-1.0,)


def test_the_controllers_that_command_a_speed_refuse_the_train_at_start(constant, capsys):
    train = load_train(str(constant / "train.yaml"))
    rule = "forces.traction.law: 'constant' of .*train.yaml must be governor or prescribed_speed: "
    with pytest.raises(InputError, match=rule + "the reversing controller commands a speed, and its traction law "
                                         "constant holds F_A1 = 60000 N whatever the speed"):
        design(train, -1.0)
    with pytest.raises(InputError, match=rule + "the reversing controller"):
        design_curve(train, -1.0, 30.0)
    with pytest.raises(InputError, match=rule + "the implement controller"):
        controller(train)
    assert "mta reverse commands a speed" in refused(capsys, "reverse", "--scene", constant / "scene.yaml")
    field = REPO / "config" / "fieldwork" / "rectangle.yaml"
    out = constant / "out"
    assert "mta field run commands a speed" in refused(capsys, "field", "run", field, "--train",
                                                         constant / "train.yaml", "--out", out)
    assert not out.exists()
    assert "mta follow commands a speed" in refused(capsys, "follow", "--field", field, "--train",
                                                    constant / "train.yaml")


def test_the_node_says_once_that_it_ignores_speed_commands(constant):
    r = Run(constant, scene_file=str(constant / "scene.yaml"))
    assert r.s.diagnostics().values["speed_commands_ignored"] == 0 and r.s.diagnostics().level == OK
    r.ticks(3)
    r.s.command("speed_setpoint", 2.0)
    r.s.command_message("cmd_vel", twist(-1.0, 0.1))
    r.s.command("steering_angle", 0.1)  # a steering command is followed: not counted
    r.s.command_message("ackermann_cmd", ackermann(0.05, 1.5))
    r.ticks(60)
    r.s.command("speed_setpoint", 3.0)
    said = "speed_setpoint: speed commands are ignored: the train's traction law constant holds F_A1 = 60000 N"
    assert r.log.count("warning", said) == 1 and r.log.count("warning", "speed commands are ignored") == 1
    d = r.s.diagnostics()
    assert d.level == WARN and said in d.message and d.values["speed_commands_ignored"] == 4
    r.s.reset()
    d = r.s.diagnostics()
    assert d.values["speed_commands_ignored"] == 0 and "ignored" not in d.message
    r.s.command_message("cmd_vel", twist(1.0, 0.0))  # a new run says it again, once
    assert r.log.count("warning", "cmd_vel: speed commands are ignored") == 1
    r.s.close()


def test_a_governed_train_follows_its_speed_commands_without_a_word(run):
    run.s.command("speed_setpoint", 2.0)
    run.s.command_message("cmd_vel", twist(1.0, 0.0))
    d = run.s.diagnostics()
    assert d.values["speed_commands_ignored"] == 0 and "ignored" not in d.message
    assert run.log.count("warning", "ignored") == 0


def test_the_kinematic_level_is_refused_for_a_constant_law_by_check_as_by_run(constant, capsys):
    (constant / "kin.yaml").write_text(SCENE + "fidelity: kinematic\n")
    line = refused(capsys, "check", constant / "kin.yaml")
    assert "fidelity: 'kinematic'" in line and "the kinematic level prescribes the speed" in line


def test_a_field_run_refuses_speeds_it_cannot_drive_before_writing(tmp_path, capsys):
    """A prescribed_speed train whose set speed (the working speed by default) is 0: one line naming
    it, and no output folder made."""
    write_train(tmp_path, "{law: prescribed_speed, set_speed: 0.0, response_time: 1.0}")
    out = tmp_path / "out"
    line = refused(capsys, "field", "run", REPO / "config" / "fieldwork" / "rectangle.yaml", "--train",
                   tmp_path / "train.yaml", "--out", out)
    assert line.startswith("mta field run: set_speed of train 'default_seeding_unit': 0.0 must be > 0 m/s"), line
    assert not out.exists()


def test_a_sweep_of_a_field_scene_refuses_a_constant_law_before_it_runs(constant, capsys):
    (constant / "sweep.yaml").write_text(f"name: field_constant\ntrain: train.yaml\nscenes: "
                                         f"[{REPO / 'config' / 'fieldwork' / 'rectangle.yaml'}]\n"
                                         "sample: {method: grid}\nvary:\n  - path: carts[2].length\n    values: [5, 6]\n")
    line = refused(capsys, "sweep", constant / "sweep.yaml", "--out", constant / "runs")
    assert "forces.traction.law: 'constant'" in line and "implement controller commands a speed" in line
    assert not (constant / "runs").exists()


def test_mta_maneuver_reads_the_speed_the_loader_reads(constant):
    """A manoeuvre that reads the speed, played on a constant-law scene by mta maneuver: the start's
    speed, as the loader expands the same manoeuvre in a scene file (not the law's unused set_speed)."""
    from mta_sim_ros.tools.maneuver import scene_with_maneuver

    params = {"t0": 2.0, "angle": 0.25, "ramp_time": 1.0}
    (constant / "turn.yaml").write_text(SCENE.replace("speed: -1.0", "speed: 3.0").replace(
        "steering: {table: {time: [0], angle: [0]}}", "steering: {maneuver: headland_turn, params: "
        "{t0: 2.0, angle: 0.25, ramp_time: 1.0}}"))
    loaded = load_scene(str(constant / "turn.yaml"))
    straight = dataclasses.replace(loaded, steering=Table(time=(0.0,), value=(0.0,)), maneuver="")
    played = scene_with_maneuver(straight, "headland_turn", params)
    assert played.steering == loaded.steering
