"""The loader's fidelity fields: cart cornering_stiffness, scene fidelity and needs. Each fault
gets the one-line ``FIELD: VALUE in LOCATION of FILE must be RULE`` message (test_loader.py)."""
from __future__ import annotations

import copy

import pytest
from test_loader import SCENE, SCENE_FILES, TRAIN, check_fault, put, write_pair

from mta_sim_ros.physics import loader, spec

FAULTS = [
    ("train", put("carts.1.cornering_stiffness", -2e5), "cornering_stiffness", "-200000", "carts[1]", "> 0"),
    ("train", put("carts.0.cornering_stiffness", 0), "cornering_stiffness", "0", "carts[0]", "> 0"),
    ("train", put("carts.2.cornering_stiffness", "stiff"), "cornering_stiffness", "'stiff'", "carts[2]", "a number"),
    ("train", put("carts.2.cornering_stiffness", float("inf")), "cornering_stiffness", "inf", "carts[2]", "a finite number"),
    ("scene", put("fidelity", "fast"), "fidelity", "'fast'", "top level", "one of auto, kinematic, dynamic, slip"),
    ("scene", put("fidelity", 2), "fidelity", "2", "top level", "one of auto, kinematic, dynamic, slip"),
    ("scene", put("needs", 0.5), "needs", "0.5", "top level", "a mapping of fields"),
    ("scene", put("needs", {}), "needs", "{}", "top level", "a non-empty mapping of OUTPUT: tolerance"),
    ("scene", put("needs", {"pose": 0.5}), "pose", "0.5", "needs", "unknown field; expected one of poses, speed"),
    ("scene", put("needs", {"poses": 0}), "poses", "0", "needs", "> 0"),
    ("scene", put("needs", {"power": -0.1}), "power", "-0.1", "needs", "> 0"),
    ("scene", put("needs", {"speed": "tight"}), "speed", "'tight'", "needs", "a number"),
]


@pytest.mark.parametrize("target, mutate, field, value, where, rule", FAULTS,
                         ids=[f"{i:02d}-{row[0]}-{row[2]}" for i, row in enumerate(FAULTS)])
def test_fault_message(tmp_path, target, mutate, field, value, where, rule):
    check_fault(tmp_path, target, mutate, field, value, where, rule)


def test_fields_read_with_their_defaults(tmp_path):
    train, scene = copy.deepcopy(TRAIN), copy.deepcopy(SCENE)
    _, scene_path = write_pair(tmp_path, train, scene)
    sc = loader.load_scene(scene_path)
    assert sc.fidelity == "auto" and sc.needs is None
    assert all(c.cornering_stiffness is None for c in sc.train.carts)

    train["carts"][1]["cornering_stiffness"] = 150000
    scene.update(fidelity="SLIP", needs={"poses": 0.5, "power": 0.05})
    _, scene_path = write_pair(tmp_path, train, scene)
    sc = loader.load_scene(scene_path)
    assert sc.fidelity == "slip"  # matched case-insensitively, spelled as listed
    assert sc.needs == spec.Needs(poses=0.5, power=0.05)
    assert sc.needs.asked() == {"poses": 0.5, "power": 0.05}
    assert sc.train.carts[1].cornering_stiffness == 150000.0


NEEDS_SCENES = ("straight_pass", "steady_turn", "lane_change", "slalom", "headland_turn")


@pytest.mark.parametrize("name", NEEDS_SCENES)
def test_shipped_scenes_state_their_needs(name):
    """The five original scenes say what they need, so `auto` has something to choose by."""
    path = next(p for p in SCENE_FILES if p.stem == name)
    sc = loader.load_scene(path)
    assert sc.fidelity in ("auto",) + spec.FIDELITY_LEVELS
    assert sc.needs is not None and sc.needs.asked()
