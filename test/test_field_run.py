"""``mta field run`` and ``mta field report``: a field planned, worked and measured from the command
line, its files read back and held to each other and to the plan (the route driven is the plan's,
the areas add up), a plan read from ``mta field plan``'s folder, the pictures drawn; bad input
refused in one line (exit 2) with nothing written, and no output overwriting an input."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import shapely

from mta_sim_ros.cli import main
from mta_sim_ros.field.boundary import load_field
from mta_sim_ros.field.route_io import read_route

from fieldcli import field_command, field_refused

FIELD = """name: small
boundary: [[0, 0], [240, 0], [240, 150], [0, 150]]
headlands: 1
entry: [0, 0]
"""


def mta(capsys, *args) -> tuple[int, str, str]:
    return field_command(capsys, *args)


def refused(capsys, expected: tuple, *args) -> str:
    return field_refused(capsys, expected, *args)


@pytest.fixture(scope="module")
def field_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("field") / "small.yaml"
    path.write_text(FIELD)
    return path


@pytest.fixture(scope="module")
def worked(field_file, tmp_path_factory):
    """The small field planned (mta field plan), then worked from that plan (mta field run --plan)."""
    plans = tmp_path_factory.mktemp("plan")
    out = tmp_path_factory.mktemp("run")
    assert main(["field", "plan", str(field_file), "--out", str(plans)]) == 0
    assert main(["field", "run", str(field_file), "--plan", str(plans), "--out", str(out)]) == 0
    return plans, out


def test_a_run_writes_its_trace_coverage_and_figures(worked, field_file):
    plans, out = worked
    assert sorted(p.name for p in out.iterdir()) == ["coverage.json", "metrics.json", "metrics.md", "trace.npz"]
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["verdict"] == "ok" and metrics["reason"] == ""
    figures = metrics["figures"]
    wkt = {k: shapely.from_wkt(v) for k, v in json.loads((out / "coverage.json").read_text())["wkt"].items()}
    field = load_field(field_file)
    assert figures["field_area_ha"] == pytest.approx(240 * 150 / 1e4, rel=1e-12)
    assert wkt["field"].equals(field.polygon)
    # the areas add up: target = its worked part + skipped, and the causes are the skip
    target_worked = wkt["target"].intersection(wkt["worked"]).area
    assert target_worked + wkt["skipped"].area == pytest.approx(wkt["target"].area, rel=1e-9)
    causes = sum(wkt[f"skipped_{c}"].area for c in ("boundary", "turns", "tracking"))
    assert causes == pytest.approx(wkt["skipped"].area, rel=1e-9)
    assert figures["worked_area_ha"] == pytest.approx(wkt["worked"].area / 1e4, rel=1e-12)
    with np.load(out / "trace.npz") as npz:
        t, axle, lowered = npz["t"], npz["axle"], npz["lowered"]
        route_xy = npz["route_xy"]
        assert list(npz["carts"]) == ["tractor", "air_cart", "seeder"]
    assert axle.shape == (t.size, 3, 2) and lowered.shape == t.shape
    assert np.allclose(np.diff(t), float(metrics["controller"]["settings"]["tick"]))
    assert figures["total_time_h"] * 3600 == pytest.approx(t[-1], rel=1e-12)
    planned = read_route(plans / "plan.mcap", field).route
    np.testing.assert_array_equal(route_xy, planned.xy)  # the route driven is the plan's
    text = (out / "metrics.md").read_text()
    assert "| worked, ha |" in text and "Verdict: ok" in text and "Where the time went" in text


def test_the_report_draws_the_run(worked, capsys, tmp_path):
    _, out = worked
    code, printed, err = mta(capsys, "report", out, "--out", tmp_path)
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["field.png", "report.md", "tracking.png"]
    for name in ("field.png", "tracking.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    report = (tmp_path / "report.md").read_text()
    assert "| skipped by tracking error, ha |" in report and "(field.png)" in report and "(tracking.png)" in report


def test_a_folder_that_is_not_a_run_is_refused(capsys, tmp_path):
    refused(capsys, ("run:", "a folder of mta field run", "trace.npz"), "report", tmp_path)
    (tmp_path / "trace.npz").write_bytes(b"not a zip")
    for name in ("coverage.json", "metrics.json"):
        (tmp_path / name).write_text("{}")
    refused(capsys, ("run:", "a readable field run"), "report", tmp_path)


def test_bad_input_is_refused_in_one_line_with_nothing_written(capsys, tmp_path, field_file):
    out = tmp_path / "out"
    refused(capsys, ("file", "not found"), "run", tmp_path / "missing.yaml", "--out", out)
    refused(capsys, ("--turn-speed", "in (0, 20] m/s"), "run", field_file, "--turn-speed", "0", "--out", out)
    refused(capsys, ("--plan", "an existing plan folder"), "run", field_file, "--plan", tmp_path / "nope",
            "--out", out)
    refused(capsys, ("--plan", "a plan folder holding plan.mcap"), "run", field_file, "--plan", tmp_path,
            "--out", out)
    no_implement = tmp_path / "bare.yaml"
    text = open("config/trains/default.yaml").read()
    no_implement.write_text(text[:text.index("implement:")] + text[text.index("steering_actuator:"):])
    refused(capsys, ("implement", "(missing)"), "run", field_file, "--train", no_implement, "--out", out)
    assert not out.exists()


def test_no_output_overwrites_an_input(capsys, tmp_path):
    """A GeoJSON field file named as one of the run's outputs, in the output folder: refused."""
    field = tmp_path / "metrics.json"
    shutil.copy("config/fields/kuban.geojson", field)
    before = field.read_bytes()
    refused(capsys, ("--out", "is not the input"), "run", field, "--out", tmp_path)
    assert field.read_bytes() == before


def test_a_foreign_plan_of_x_y_is_driven_and_its_straights_worked(field_file, tmp_path, capsys):
    """A plan as Fields2Cover or opennav_coverage exports it, a CSV of x, y only: two passes 30 m
    apart joined by a half circle. Its straights are taken as swaths (route_io: straight runs of 10 m
    and more) and worked; the worked ground is about the two strips, each 12 m wide along its
    straight: 2 x 12 m x 160 m (the implement lowered from the first straight's start, lifted on
    the half circle; what it works inside the field)."""
    t = np.linspace(0.0, np.pi, 60)
    xs = np.r_[np.linspace(40.0, 200.0, 321), 200.0 + 15.0 * np.sin(t[1:-1]), np.linspace(200.0, 40.0, 321)]
    ys = np.r_[np.full(321, 45.0), 60.0 - 15.0 * np.cos(t[1:-1]), np.full(321, 75.0)]
    plan = tmp_path / "foreign.csv"
    plan.write_text("x,y\n" + "\n".join(f"{x:.4f},{y:.4f}" for x, y in zip(xs, ys)) + "\n")
    code, out, err = mta(capsys, "run", field_file, "--plan", plan, "--out", tmp_path / "run")
    assert code == 0, err
    figures = json.loads((tmp_path / "run" / "metrics.json").read_text())["figures"]
    assert figures["worked_area_ha"] == pytest.approx(2 * 12.0 * 160.0 / 1e4, rel=0.03)
    assert figures["double_worked_ha"] == pytest.approx(0.0, abs=1e-3)


def test_a_field_run_states_its_error_within_its_bounds(field_file):
    """The estimate (a companion at half rk4's step) at or above the run's true error and at most 10
    times it: the true error against the same plan driven at an eighth of the step (whose own error
    is 4096 times smaller, rk4)."""
    import dataclasses

    from mta_sim_ros.controllers.implement.design import Settings
    from mta_sim_ros.controllers.implement.drive import run_field
    from mta_sim_ros.controllers.implement.work import work_field
    from mta_sim_ros.physics.loader import load_train
    from mta_sim_ros.run.accuracy import points_of

    train = load_train(Path(__file__).resolve().parents[1] / "config" / "trains" / "default.yaml")
    work = work_field(load_field(field_file), train)
    fine = run_field(work.plan, train, dataclasses.replace(Settings(), step=work.run.step / 8))

    def points(trace):
        return points_of(train, trace.axle[:, :, 0], trace.axle[:, :, 1], trace.heading)

    a, b = points(work.run.trace), points(fine.trace)
    assert a.shape == b.shape  # the same ticks: the same route driven to its end
    true = float(np.max(np.linalg.norm(a - b, axis=2)))
    assert true <= work.accuracy.error <= 10 * true, (work.accuracy.line(), true)
    assert work.accuracy.tolerance == 0.01 and work.accuracy.meets and "step halving" in work.accuracy.line()
    assert "within the tolerance 0.01 m" in work.accuracy.line()

