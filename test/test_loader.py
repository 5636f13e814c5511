"""The YAML loader: shipped files load, every fault gets one precise message, degrees convert.

Each fault message has the form ``FIELD: VALUE in LOCATION of FILE must be RULE``.
"""
from __future__ import annotations

import ast
import copy
import json
import math
import re
from pathlib import Path

import pytest
import yaml
from child import python

from mta_sim_ros.physics import loader, spec
from mta_sim_ros.physics.loader import SpecError

CONFIG = Path(__file__).resolve().parent.parent / "config"
TRAIN_FILES = sorted((CONFIG / "trains").glob("*.yaml"))
SCENE_FILES = sorted((CONFIG / "scenes").glob("*.yaml"))
MESSAGE = re.compile(r"^(?P<field>[^\s:]+): (?P<value>.+) in (?P<where>.+) of (?P<file>\S+) must be (?P<rule>.+)$")

TRAIN = {
    "name": "probe",
    "carts": [
        {"name": "tractor", "length": 3.0, "hitch_offset": 1.5, "com_offset": 1.2, "mass": 16000, "yaw_inertia": 57000},
        {"name": "air_cart", "length": 5.0, "hitch_offset": 1.5, "com_offset": 0.5, "mass": 10000, "yaw_inertia": 51000},
        {"name": "seeder", "length": 6.0, "hitch_offset": 0.0, "com_offset": 2.5, "mass": 8000, "yaw_inertia": 129000},
    ],
    "forces": {
        "traction": {"law": "governor", "set_speed": 3.0, "max_force": 125000, "max_power": 250000, "kp": 34000, "ki": 8500},
        "rolling": [{"cart": "tractor", "coefficient": 0.08}, {"cart": "air_cart", "coefficient": 0.1}],
        "draft": [{"cart": "seeder", "A": 2500, "width": 12, "depth": 1, "soil_factor": 1.0}],
    },
    "steering_actuator": {"time_constant": 0.2, "max_rate": 0.5, "max_angle": 0.7},
}
SCENE = {
    "name": "probe_scene",
    "train": "../trains/probe.yaml",
    "duration": 60,
    "initial": {"speed": 3.0, "hitch_angles": [0, 0]},
    "steering": {"table": {"time": [0, 5, 6], "angle": [0, 0, 0.2]}},
    "speed": 3.0,
    "integrator": {"method": "rk4", "step": 0.01},
    "publish_rate": 50,
}


def write_pair(root: Path, train: dict = TRAIN, scene: dict = SCENE) -> tuple[Path, Path]:
    (root / "trains").mkdir(exist_ok=True)
    (root / "scenes").mkdir(exist_ok=True)
    train_path, scene_path = root / "trains" / "probe.yaml", root / "scenes" / "probe_scene.yaml"
    train_path.write_text(yaml.safe_dump(train))
    scene_path.write_text(yaml.safe_dump(scene))
    return train_path, scene_path


def fault(load, path) -> re.Match:
    """Load ``path``, expect a SpecError, and return its message parsed by MESSAGE."""
    with pytest.raises(SpecError) as info:
        load(path)
    message = str(info.value)
    assert "\n" not in message
    match = MESSAGE.match(message)
    assert match, f"message not in the form 'field: value in location of file must be rule': {message}"
    assert match["file"] == str(path)
    return match


# --------------------------------------------------------------------------- shipped files


@pytest.mark.parametrize("path", TRAIN_FILES, ids=lambda p: p.name)
def test_shipped_train_loads(path):
    train = loader.load_train(path)
    assert train.n >= 1 and train.source == str(path)
    assert loader.load_file(path) == train


@pytest.mark.parametrize("path", SCENE_FILES, ids=lambda p: p.name)
def test_shipped_scene_loads(path):
    scene = loader.load_scene(path)
    assert scene.duration > 0 and scene.source == str(path)
    assert scene.integrator.step is None and scene.integrator.tolerance == 1e-6  # each asks for the default tolerance
    assert scene.raw == yaml.safe_load(path.read_text())


def test_shipped_files_exist():
    assert {p.name for p in TRAIN_FILES} >= {"default.yaml", "single_tractor.yaml", "offset_hitch.yaml", "long_train.yaml"}
    assert {p.name for p in SCENE_FILES} >= {
        "straight_pass.yaml", "steady_turn.yaml", "lane_change.yaml", "headland_turn.yaml", "slalom.yaml"
    }


def test_shipped_train_shapes():
    assert loader.load_train(CONFIG / "trains" / "single_tractor.yaml").n == 1
    assert loader.load_train(CONFIG / "trains" / "long_train.yaml").n == 5
    assert any(c.hitch_offset < 0 for c in loader.load_train(CONFIG / "trains" / "offset_hitch.yaml").carts)


def test_default_train_power_at_field_speed():
    """Straight at 3 m/s: (sum f m g + draft) V lies in the article's 172-186 kW band."""
    train = loader.load_train(CONFIG / "trains" / "default.yaml")
    masses = {c.name: c.mass for c in train.carts}
    rolling = sum(r.coefficient * masses[r.cart] * train.gravity for r in train.rolling)
    draft = sum(d.soil_factor * d.A * d.width * d.depth for d in train.draft if d.B == d.C == 0)
    assert 172e3 <= (rolling + draft) * 3.0 <= 186e3


def steady_circle(train: spec.Train, psi1: float) -> list[tuple[float, float]]:
    """(R_A{k+1}, hitch angle th_k - th_{k+1}) for each hitch on the steady circle at psi_1.

    MODEL.md: R_B1 = l_1 / tan psi_1, R_A{k+1}^2 = R_Bk^2 + a_k^2, sin psi_{k+1} = l_{k+1} / R_A{k+1},
    R_B{k+1}^2 = R_A{k+1}^2 - l_{k+1}^2; hitch angle = psi_{k+1} + beta_k with
    beta_k = atan2(lam_k sin psi_k, cos psi_k), lam_k = a_k / l_k.
    """
    carts = train.carts
    r_b, psi, out = carts[0].length / math.tan(psi1), psi1, []
    for cart, nxt in zip(carts, carts[1:]):
        r_a = math.hypot(r_b, cart.hitch_offset)
        assert r_a > nxt.length, f"no steady circle: R_A of {nxt.name} = {r_a:.2f} <= l = {nxt.length}"
        beta = math.atan2(cart.hitch_offset / cart.length * math.sin(psi), math.cos(psi))
        psi = math.asin(nxt.length / r_a)
        out.append((r_a, psi + beta))
        r_b = math.sqrt(r_a**2 - nxt.length**2)
    return out


@pytest.mark.parametrize("path", SCENE_FILES, ids=lambda p: p.name)
def test_shipped_scene_steering_has_a_steady_circle_with_margin(path):
    """At the scene's largest steering the steady circle exists (R_A{k+1} > 1.3 l_{k+1}) and
    every steady hitch angle stays below 75 % of that coupling's limit: no jackknife. A scene
    built to sit near the limit (NEAR_LIMIT) must still have its circle and stay below the limit."""
    scene = loader.load_scene(path)
    psi1 = max(abs(v) for v in scene.steering.value)
    if psi1 == 0:
        return
    circle, share = (1.0, 1.0) if path.name in NEAR_LIMIT else (1.3, 0.75)
    for (r_a, hitch), cart in zip(steady_circle(scene.train, psi1), scene.train.carts[1:]):
        assert r_a > circle * cart.length
        assert hitch < share * cart.max_hitch_angle


#: Scenes meant to turn about as tight as the train can (benchmarks of where methods fail).
NEAR_LIMIT = {"tight_turn.yaml"}


def test_headland_turn_is_the_main_scene_and_a_u_turn():
    scene = loader.load_scene(CONFIG / "scenes" / "headland_turn.yaml")
    assert scene.maneuver == "headland_turn"
    assert 60 <= scene.duration <= 90
    assert scene.steering.value[0] == scene.steering.value[-1] == 0.0
    assert scene.steering.time[-1] < scene.duration


# --------------------------------------------------------------------------- fault table


def at(doc: dict, path: str):
    """The container and key named by a dotted path such as 'carts.1.mass'."""
    *parents, last = path.split(".")
    for key in parents:
        doc = doc[int(key)] if isinstance(doc, list) else doc[key]
    return doc, (int(last) if isinstance(doc, list) else last)


def put(path: str, value):
    def mutate(doc):
        container, key = at(doc, path)
        container[key] = value
    return mutate


def drop(path: str):
    def mutate(doc):
        container, key = at(doc, path)
        del container[key]
    return mutate


def rename(path: str, new: str):
    def mutate(doc):
        container, key = at(doc, path)
        container[new] = container.pop(key)
    return mutate


def both(*mutations):
    def mutate(doc):
        for m in mutations:
            m(doc)
    return mutate


GOVERNOR = "forces.traction"
FAULTS = [
    # (file, mutation, expected field, value, location, rule substrings)
    ("train", put("carts.1.mass", -3), "mass", "-3", "carts[1]", "> 0"),
    ("train", put("carts.0.length", 0), "length", "0", "carts[0]", "in [0.01, 1000] m"),
    ("train", put("carts.2.yaw_inertia", -1.0), "yaw_inertia", "-1.0", "carts[2]", "> 0"),
    ("train", drop("carts.2.yaw_inertia"), "yaw_inertia", "(missing)", "carts[2]", "given"),
    ("train", rename("carts.0.length", "lenght"), "lenght", "3.0", "carts[0]", "unknown field; expected one of name, length"),
    ("train", put("carts.1.mass", "heavy"), "mass", "'heavy'", "carts[1]", "a number"),
    ("train", put("carts.1.mass", True), "mass", "True", "carts[1]", "a number"),
    ("train", put("carts.0.hitch_offset", math.inf), "hitch_offset", "inf", "carts[0]", "finite"),
    ("train", put("carts.0.com_offset", math.nan), "com_offset", "nan", "carts[0]", "finite"),
    ("train", put("carts", []), "carts", "[]", "top level", "non-empty list"),
    ("train", put("carts", "tractor"), "carts", "'tractor'", "top level", "non-empty list"),
    ("train", put("carts.0", 5), "carts[0]", "5", "top level", "mapping"),
    ("train", put("carts.2.name", "air_cart"), "name", "'air_cart'", "carts[2]", "unique: carts[1]"),
    ("train", put("carts.1.name", 7), "name", "7", "carts[1]", "non-empty string"),
    ("train", put("carts.1.max_hitch_angle", 4.0), "max_hitch_angle", "4.0", "carts[1]", "in (0, pi]"),
    ("train", put("carts.1.max_hitch_angle", 0), "max_hitch_angle", "0", "carts[1]", "in (0, pi]"),
    ("train", put("forces.rolling.0.cart", "tracktor"), "cart", "'tracktor'", "forces.rolling[0]", "the name of a cart"),
    ("train", put("forces.draft.0.cart", "drill"), "cart", "'drill'", "forces.draft[0]", "one of tractor, air_cart, seeder"),
    ("train", put("forces.rolling.1.coefficient", 1.0), "coefficient", "1.0", "forces.rolling[1]", "in [0, 1)"),
    ("train", put("forces.rolling.1.coefficient", -0.1), "coefficient", "-0.1", "forces.rolling[1]", "in [0, 1)"),
    ("train", put("forces.draft.0.A", -1), "A", "-1", "forces.draft[0]", "in [0, 1e+08]"),
    ("train", put("forces.draft.0.C", -0.5), "C", "-0.5", "forces.draft[0]", "in [0, 1e+08]"),
    ("train", put("forces.draft.0.width", 0), "width", "0", "forces.draft[0]", "> 0"),
    ("train", put("forces.draft.0.depth", -1), "depth", "-1", "forces.draft[0]", "> 0"),
    ("train", put("forces.draft.0.soil_factor", 0), "soil_factor", "0", "forces.draft[0]", "> 0"),
    ("train", drop("forces.traction"), "traction", "(missing)", "forces", "given"),
    ("train", put(f"{GOVERNOR}.law", "turbo"), "law", "'turbo'", GOVERNOR, "one of constant, governor, prescribed_speed"),
    ("train", put(GOVERNOR, {"law": "constant"}), "force", "(missing)", GOVERNOR, "given"),
    ("train", put(GOVERNOR, {"law": "constant", "force": 5e4, "kp": 1}), "kp", "1", GOVERNOR, "unknown field; expected one of law, force"),
    ("train", put(GOVERNOR, {"law": "prescribed_speed", "set_speed": 3}), "response_time", "(missing)", GOVERNOR, "given"),
    ("train", put(GOVERNOR, {"law": "prescribed_speed", "response_time": 0}), "response_time", "0", GOVERNOR, "in [0.001, 1e+06] s"),
    ("train", put(f"{GOVERNOR}.kp", 0), "kp", "0", GOVERNOR, "> 0"),
    ("train", put(f"{GOVERNOR}.ki", -1), "ki", "-1", GOVERNOR, "in [0, 1e+09]"),
    ("train", put(f"{GOVERNOR}.max_force", 0), "max_force", "0", GOVERNOR, "> 0"),
    ("train", drop(f"{GOVERNOR}.max_power"), "max_power", "(missing)", GOVERNOR, "given"),
    ("train", drop(f"{GOVERNOR}.set_speed"), "set_speed", "(missing)", GOVERNOR, "given"),
    ("train", put("steering_actuator.time_constant", 0), "time_constant", "0", "steering_actuator", "in [0.001, 1e+06] s"),
    ("train", put("steering_actuator.max_rate", -1), "max_rate", "-1", "steering_actuator", "> 0"),
    ("train", put("steering_actuator.max_angle", 1.6), "max_angle", "1.6", "steering_actuator", "in (0, pi/2)"),
    ("train", rename("steering_actuator.max_angle", "max_angel"), "max_angel", "0.7", "steering_actuator", "unknown field"),
    (
        "train",
        both(drop("steering_actuator.max_angle"), put("steering_actuator.max_angle_deg", 100)),
        "max_angle_deg", "100", "steering_actuator", "in (0, pi/2) (given in degrees: 1.74533 rad)",
    ),
    ("train", put("steering_actuator.max_angle_deg", 40), "max_angle_deg", "40", "steering_actuator", "given alone: max_angle"),
    ("train", put("gravity", 0), "gravity", "0", "top level", "> 0"),
    ("train", put("smoothing_speed", -0.05), "smoothing_speed", "-0.05", "top level", "in [1e-06, 10] m/s"),
    ("train", put("colour", "red"), "colour", "'red'", "top level", "unknown field"),
    ("scene", put("duration", 0), "duration", "0", "top level", "> 0"),
    ("scene", drop("duration"), "duration", "(missing)", "top level", "given"),
    ("scene", rename("duration", "duraton"), "duraton", "60", "top level", "unknown field"),
    ("scene", put("train", "../trains/nope.yaml"), "train", "'../trains/nope.yaml'", "top level", "not found"),
    ("scene", put("integrator.method", "rk5"), "method", "'rk5'", "integrator", "one of euler, heun, ralston, kutta3, rk4, rk38, RK45"),
    ("scene", put("integrator.step", 0.05), "step", "0.05", "integrator", "1/publish_rate] = [2e-06, 0.02] s"),
    ("scene", put("integrator.step", 0), "step", "0", "integrator", "in [1/publish_rate / 10000, 1/publish_rate]"),
    ("scene", put("integrator.rtol", 0), "rtol", "0", "integrator", "in [1e-10, 1]"),
    ("scene", put("integrator.atol", -1e-9), "atol", "-1e-09", "integrator", "> 0"),
    ("scene", put("publish_rate", 0), "publish_rate", "0", "top level", "in [1, 1000] Hz"),
    ("scene", put("steering.table.time", [0, 6, 5]), "time", "[0, 6, 5]", "steering.table", "strictly increasing"),
    ("scene", put("steering.table.time", [0, 5]), "angle", "[0, 0, 0.2]", "steering.table", "as long as time (2 entries)"),
    ("scene", put("steering.table.angle", [0, 0, 0.9]), "angle[2]", "0.9", "steering.table", "within +-max_angle"),
    ("scene", put("steering.table.time", [0, "x", 6]), "time[1]", "'x'", "steering.table", "a finite number"),
    ("scene", put("steering.maneuver", "step"), "steering", "{'maneuver': 'step'", "top level", "exactly one of table, maneuver"),
    ("scene", put("steering", {}), "steering", "{}", "top level", "exactly one of table, maneuver"),
    ("scene", put("steering.params", {"t0": 1}), "params", "{'t0': 1}", "steering", "given only with a maneuver"),
    ("scene", put("steering", {"maneuver": "uturn"}), "maneuver", "'uturn'", "steering", "one of straight, step, ramp"),
    (
        "scene", put("steering", {"maneuver": "lane_change", "params": {"amplitud": 0.1}}),
        "amplitud", "0.1", "steering.params", "unknown field; expected one of t0, amplitude[_deg], duration",
    ),
    (
        "scene", put("steering", {"maneuver": "lane_change", "params": {"amplitude": 1.0}}),
        "amplitude", "1.0", "steering.params", "within the steering actuator's max_angle 0.7 rad",
    ),
    (
        "scene", put("steering", {"maneuver": "sine", "params": {"period": -2}}),
        "period", "-2", "steering.params", "> 0",
    ),
    (
        "scene", put("steering", {"maneuver": "headland_turn", "params": {"ramp_time": 100}}),
        "ramp_time", "100", "steering.params", "shorter: the two ramps alone turn",
    ),
    (
        "scene", both(put("speed", 0.0), put("initial.speed", 0.0), put("steering", {"maneuver": "headland_turn"})),
        "speed", "0.0", "steering.params", "> 0 (a forward speed) (taken from the scene; give it in params)",
    ),
    ("scene", put("initial.hitch_angles", [0]), "hitch_angles", "[0]", "initial", "a list of 2 angles"),
    ("scene", put("initial.hitch_angles", [0, 2.0]), "hitch_angles[1]", "2.0", "initial", "max_hitch_angle"),
    (
        "scene", both(drop("initial.hitch_angles"), put("initial.hitch_angles_deg", [0, 100])),
        "hitch_angles_deg[1]", "100", "initial", "max_hitch_angle",
    ),
    ("scene", put("initial.steering", 1.0), "steering", "1.0", "initial", "within +-max_angle = 0.7 rad"),
    ("scene", put("initial.speed", "fast"), "speed", "'fast'", "initial", "a number"),
    ("scene", both(put("initial.heading", 0), put("initial.heading_deg", 90)), "heading_deg", "90", "initial", "given alone: heading"),
    ("scene", put("speed", "fast"), "speed", "'fast'", "top level", "a number or {table:"),
    ("scene", put("speed", {"table": {"time": [0, 0], "speed": [1, 2]}}), "time", "[0, 0]", "speed.table", "strictly increasing"),
    ("scene", put("speed", {"table": {"time": [0, 1], "v": [1, 2]}}), "v", "[1, 2]", "speed.table", "unknown field"),
]


@pytest.mark.parametrize(
    "target, mutate, field, value, where, rule",
    FAULTS,
    ids=[f"{i:02d}-{row[0]}-{row[2]}" for i, row in enumerate(FAULTS)],
)
def test_fault_message(tmp_path, target, mutate, field, value, where, rule):
    check_fault(tmp_path, target, mutate, field, value, where, rule)


def check_fault(tmp_path, target, mutate, field, value, where, rule):
    """The mutated train or scene file is refused with the one-line message naming them."""
    train, scene = copy.deepcopy(TRAIN), copy.deepcopy(SCENE)
    mutate(train if target == "train" else scene)
    train_path, scene_path = write_pair(tmp_path, train, scene)
    load, path = (loader.load_train, train_path) if target == "train" else (loader.load_scene, scene_path)
    match = fault(load, path)
    assert match["field"] == field
    assert match["value"].startswith(value), match.group(0)
    assert match["where"] == where, match.group(0)
    assert rule in match["rule"], match.group(0)


def test_fault_table_is_large_enough():
    assert len(FAULTS) >= 25


# --------------------------------------------------------------------------- file-level faults


def test_missing_file(tmp_path):
    match = fault(loader.load_train, tmp_path / "nope.yaml")
    assert match["field"] == "file" and match["value"] == "not found"


def test_empty_file(tmp_path):
    path = tmp_path / "empty.yaml"
    path.write_text("# nothing here\n")
    match = fault(loader.load_scene, path)
    assert match["value"] == "empty" and "mapping" in match["rule"]


def test_top_level_not_a_mapping(tmp_path):
    path = tmp_path / "list.yaml"
    path.write_text("- 1\n- 2\n")
    assert "a list" in fault(loader.load_train, path)["value"]


def test_yaml_syntax_error_names_the_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("name: x\ncarts:\n  - {name: tractor, length: 3\nforces: {}\n")
    match = fault(loader.load_train, path)
    assert match["field"] == "yaml"
    assert re.fullmatch(r"line \d+, column \d+", match["where"])
    assert match["rule"] == "valid YAML syntax"


def test_repeated_key_names_the_line(tmp_path):
    path = tmp_path / "twice.yaml"
    path.write_text("name: a\nduration: 5\nduration: 6\n")
    match = fault(loader.load_scene, path)
    assert (match["field"], match["value"], match["where"]) == ("duration", "given twice", "line 3, column 1")


def test_file_neither_train_nor_scene(tmp_path):
    path = tmp_path / "other.yaml"
    path.write_text("foo: 1\n")
    assert "a train (with carts) or a scene (with train)" in fault(loader.load_file, path)["rule"]


def test_train_fault_inside_a_scene_names_the_train_file(tmp_path):
    train = copy.deepcopy(TRAIN)
    train["carts"][1]["mass"] = -3
    train_path, scene_path = write_pair(tmp_path, train)
    with pytest.raises(SpecError, match=re.escape(f"mass: -3 in carts[1] of {train_path} must be > 0")):
        loader.load_scene(scene_path)


# --------------------------------------------------------------------------- check_files


def test_check_files_ok(capsys):
    assert loader.check_files([*TRAIN_FILES, *SCENE_FILES]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == [f"ok: {p}" for p in [*TRAIN_FILES, *SCENE_FILES]]


def test_check_files_fault_prints_one_line_and_returns_2(tmp_path, capsys):
    train = copy.deepcopy(TRAIN)
    train["carts"][1]["mass"] = -3
    train_path, scene_path = write_pair(tmp_path, train)
    status = loader.check_files([CONFIG / "trains" / "default.yaml", train_path])
    captured = capsys.readouterr()
    assert status == 2
    assert captured.out.splitlines() == [f"ok: {CONFIG / 'trains' / 'default.yaml'}"]
    assert captured.err.splitlines() == [f"error: mass: -3 in carts[1] of {train_path} must be > 0 and <= 1e+07 kg"]
    assert "Traceback" not in captured.err


def test_check_files_tells_train_from_scene(tmp_path, capsys):
    train_path, scene_path = write_pair(tmp_path)
    assert loader.check_files([train_path, scene_path]) == 0
    assert isinstance(loader.load_file(train_path), spec.Train)
    assert isinstance(loader.load_file(scene_path), spec.Scene)


# --------------------------------------------------------------------------- conversions


def test_degrees_are_converted_to_radians(tmp_path):
    train, scene = copy.deepcopy(TRAIN), copy.deepcopy(SCENE)
    actuator = train["steering_actuator"]
    del actuator["max_angle"], actuator["max_rate"]
    actuator.update(max_angle_deg=40, max_rate_deg=30)
    train["carts"][1]["max_hitch_angle_deg"] = 80
    scene["initial"] = {"heading_deg": 90, "steering_deg": 10, "hitch_angles_deg": [5, -5]}
    scene["steering"] = {"table": {"time": [0, 1], "angle_deg": [0, 20]}}
    train_path, scene_path = write_pair(tmp_path, train, scene)
    loaded = loader.load_scene(scene_path)
    act = loaded.train.actuator
    assert act.max_angle == pytest.approx(math.radians(40)) and act.max_rate == pytest.approx(math.radians(30))
    assert loaded.train.carts[1].max_hitch_angle == pytest.approx(math.radians(80))
    assert loaded.initial.heading == pytest.approx(math.pi / 2)
    assert loaded.initial.steering == pytest.approx(math.radians(10))
    assert loaded.initial.hitch_angles == pytest.approx((math.radians(5), math.radians(-5)))
    assert loaded.steering.value == pytest.approx((0.0, math.radians(20)))


def test_maneuver_params_in_degrees(tmp_path):
    scene = copy.deepcopy(SCENE)
    scene["steering"] = {"maneuver": "headland_turn", "params": {"angle_deg": 15, "turn_angle_deg": 90, "speed": 2}}
    loaded = loader.load_scene(write_pair(tmp_path, scene=scene)[1])
    assert max(loaded.steering.value) == pytest.approx(math.radians(15))
    assert loaded.maneuver == "headland_turn"


def test_defaults_and_normalisation(tmp_path):
    scene = copy.deepcopy(SCENE)
    del scene["initial"], scene["speed"], scene["publish_rate"], scene["name"]
    scene["integrator"] = {"method": "dop853"}
    train = copy.deepcopy(TRAIN)
    del train["steering_actuator"], train["forces"]["draft"]
    train["forces"]["traction"]["law"] = "Governor"
    loaded = loader.load_scene(write_pair(tmp_path, train, scene)[1])
    assert loaded.integrator.method == "DOP853"
    assert loaded.train.traction.law == "governor"
    assert loaded.initial == spec.Initial() and loaded.speed is None
    assert loaded.publish_rate == spec.Scene.publish_rate and loaded.name == "probe_scene"
    assert loaded.train.actuator == spec.Train.actuator and loaded.train.draft == ()


def test_scientific_notation_reads_as_a_number(tmp_path):
    """Plain YAML 1.1 reads 1e-6 as a string; the loader reads it as the number it means."""
    _, scene_path = write_pair(tmp_path)
    text = yaml.safe_dump({**SCENE, "integrator": {"method": "RK45"}}) + "\n"
    text = text.replace("integrator:\n  method: RK45\n", "integrator:\n  method: RK45\n  rtol: 1e-6\n  atol: 1E-9\n")
    scene_path.write_text(text)
    loaded = loader.load_scene(scene_path)
    assert (loaded.integrator.rtol, loaded.integrator.atol) == (1e-6, 1e-9)


def test_scene_train_path_is_relative_to_the_scene_folder(tmp_path):
    """Loaded from another folder (a process of its own, started in trains/, not the scene's)."""
    write_pair(tmp_path)
    done = python("""
        from pathlib import Path
        from mta_sim_ros.physics import loader
        loaded = loader.load_scene(Path("..") / "scenes" / "probe_scene.yaml")
        print(repr((loaded.train.source, loaded.raw, loaded.source)))
    """, cwd=tmp_path / "trains")
    assert done.returncode == 0, done.stderr
    train_source, raw, source = ast.literal_eval(done.stdout)
    assert train_source == str(Path("..") / "trains" / "probe.yaml")
    assert raw == SCENE and source == str(Path("..") / "scenes" / "probe_scene.yaml")


def test_speed_table_and_number(tmp_path):
    scene = copy.deepcopy(SCENE)
    scene["speed"] = {"table": {"time": [0, 10], "speed": [3, 2]}}
    assert loader.load_scene(write_pair(tmp_path, scene=scene)[1]).speed == spec.Table((0.0, 10.0), (3.0, 2.0))
    assert loader.load_scene(write_pair(tmp_path)[1]).speed == spec.Table((0.0,), (3.0,))


#: In a process of its own: every file opened while the texts load (an audit hook sees each open,
#: by open(), io or pathlib), and then while a train file loads (so the hook is seen to work).
OPENS = """
    import json, re, sys
    from mta_sim_ros.physics import loader
    TRAIN, SCENE, NAMES = sys.argv[1:4]
    train_text, scene_text = open(TRAIN).read(), open(SCENE).read()
    opened, results = [], []
    sys.addaudithook(lambda event, args: opened.append(str(args[0])) if event == "open" else None)
    train = loader.load_train_text(train_text, "recorded train")
    for named in json.loads(NAMES):
        text = re.sub(r"(?m)^train:.*$", f"train: {named}", scene_text)
        scene = loader.load_scene_text(text, "recorded scene", train)
        results.append((scene.train is train, scene.name))
    by_texts = list(opened)
    loader.load_train(TRAIN)
    print(json.dumps({"results": results, "by_texts": by_texts, "by_file": opened[len(by_texts):]}))
"""


def test_a_scene_text_takes_the_train_given_and_opens_no_file():
    """load_scene_text (what mta replay --resimulate reads from a bag): the scene's train: names a
    file that must not be opened, whatever it is (absolute, a directory, a path in a string)."""
    train_path, scene_path = CONFIG / "trains" / "default.yaml", CONFIG / "scenes" / "headland_turn.yaml"
    train_text, scene_text = train_path.read_text(), scene_path.read_text()
    train = loader.load_train_text(train_text, "recorded train")
    names = ["/etc/passwd", "..", '"/etc/shadow"', "../trains/default.yaml"]
    done = python(OPENS, str(train_path), str(scene_path), json.dumps(names))
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout)
    assert seen["results"] == [[True, "headland_turn"]] * len(names)
    assert seen["by_texts"] == []
    assert str(train_path) in seen["by_file"]  # the hook sees what the loader opens
    with pytest.raises(loader.SpecError, match="train: .* in top level of recorded scene must be given"):
        loader.load_scene_text(re.sub(r"(?m)^train:.*$", "", scene_text), "recorded scene", train)
