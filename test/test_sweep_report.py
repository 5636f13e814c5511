"""The report of a sweep (mta_sim_ros/sweep/report.py): Pareto fronts, Sobol indices, the report
files, and a scheme exported as a train file that runs to the sweep's numbers.

Two tiny sweeps run serially in a temporary folder, on copies of the default train and of two
shipped scenes: a grid (3 hitch offsets x 2 scene speeds, a constraint dropping one offset; 12
runs) and a Saltelli sample (N = 8, 2 factors, 1 scene: 48 runs) whose spec names its files by
relative paths, as config/sweeps/ does.
"""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mta_sim_ros.physics import loader
from mta_sim_ros.run import batch
from mta_sim_ros.sweep import engine, report, results
from mta_sim_ros.sweep import spec as sweep_spec
from mta_sim_ros.sweep.export import export
from mta_sim_ros.validate import InputError

pytestmark = pytest.mark.slow  # sweeps run for its fixtures, figures drawn

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "config"

# Ishigami's function, a = 7, b = 0.1, on [-pi, pi]^3: the known indices (Saltelli et al., Global
# sensitivity analysis: the primer, 2008, section 4.9).
ISHIGAMI_S1 = (0.3139, 0.4424, 0.0)
ISHIGAMI_ST = (0.5576, 0.4424, 0.2437)


def _layout(root: Path) -> Path:
    """root/trains/default.yaml and root/scenes/{straight_pass,headland_turn}.yaml, copies of the
    shipped files (the scenes name ../trains/default.yaml, the copy)."""
    (root / "trains").mkdir(parents=True)
    (root / "scenes").mkdir()
    (root / "sweeps").mkdir()
    shutil.copy(CONFIG / "trains" / "default.yaml", root / "trains" / "default.yaml")
    for name in ("straight_pass", "headland_turn"):
        shutil.copy(CONFIG / "scenes" / f"{name}.yaml", root / "scenes" / f"{name}.yaml")
    return root


@pytest.fixture(scope="module")
def grid(tmp_path_factory):
    """(spec path, results folder) of the grid sweep; absolute paths in the spec. total_length is
    14 m + a_1 + a_2 = 15.5 m + a_1, so a_1 = 1.5 (17 m) breaks max 16.75 and is dropped."""
    root = _layout(tmp_path_factory.mktemp("grid"))
    path = root / "sweeps" / "grid.yaml"
    path.write_text(f"""name: grid
train: {root / 'trains' / 'default.yaml'}
scenes: [{root / 'scenes' / 'straight_pass.yaml'}, {root / 'scenes' / 'headland_turn.yaml'}]
sample: {{method: grid}}
vary:
  - path: carts[0].hitch_offset
    values: [0.5, 1.0, 1.5]
  - path: scene.speed
    values: [2.5, 3.0]
constraints:
  - {{quantity: total_length, max: 16.75}}
batch: 4
""")
    folder = root / "results"
    engine.run_sweep(sweep_spec.load(path), folder, serial=True, quiet=True)
    return path, folder


@pytest.fixture(scope="module")
def saltelli(tmp_path_factory):
    """(spec path, results folder) of the Saltelli sweep: 8 x (2 x 2 + 2) = 48 schemes, one scene;
    the spec names its files relative to its folder."""
    root = _layout(tmp_path_factory.mktemp("saltelli"))
    path = root / "sweeps" / "saltelli.yaml"
    path.write_text("""name: saltelli
train: ../trains/default.yaml
scenes: [../scenes/straight_pass.yaml]
sample: {method: saltelli, count: 8, seed: 3}
vary:
  - path: carts[0].hitch_offset
    low: 0.5
    high: 1.5
  - path: carts[2].length
    low: 5.0
    high: 7.0
batch: 16
""")
    folder = root / "results"
    engine.run_sweep(sweep_spec.load(path), folder, serial=True, quiet=True)
    return path, folder


# --------------------------------------------------------------------------- Pareto front


def _brute_front(df, x, y, minimize) -> set:
    """The index of the rows no other dominates (O(n^2)), among the ok rows with x, y finite."""
    a = df[x].to_numpy(dtype=float) * (1 if minimize[0] else -1)
    b = df[y].to_numpy(dtype=float) * (1 if minimize[1] else -1)
    candidate = (df["verdict"] == "ok").to_numpy() & np.isfinite(a) & np.isfinite(b)
    keep = set()
    for i in np.flatnonzero(candidate):
        dominated = any(a[j] <= a[i] and b[j] <= b[i] and (a[j] < a[i] or b[j] < b[i])
                        for j in np.flatnonzero(candidate))
        if not dominated:
            keep.add(df.index[i])
    return keep


def _random_results(rng, n: int, levels: int | None) -> pd.DataFrame:
    """n rows shaped as a sweep's: x and y on a few levels (ties, equal rows) or continuous,
    some NaN and infinite, some not ok."""
    def column():
        v = rng.integers(0, levels, n).astype(float) if levels else rng.normal(size=n)
        v[rng.random(n) < 0.1] = math.nan
        v[rng.random(n) < 0.05] = rng.choice([math.inf, -math.inf])
        return v

    verdict = rng.choice(["ok", "ok", "ok", "stopped", "dropped", "refused"], n)
    return pd.DataFrame({"run": np.arange(n), "scheme": np.arange(n), "scene": "s", "a": rng.random(n),
                         "train_hash": "", "verdict": verdict, "reason": "", "x_m": column(), "y_m": column()},
                        index=rng.permutation(n) + 1000)


def test_pareto_front_is_the_brute_force_front():
    rng = np.random.default_rng(20261201)
    for trial in range(400):
        df = _random_results(rng, int(rng.integers(0, 40)), [3, 6, None][trial % 3])
        minimize = (bool(rng.integers(2)), bool(rng.integers(2)))
        front = results.pareto_front(df, "x_m", "y_m", minimize)
        assert set(front.index) == _brute_front(df, "x_m", "y_m", minimize), (trial, minimize)
        assert len(set(front.index)) == len(front)
        signed = front["x_m"].to_numpy() * (1 if minimize[0] else -1)
        assert np.all(np.diff(signed) >= 0)  # best x first
    df = _random_results(rng, 3000, None)
    assert set(results.pareto_front(df, "x_m", "y_m").index) == _brute_front(df, "x_m", "y_m", (True, True))


def test_pareto_front_keeps_rows_equal_in_both():
    df = pd.DataFrame({"run": [0, 1, 2, 3], "scheme": [0, 1, 2, 3], "scene": "s", "train_hash": "",
                       "verdict": "ok", "reason": "", "x_m": [1.0, 1.0, 2.0, 1.0], "y_m": [5.0, 5.0, 1.0, 6.0]})
    front = results.pareto_front(df, "x_m", "y_m")
    assert front["run"].tolist() == [0, 1, 2]  # 0 and 1 equal: neither dominates; 3 is dominated by both
    assert results.pareto_front(df.iloc[:0], "x_m", "y_m").empty


# --------------------------------------------------------------------------- the report


def _section(text: str, heading: str) -> str:
    """The lines of ``text`` from ``heading`` to the next heading of the same or a higher level."""
    level = heading.split(" ")[0]
    start = text.index(heading + "\n")
    rest = text[start + len(heading) + 1:]
    ends = [i for i in (rest.find("\n" + "#" * n + " ") for n in range(1, len(level) + 1)) if i >= 0]
    return rest[:min(ends)] if ends else rest


def test_make_report_writes_the_figures_and_the_counts(grid, tmp_path):
    _, folder = grid
    paths = report.make_report(folder)
    out = folder / "report"
    assert [p.name for p in paths] == ["pareto_straight_pass.png", "scatter_straight_pass.png",
                                       "pareto_headland_turn.png", "scatter_headland_turn.png", "report.md"]
    assert all(p.parent == out for p in paths)
    for p in paths[:-1]:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 5000
    md = paths[-1].read_text()
    assert "12 runs, 6 schemes x 2 scenes" in md
    assert "| ok | 8 |" in md and "| dropped | 4 |" in md and "| stopped | 0 |" in md and "| refused | 0 |" in md
    assert "| dropped | total_length 17 > max 16.75 | 4 |" in md
    # Each scene's own objectives: the headland turn's are a manoeuvre's first three that vary.
    df = results.load_results(folder)
    turn = df[df["scene"] == "headland_turn"]
    straight_rows = df[df["scene"] == "straight_pass"]
    assert results.default_objectives(turn)[:2] == ["energy_per_ha_kWh", "headland_width_m"]
    assert "Objectives: energy_per_ha_kWh (minimized), headland_width_m (minimized)" in _section(
        md, "## Scene headland_turn")
    # The straight pass never steers: its headland width is NaN in every run, so it is not one of
    # its objectives, and its hitch angles stay 0 in every run: not drawn as a distribution.
    straight = _section(md, "## Scene straight_pass")
    objectives = results.default_objectives(straight_rows)
    assert "headland_width_m" not in objectives and len(objectives) >= 2
    assert all(results.varying(straight_rows, m) for m in objectives)
    assert f"Objectives: {objectives[0]} (minimized)" in straight
    assert not results.varying(straight_rows, "max_hitch_angle_deg")
    assert "Not drawn as distributions" in straight and "max_hitch_angle_deg" in straight.split("Not drawn")[1]
    assert _section(straight, f"### The best 10 schemes by {objectives[0]}").count("\n| ") == 5  # head + 4 runs
    # Asked for, a metric a scene lacks is said there with what it has, the scene's own standing in.
    asked = report.make_report(folder, x="energy_per_ha_kWh", y="headland_width_m", out=tmp_path / "asked")[-1]
    straight = _section(asked.read_text(), "## Scene straight_pass")
    assert "headland_width_m is not defined in this scene (no ok run has it finite); defined here: " in straight
    assert "energy_per_ha_kWh" in straight.split("defined here: ")[1].splitlines()[0]
    front = results.pareto_front(turn, "energy_per_ha_kWh", "headland_width_m")
    assert len(front) >= 1
    table = _section(_section(md, "## Scene headland_turn"),
                     "### Pareto front of energy_per_ha_kWh and headland_width_m")
    rows = [line for line in table.splitlines() if line.startswith("| ") and not line.startswith("| carts")]
    assert [int(r.split("|")[-2]) for r in rows] == front["run"].tolist()
    assert "Sobol" not in md  # a grid
    # Every ok row states its run's accuracy, within the scenes' tolerance, and the report says the largest.
    ok = turn[turn["verdict"] == "ok"]["position_error_m"]
    assert ((ok > 0) & (ok <= 1e-6)).all(), ok.tolist()
    assert f"is at most {report._number(float(ok.max()))} m" in _section(md, "## Scene headland_turn")
    # One scene, another folder, other metrics (the margin: maximized).
    paths = report.make_report(folder, x="energy_kWh", y="min_jackknife_margin_deg", scene="headland_turn", best=2,
                               out=tmp_path / "r")
    assert [p.name for p in paths] == ["pareto_headland_turn.png", "scatter_headland_turn.png", "report.md"]
    md = paths[-1].read_text()
    assert "min_jackknife_margin_deg (maximized)" in md and "## Scene straight_pass" not in md
    assert _section(md, "### The best 2 schemes by energy_kWh").count("\n| ") == 3


def test_bad_names_and_folders_are_one_line_faults(grid, tmp_path):
    _, folder = grid
    with pytest.raises(InputError, match=r"^--x: 'energy_per_ha_kwh' must be a metric .*"
                                         r"did you mean energy_per_ha_kWh\?"):
        report.make_report(folder, x="energy_per_ha_kwh", out=tmp_path / "r")
    with pytest.raises(InputError, match=r"^--y: 'headland_width' .*did you mean headland_width_m\?"):
        report.make_report(folder, y="headland_width", out=tmp_path / "r")
    with pytest.raises(InputError, match=r"^--scene: 'headland' must be a scene of the results.*headland_turn"):
        report.make_report(folder, scene="headland", out=tmp_path / "r")
    with pytest.raises(InputError, match=r"^--x: 'carts\[0\].hitch_offset' must be a metric"):
        results.pareto_front(results.load_results(folder), "carts[0].hitch_offset", "energy_kWh")
    # A metric no ok run of any scene has finite is refused, naming those that are.
    df = results.load_results(folder)
    df["headland_width_m"] = float("nan")
    (tmp_path / "nan").mkdir()
    df.to_parquet(tmp_path / "nan" / "results.parquet")
    with pytest.raises(InputError, match=r"^--y: 'headland_width_m' must be a metric some ok run has finite: one of "
                                         r".*energy_per_ha_kWh"):
        report.make_report(tmp_path / "nan", x="energy_kWh", y="headland_width_m", out=tmp_path / "r")
    missing = tmp_path / "nowhere"
    with pytest.raises(InputError, match=f"^folder: '{missing}' must be a sweep's folder"):
        results.load_results(missing)
    with pytest.raises(InputError, match=f"not found: {tmp_path / 'results.parquet'}"):
        results.load_results(tmp_path)
    (tmp_path / "results.parquet").write_bytes(b"not parquet")
    with pytest.raises(InputError, match=f"^results: '{tmp_path / 'results.parquet'}' must be a readable Parquet"):
        results.load_results(tmp_path)
    with pytest.raises(InputError) as caught:
        results.load_results(tmp_path)
    assert "\n" not in str(caught.value)


# --------------------------------------------------------------------------- Sobol indices


def _ishigami_results(count: int) -> tuple[results.Design, pd.DataFrame]:
    """Results shaped as a Saltelli sweep's of Ishigami's function: SALib's sample on the unit cube
    (as spec.saltelli_unit draws it), mapped to [-pi, pi]."""
    from SALib.sample import sobol as sobol_sample

    design = results.Design("saltelli", count, ("x1", "x2", "x3"))
    u = sobol_sample.sample(design.problem(), count, calc_second_order=True, seed=1)
    x = -math.pi + 2 * math.pi * u
    y = np.sin(x[:, 0]) + 7 * np.sin(x[:, 1]) ** 2 + 0.1 * x[:, 2] ** 4 * np.sin(x[:, 0])
    n = len(y)
    df = pd.DataFrame({"run": np.arange(n), "scheme": np.arange(n), "scene": "s", "x1": u[:, 0], "x2": u[:, 1],
                       "x3": u[:, 2], "train_hash": "", "verdict": "ok", "reason": "", "ishigami": y})
    return design, df


def test_sobol_indices_of_ishigami():
    design, df = _ishigami_results(1024)
    indices = results.sobol_indices(design, df, "ishigami", "s")
    assert list(indices) == ["x1", "x2", "x3"]
    for name, s1, st in zip(indices, ISHIGAMI_S1, ISHIGAMI_ST):
        assert indices[name]["S1"] == pytest.approx(s1, abs=0.03), name
        assert indices[name]["ST"] == pytest.approx(st, abs=0.03), name
        assert 0 < indices[name]["S1_conf"] < 0.1 and 0 < indices[name]["ST_conf"] < 0.1
    assert results.sobol_indices(design, df, "ishigami", "s") == indices  # the bootstrap is seeded
    # Every run is needed.
    lacking = df.copy()
    lacking.loc[5, "ishigami"] = math.nan
    lacking.loc[7, "verdict"] = "stopped"
    with pytest.raises(InputError, match=r"^ishigami: missing in 2 of 8192 runs of scene 's' \(1 not ok, 1 not "
                                         r"finite\) must be given by every run"):
        results.sobol_indices(design, lacking, "ishigami", "s")
    with pytest.raises(InputError, match=r"1024 x 8 = 8192 runs.*it has 8191"):
        results.sobol_indices(design, df.iloc[1:], "ishigami", "s")
    with pytest.raises(InputError, match=r"^sample.method: 'grid' must be saltelli"):
        results.sobol_indices(results.Design("grid", 0, design.factors), df, "ishigami", "s")


def test_saltelli_sweep_end_to_end(saltelli):
    path, folder = saltelli
    spec = sweep_spec.load(path)
    df = results.load_results(folder)
    assert len(df) == 48 and (df["verdict"] == "ok").all()
    design = results.stored_design(folder, df)
    assert design == results.Design("saltelli", 8, ("carts[0].hitch_offset", "carts[2].length"))
    assert design.problem() == sweep_spec.sobol_problem(spec)
    # metrics that vary on the straight pass (its energy per hectare is the same for every scheme
    # up to the start's transient, its largest hitch angle the start's 5 deg)
    for metric in ("max_offtracking_m", "swept_width_m"):
        indices = results.sobol_indices(spec, df, metric, "straight_pass")
        assert list(indices) == ["carts[0].hitch_offset", "carts[2].length"]
        assert all(math.isfinite(v) for factor in indices.values() for v in factor.values())
        assert results.sobol_indices(design, df, metric, "straight_pass") == indices
    paths = report.make_report(folder, x="max_offtracking_m", y="swept_width_m")
    md = paths[-1].read_text()
    sobol = _section(md, "### Sobol indices")
    assert sobol.count("| max_offtracking_m | ") == 2 and sobol.count("| swept_width_m | ") == 2
    with pytest.raises(InputError, match="headland_width_m: missing in 48 of 48 runs"):  # never steers
        results.sobol_indices(design, df, "headland_width_m", "straight_pass")
    assert "sampling saltelli (N = 8)" in md


# --------------------------------------------------------------------------- export


def _same(a: float, b: float) -> bool:
    """Equal bit for bit, NaN equal to NaN."""
    return (math.isnan(a) and math.isnan(b)) or float(a).hex() == float(b).hex()


def _assert_row_metrics(result: batch.RunResult, row) -> None:
    """The run alone gives the sweep's row: a sweep runs across SIMD lanes with vmath's sin, cos,
    atan2, tanh and exp (run/lanes_batch.py), within 1e-10 relative of the C library's run alone,
    the position error (a difference of two runs) within 1e-12 m."""
    assert result.verdict == row["verdict"] and result.level == row["level"]
    for name, value in result.metrics.items():
        slack = 1e-12 if name == "position_error_m" else 0.0
        assert _same(value, row[name]) or abs(value - row[name]) <= 1e-10 * abs(value) + slack, (name, value, row[name])


def test_export_runs_as_the_sweep_ran_it(grid, tmp_path):
    spec_path, folder = grid
    df = results.load_results(folder)
    row = df[(df["scene"] == "headland_turn") & (df["verdict"] == "ok")].iloc[-1]
    out = tmp_path / "best" / "scheme.yaml"
    paths = export(folder, int(row["run"]), out)  # the spec's paths are absolute: its kept text will do
    assert paths == [out, out.with_name("scheme.straight_pass.yaml"), out.with_name("scheme.headland_turn.yaml")]
    header = out.read_text().splitlines()[:4]
    assert f"run {int(row['run'])}" in header[0] and "sweep grid" in header[0]
    assert header[2] == (f"# factors: carts[0].hitch_offset = {float(row['carts[0].hitch_offset'])!r}, "
                         f"scene.speed = {float(row['scene.speed'])!r}")
    assert header[3] == f"# train_hash: {row['train_hash']}"
    train = loader.load_train(out)
    assert engine.train_hash(train) == row["train_hash"]
    assert train.carts[0].hitch_offset == row["carts[0].hitch_offset"]
    for scene_file in paths[1:]:
        scene = loader.load_scene(scene_file)  # names the exported train; fidelity: the sweep's (dynamic)
        assert scene.train == loader.load_train(out)
        assert scene.speed is None or scene.speed.value[0] == row["scene.speed"]
        match = df[(df["scheme"] == row["scheme"]) & (df["scene"] == scene.name)].iloc[0]
        _assert_row_metrics(batch.run_metrics(scene), match)
    # The same with the spec given (named in the header).
    again = export(folder, int(row["run"]), tmp_path / "again.yaml", spec_path=spec_path)[0].read_text()
    assert again.splitlines()[1].startswith(f"# spec: {spec_path}; ")
    assert again.splitlines()[4:] == out.read_text().splitlines()[4:]


def test_export_without_scene_factors(saltelli, tmp_path):
    spec_path, folder = saltelli
    df = results.load_results(folder)
    row = df.iloc[17]
    out = tmp_path / "scheme17.yaml"
    assert export(folder, 17, out) == [out]  # the spec where the sweep read it (spec_path.txt)
    moved = spec_path.with_name("moved.yaml")
    spec_path.rename(moved)
    try:
        with pytest.raises(InputError, match=r"^--spec: \(not given\) must be the sweep's spec file.*relative paths"):
            export(folder, 17, out)
    finally:
        moved.rename(spec_path)
    assert export(folder, 17, out, spec_path=spec_path) == [out]
    scene_path = spec_path.parent.parent / "scenes" / "straight_pass.yaml"
    scene = loader.scene_from_data(loader.read_yaml_mapping(scene_path), str(scene_path), loader.load_train(out))
    _assert_row_metrics(batch.run_metrics(scene, fidelity="dynamic"), row)


def test_export_refuses_what_it_cannot_export(grid, tmp_path):
    spec_path, folder = grid
    df = results.load_results(folder)
    with pytest.raises(InputError, match=r"^--run: 999 must be a run index of the results \(0 to 11\)"):
        export(folder, 999, tmp_path / "x.yaml")
    with pytest.raises(InputError, match=r"^--run: 'a' must be a run index"):
        export(folder, "a", tmp_path / "x.yaml")
    dropped = int(df[df["verdict"] == "dropped"]["run"].iloc[0])
    with pytest.raises(InputError, match=rf"^--run: {dropped} must be a run whose scheme was run: it was dropped "
                                         r"\(total_length 17 > max 16.75\)"):
        export(folder, dropped, tmp_path / "x.yaml")
    changed = tmp_path / "changed.yaml"
    changed.write_text(spec_path.read_text().replace("batch: 4", "batch: 5"))
    with pytest.raises(InputError, match=r"^--spec: .* the spec changed since the sweep"):
        export(folder, 0, tmp_path / "x.yaml", spec_path=changed)
    assert not (tmp_path / "x.yaml").exists()
    # never over a file the spec reads: its base train, a scene, the spec itself (each left as it was)
    root = spec_path.parent.parent
    for own in (root / "trains" / "default.yaml", root / "scenes" / "headland_turn.yaml", spec_path):
        before = own.read_bytes()
        with pytest.raises(InputError, match=r"^--out: .* must be another file than the input"):
            export(folder, 0, own)
        assert own.read_bytes() == before
