"""Field borders a hostile tester broke (stop 42), each held here: a field given to full float
precision, with an obstacle, plans as its rounded twin does (two right-angle corners of a ring,
off by round-off, were merged at their edges' crossing kilometres away: a 1460 km route out of a
10 ha field, exit 0); a field's name never leads out of the output folder; a plan made for another
field is refused by `mta field run`; `mta field report` of a damaged run folder is one line, exit 2."""
from __future__ import annotations

import json

import numpy as np
import shapely
from fieldcli import field_command, field_refused
from hostile import CONFIG

from mta_sim_ros.field import headlands
from mta_sim_ros.field.clothoid import Curves

TRAIN = CONFIG / "trains" / "default.yaml"
#: a 315 x 333 m field with a 79 x 111 m obstacle, its corners as a projection gives them (float noise)
NOISY = {"name": "noisy",
         "boundary": [[0.12349898053798825, 0.0], [315.1103702840046, 0.12450405955314636],
                      [314.97040476911934, 333.38949624449015], [0.0, 333.26499218679965]],
         "holes": [[[78.82767901691841, 111.11797817796469], [78.78514047892531, 222.20630890596658],
                    [157.52911390649388, 222.2369485758245], [157.57302465569228, 111.1486178478226]]]}


def rounded(field: dict) -> dict:
    """The field with every coordinate to the millimetre."""
    def r(points):
        return [[round(x, 3), round(y, 3)] for x, y in points]
    return dict(field, name="rounded", boundary=r(field["boundary"]), holes=[r(h) for h in field["holes"]])


def plan_of(tmp_path, capsys, field: dict, name: str):
    path = tmp_path / f"{name}.json.yaml"
    path.write_text(json.dumps(field))  # YAML reads JSON
    code, out, err = field_command(capsys, "plan", path, "--train", TRAIN, "--out", tmp_path / name)
    assert code == 0, err
    route_line = next(line for line in out.splitlines() if line.startswith("route "))
    return float(route_line.split()[1]), tmp_path / name


def test_a_field_to_full_precision_plans_as_its_rounded_twin(tmp_path, capsys):
    noisy, _ = plan_of(tmp_path, capsys, NOISY, "noisy")
    exact, _ = plan_of(tmp_path, capsys, rounded(NOISY), "rounded")
    assert noisy == exact and noisy < 10.0  # km: 9.43 both; before, 1460.25 for the noisy one


def test_two_right_angles_off_by_round_off_are_not_merged_far_away():
    """A ring's U end: corners of +pi/2 each, an edge between them shorter than their fillets, the
    sum pi - 6e-6 (round-off). Merged at their edges' crossing, the corner lay ~3 km off; now the
    smaller is dropped as for an exact U, and every corner stays near the ring."""
    curves = Curves(radius=8.89, sharpness=0.007499)
    square = np.array([[0.0, 0.0], [200.0, 0.0], [200.0, 20.0], [0.0, 20.0012]])  # 20 m: narrower than 2 fillets
    pts, turns = headlands.corner_table(np.vstack([square, square[:1]]))
    assert -1e-5 < turns[1] + turns[2] - np.pi < -1e-6  # the two right angles at x = 200 add up to just under pi
    merged, _ = headlands.merged(pts, turns, curves, None)
    assert np.all(np.abs(merged) < 300.0), merged


def test_a_field_name_never_leads_out_of_the_output_folder(tmp_path, capsys):
    """A name that cannot name one folder is refused where it would (no --out): plans/<name> and
    runs/<name>; with --out the field plans ('Поле 12/3', as farm software names fields)."""
    for name in ("../../etc/x", "/tmp/abs", "..", "a\\b", "Поле 12/3"):
        path = tmp_path / "f.yaml"
        path.write_text(json.dumps({"name": name, "boundary": [[0, 0], [300, 0], [300, 300], [0, 300]]}))
        for command in ("plan", "run"):
            field_refused(capsys, ("--out: (not given)", f"the field's name {name!r} cannot name the default folder",
                                   "plans/<name>" if command == "plan" else "runs/<name>"), command, path,
                          "--train", TRAIN)
    code, out, err = field_command(capsys, "plan", path, "--train", TRAIN, "--out", tmp_path / "given")
    assert code == 0 and (tmp_path / "given" / "plan.csv").is_file(), err


def test_a_plan_of_another_field_is_refused(tmp_path, capsys):
    _, folder = plan_of(tmp_path, capsys, rounded(NOISY), "rounded")
    for plan in ("plan.csv", "plan.mcap"):
        field_refused(capsys, ("field: 'rounded (", "the field it is run on, rectangle"), "run",
                      CONFIG / "fields" / "rectangle.yaml", "--train", TRAIN, "--plan", folder / plan,
                      "--out", tmp_path / "run")
    assert not (tmp_path / "run").exists() or not any((tmp_path / "run").iterdir())


def run_folder(tmp_path, trace=None, metrics=None, polygon_rings=False):
    """A folder shaped as mta field run's, its files as given."""
    folder = tmp_path / "run"
    folder.mkdir(exist_ok=True)
    square = shapely.Polygon([(0, 0), (10, 0), (10, 10), (0, 10)]).wkt
    lines = shapely.MultiLineString([[(1, 1), (9, 1)], [(1, 9), (9, 9)]]).wkt
    (folder / "coverage.json").write_text(json.dumps({"wkt": {
        **{k: square for k in ("field", "worked", "skipped", "double", "outside")}, "swaths": lines,
        "headland_rings": square if polygon_rings else lines}}))
    figures = {"tracking_rms_m": 0.1, "tracking_p95_m": 0.2, "tracking_max_m": 0.3}
    (folder / "metrics.json").write_text(json.dumps(metrics if metrics is not None else {
        "field": "f", "train": "t", "verdict": "ok", "figures": figures}))
    if isinstance(trace, bytes):
        (folder / "trace.npz").write_bytes(trace)
    else:
        n = 5
        arrays = dict(t=np.arange(n), tracking_error=np.zeros(n), lowered=np.ones(n), axle=np.zeros((n, 1, 2)),
                      route_xy=np.zeros((3, 2)), carts=np.array(["tractor"]))
        arrays.update(trace or {})
        np.savez(folder / "trace.npz", **arrays)
    return folder


def test_a_damaged_run_folder_is_one_line(tmp_path, capsys):
    code, out, err = field_command(capsys, "report", run_folder(tmp_path), "--out", tmp_path / "ok")
    assert code == 0, err  # the forged folder is whole: the damage below is what is refused
    for trace, metrics, words in (
            (b"PK\x03\x04 cut short", None, "BadZipFile"),
            (None, {}, "no figures"),
            (None, [], "no figures"),
            (None, {"field": "f", "train": "t", "verdict": "ok", "figures": {}}, "missing metrics.json figures."),
            ({"t": np.arange(3)}, None, "inconsistent shapes"),
            (None, None, "coverage.json headland_rings holds a Polygon")):
        folder = run_folder(tmp_path, trace, metrics, polygon_rings="headland" in words)
        field_refused(capsys, ("run: ", "a readable field run", words), "report", folder, "--out", tmp_path / "r")


def test_a_turn_kind_asked_but_not_made_is_said(tmp_path, capsys):
    """--turn fishtail on the rectangle: its swaths are all a U apart or more, so every turn is a U;
    the plan says the kind asked is made only between swaths closer than the narrowest U."""
    code, out, err = field_command(capsys, "plan", CONFIG / "fields" / "rectangle.yaml", "--train", TRAIN,
                                   "--turn", "fishtail", "--out", tmp_path / "p")
    assert code == 0, err
    assert "turns 14 u" in out
    assert "turn fishtail: made only between swaths closer than the narrowest U, 19.8 m (a U wherever one fits: " \
           "14 of them)" in out


def test_a_train_that_cannot_turn_is_told_why(tmp_path, capsys):
    """A steering lock of 1 deg was blamed on max_hitch_angle (80 deg, fine); an implement 1000 m
    aside on the number of headland rings. Each line now names the cause."""
    default = TRAIN.read_text()
    for change, words in ((("max_angle_deg: 40", "max_angle_deg: 1.0"), ("max_angle_deg: 1 in actuator",
                                                                           "a steering lock that leaves a planned turn room")),
                          (("  offset: 1.5 ", "  offset: 1000 "), ("corners turns of radius 1000 m",
                                                                     "implement.offset"))):
        assert change[0] in default, change
        train = tmp_path / "train.yaml"
        train.write_text(default.replace(change[0], change[1], 1))
        field_refused(capsys, words, "plan", CONFIG / "fields" / "rectangle.yaml", "--train", train,
                      "--out", tmp_path / "p")
