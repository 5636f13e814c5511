"""A field scene (field/scene.py): a field with its plan's options and speeds, what `mta field run`
takes and what a sweep lists beside manoeuvre scenes.

- The shipped field scenes load; a scene's options reach the plan, and a flag given on the command
  line wins over the scene's.
- Hostile field scenes are refused in one line naming the field, the value and the rule.
- A sweep of a field scene: every row's figures are the ones the field worked directly with the
  same train and options gives (an independent call, not the engine's), bit for bit; a ``scene.``
  factor reaches the scenes that have it (the plan's angle) and leaves the others; the report's
  objectives for a field scene are its time, fuel and skipped area, and a metric no ok run has is
  said with the ones it has.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from fieldcli import field_command, field_refused

from mta_sim_ros.controllers.implement.design import Settings
from mta_sim_ros.controllers.implement.work import work_field
from mta_sim_ros.field.boundary import FieldError
from mta_sim_ros.field.scene import load_field_or_scene, load_field_scene
from mta_sim_ros.physics.loader import load_train
from mta_sim_ros.sweep import engine, report, results
from mta_sim_ros.sweep import spec as sweep_spec
from mta_sim_ros.validate import InputError

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "config"
TRAIN = CONFIG / "trains" / "default.yaml"


def small_field(folder: Path) -> Path:
    """A 160 m x 100 m field (1.6 ha), small enough that a whole run takes a second."""
    path = folder / "small.yaml"
    path.write_text(yaml.safe_dump({"name": "small", "boundary": [[0, 0], [160, 0], [160, 100], [0, 100]],
                                    "headlands": 2}))
    return path


def field_scene(folder: Path, **plan) -> Path:
    path = folder / "small_work.yaml"
    path.write_text(yaml.safe_dump({"name": "small_work", "field": str(small_field(folder)),
                                    "plan": {"angle_deg": 0, **plan}, "drive": {"turn_speed": 2.0}}))
    return path


@pytest.mark.parametrize("name", ["rectangle", "irregular", "kuban", "irregular_by_angle"])
def test_the_shipped_field_scenes_load(name):
    scene = load_field_scene(CONFIG / "fieldwork" / f"{name}.yaml")
    options = scene.options(load_train(TRAIN))
    assert options.width == 12.0 and options.route == "auto" and scene.drive == {"turn_speed": 2.0}
    assert (options.angle == 0.0) == (name == "irregular_by_angle")


def test_a_bare_field_is_a_scene_of_default_options():
    scene = load_field_or_scene(CONFIG / "fields" / "rectangle.yaml")
    assert scene.plan == {} and scene.drive == {} and scene.field.name == "rectangle"


@pytest.mark.parametrize("change, expected", [
    ({"plan": {"angle_deg": 400}}, ("angle_deg: 400", "within +-2 pi rad")),
    ({"plan": {"overlap": 0.5}}, ("overlap: 0.5", "in [0, 0.5)")),
    ({"plan": {"headlands": 2.5}}, ("headlands: 2.5", "a whole number in [0, 20]")),
    ({"plan": {"route": "spiral"}}, ("route: 'spiral'", "boustrophedon")),
    ({"plan": {"turns": "u"}}, ("turns", "turn")),
    ({"drive": {"work_speed": 0}}, ("work_speed: 0", "in (0, 20] m/s")),
    ({"field": "nowhere.yaml"}, ("field: 'nowhere.yaml'", "not found")),
    ({"field": 3}, ("field: 3", "string")),
    ({"colour": "red"}, ("colour", "unknown")),
])
def test_a_hostile_field_scene_is_refused_in_one_line(tmp_path, capsys, change, expected):
    data = yaml.safe_load(field_scene(tmp_path).read_text())
    for key, value in change.items():
        if isinstance(value, dict):
            data[key] = {**data.get(key, {}), **value}
        else:
            data[key] = value
    path = tmp_path / "hostile.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(FieldError) as err:
        load_field_scene(path)
    assert "\n" not in str(err.value) and all(text in str(err.value) for text in expected), str(err.value)
    field_refused(capsys, expected, "plan", path, "--out", tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_the_scene_s_options_reach_the_plan_and_a_flag_wins(tmp_path, capsys):
    scene = field_scene(tmp_path, angle_deg=90, route="skip")
    code, out, err = field_command(capsys, "plan", scene, "--out", tmp_path / "p1")
    assert code == 0, err
    assert "at 90.0 deg" in out
    code, out, err = field_command(capsys, "plan", scene, "--angle", 0, "--out", tmp_path / "p2")
    assert code == 0, err
    assert "at 0.0 deg" in out


@pytest.fixture(scope="module")
def field_sweep(tmp_path_factory):
    folder = tmp_path_factory.mktemp("field_sweep")
    scene = field_scene(folder)
    spec_path = folder / "spec.yaml"
    spec_path.write_text(yaml.safe_dump({
        "name": "field_small", "train": str(TRAIN),
        "scenes": [str(scene), str(CONFIG / "scenes" / "straight_pass.yaml")],
        "sample": {"method": "grid"},
        "vary": [{"path": "carts[1].length", "values": [4.0, 6.0]},
                 {"path": "scene.plan.angle_deg", "values": [0, 90]}]}))
    spec = sweep_spec.load(spec_path)
    out = folder / "results"
    engine.run_sweep(spec, out, serial=True, quiet=True)
    return spec, out


def test_a_field_scene_s_rows_are_the_field_worked_directly(field_sweep):
    spec, out = field_sweep
    df = results.load_results(out)
    rows = df[df["scene"] == "small_work"]
    assert len(rows) == 4 and (rows["verdict"] == "ok").sum() >= 3
    for _, row in rows.iterrows():
        train = load_train(TRAIN)
        carts = list(train.carts)
        carts[1] = dataclasses.replace(carts[1], length=float(row["carts[1].length"]))
        train = dataclasses.replace(train, carts=tuple(carts))
        scene = load_field_scene(Path(spec.scenes[0][2]))
        options = dataclasses.replace(scene.options(train), angle=math.radians(row["scene.plan.angle_deg"]))
        if row["verdict"] == "refused":  # a train whose turns need more headland than the field has
            with pytest.raises(InputError) as refused:
                work_field(scene.field, train, options, Settings(**scene.drive))
            assert str(refused.value) == row["reason"]
            continue
        direct = work_field(scene.field, train, options, Settings(**scene.drive)).result.values
        for name, value in direct.items():
            assert (math.isnan(value) and math.isnan(row[name])) or value == row[name], name
    # the plan's angle is a field of the field scene only: the straight pass ran as it is, so its
    # rows of one train length are the same whatever the angle
    straight = df[df["scene"] == "straight_pass"]
    for length in (4.0, 6.0):
        same = straight[straight["carts[1].length"] == length]
        assert len(same) == 2 and same["energy_kWh"].nunique() == 1
    ok = rows["verdict"] == "ok"
    assert np.isnan(straight["total_time_h"]).all() and np.isfinite(rows["total_time_h"][ok]).all()


def test_the_report_compares_a_field_by_time_fuel_and_skipped_area(field_sweep, tmp_path):
    _, out = field_sweep
    md = report.make_report(out, out=tmp_path / "report")[-1].read_text()
    section = md.split("## Scene small_work")[1].split("## Scene")[0]
    objectives = results.default_objectives(results.load_results(out).query("scene == 'small_work'"))
    assert objectives[0] == "total_time_h" and set(objectives) <= set(results.FIELD_OBJECTIVES)
    assert "### The best 10 schemes by total_time_h" in section
    for metric in objectives:
        assert f"{metric} (minimized)" in section
