"""The margins a run states (run/margins.py) where users read them: `mta run`'s report and the
node's /diagnostics (its session, driven by a set clock), against the closed forms of the hillside
unit straight along the contour of a side slope b: every no-slip axle's grip margin is
1 - tan(b) / mu (test_grip), the air cart's rollover margin 1 - 2 h tan(b) / t; past tan(b) = mu
the report and the diagnostics say that the no-slip model does not hold there."""
from __future__ import annotations

import math
import shutil

import pytest
from test_session import FakeClock, Log

from mta_sim_ros import cli
from mta_sim_ros.node.params import PARAMS
from mta_sim_ros.node.run_session import RunSession
from mta_sim_ros.node.status import OK, WARN

MU, T_AIR, H_AIR = 0.5, 2.8, 1.9  # the hillside unit's lateral_friction, air cart's track and height


def contour_scene(tmp_path, cross_percent: float, duration: float = 4.0, fidelity: str = "dynamic"):
    """The hillside unit straight along the contour of a side slope of ``cross_percent``."""
    shutil.copy("config/trains/hillside_unit.yaml", tmp_path / "hillside_unit.yaml")
    path = tmp_path / f"contour_{cross_percent:g}.yaml"
    path.write_text(f"""train: hillside_unit.yaml
duration: {duration}
initial: {{speed: 2.8}}
steering: {{maneuver: straight}}
speed: 2.8
terrain: {{grade_percent: 0, cross_slope_percent: {cross_percent}}}
integrator: {{method: rk4, step: 0.02}}
publish_rate: 50
fidelity: {fidelity}
""", encoding="utf-8")
    return path


def report_rows(tmp_path, scene) -> dict[str, str]:
    assert cli.main(["run", "--scene", str(scene), "--bag", str(tmp_path / "r.mcap"), "--quiet"]) == 0
    rows = [line.split("|") for line in (tmp_path / "r.md").read_text(encoding="utf-8").splitlines()
            if line.startswith("| ")]
    return {r[1].strip(): r[2].strip() for r in rows}


@pytest.mark.parametrize("cross", [30.0, 60.0])
def test_the_run_report_states_the_grip_and_tip_margins(tmp_path, cross):
    rows = report_rows(tmp_path, contour_scene(tmp_path, cross))
    b = cross / 100
    grip = rows["smallest grip margin"]
    assert grip.startswith(f"{1 - b / MU:.3f} (")
    assert ("the no-slip model does not hold: run fidelity slip" in grip) == (b > MU)
    assert rows["smallest static rollover margin"].startswith(f"{1 - 2 * H_AIR * b / T_AIR:.3f} (air_cart")
    assert float(rows["smallest tip margin of the tractor"].split()[0]) < 1


def test_the_default_train_s_report_states_no_margin_it_cannot_know(tmp_path):
    """No lateral_friction, no com_height on the default train: no tip or grip rows."""
    shutil.copytree("config/trains", tmp_path / "trains")
    (tmp_path / "scenes").mkdir()
    shutil.copy("config/scenes/straight_pass.yaml", tmp_path / "scenes" / "s.yaml")
    rows = report_rows(tmp_path, tmp_path / "scenes" / "s.yaml")
    assert "smallest grip margin" not in rows and "smallest tip margin of the tractor" not in rows


def session(tmp_path, scene) -> RunSession:
    cfg = {p.name: p.default for p in PARAMS}
    cfg.update(scene_file=str(scene), bag_dir=str(tmp_path / "bags"), publish_rate=50.0, watchdog_timeout=0.0,
               record=False)
    clock = FakeClock()
    return RunSession(cfg, clock=clock, publish=lambda _: None, log=Log(), namespace="/", background=False,
                      compute_clock=clock, cpu_clock=clock)


@pytest.mark.parametrize("cross, level", [(30.0, OK), (60.0, WARN)])
def test_the_node_s_diagnostics_state_the_margins_and_warn_past_the_grip(tmp_path, cross, level):
    s = session(tmp_path, contour_scene(tmp_path, cross, duration=60.0))
    for _ in range(10):
        s.tick()
    status = s.diagnostics()
    b = cross / 100
    assert status.values["grip_margin"] == pytest.approx(1 - b / MU, rel=1e-9)
    assert status.values["rollover_margin"] == pytest.approx(1 - 2 * H_AIR * b / T_AIR, rel=1e-12)
    assert 0 < status.values["tip_margin"] < 1
    assert status.level == level
    assert ("grip margin" in status.message and "fidelity slip" in status.message) == (level == WARN)


def test_at_the_slip_level_the_node_states_no_grip_margin(tmp_path):
    """The slip level's tyres give what their slip angles give: no constraint forces, no margin."""
    s = session(tmp_path, contour_scene(tmp_path, 60.0, duration=60.0, fidelity="slip"))
    s.tick()
    values = s.diagnostics().values
    assert math.isnan(values["grip_margin"]) and math.isnan(values["tip_margin"])
    assert values["rollover_margin"] < 1


def test_a_state_that_is_not_finite_has_margins_not_known_and_no_error(tmp_path):
    """What a halted run may hold: NaN in the state gives NaN margins (no exception in the
    node's diagnostics), and no warning about them."""
    import numpy as np

    from mta_sim_ros.physics.loader import load_scene
    from mta_sim_ros.run.margins import MarginGauge
    from mta_sim_ros.run.simulation import Simulation

    sim = Simulation(load_scene(contour_scene(tmp_path, 30.0)))
    y = np.full_like(sim.y, np.nan)
    m = MarginGauge(sim.model.train).at(sim.model, y, 0.0, 2.8)
    assert math.isnan(m.rollover) and math.isnan(m.tip) and math.isnan(m.grip) and m.problems() == []


def test_an_unloaded_axle_that_must_hold_is_stated_not_hidden():
    """A grip margin of -inf (an axle with no static load that must give a lateral force,
    loads.grip_margins) is the worst there is: the report states it and what it means."""
    from mta_sim_ros.run.margins import Margins
    from mta_sim_ros.run.summary import RunSummary

    summary = RunSummary(("tractor", "cart"))
    summary.add_margins(Margins(math.nan, "", 0.4, 0.2, "tractor's axle"))
    summary.add_margins(Margins(math.nan, "", math.nan, -math.inf, "cart's axle"))
    text = summary.markdown("run")
    assert "| smallest grip margin | -inf (cart's axle;" in text and "the no-slip model does not hold" in text
    assert "| smallest tip margin of the tractor | 0.400" in text
