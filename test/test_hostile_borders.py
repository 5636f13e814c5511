"""Borders a hostile tester broke (stop 42), each held here: no output is written over a file the
command reads (a run's height grid, a bag `mta analyze` reads); a bag whose chunk fails its CRC is
refused, not read as numbers; what `mta run` refuses, `mta check` refuses (the slip level on a
height grid); every number has a range (heights, rtol, a run of less than one tick); a named pipe
is refused, not waited on; `--frame-id` takes the node's rule. Each refusal is one line, exit 2
(1 for a bag that cannot be read, as documented)."""
from __future__ import annotations

import hashlib
import os

import numpy as np
import pytest
from hostile import CONFIG, assert_refused, damaged_bag, mta, short_scene

from mta_sim_ros import cli

TRAIN = CONFIG / "trains" / "default.yaml"


def grid_scene(folder, heights_file="h.csv", extra="") -> str:
    """A 2 s straight run on a flat 20 x 20 grid (8 m spacing) from the file ``heights_file``."""
    path = folder / "grid.yaml"
    path.write_text(f"train: {TRAIN}\nduration: 2\ninitial: {{speed: 3.0}}\nsteering: {{maneuver: straight}}\n"
                    f"speed: 3.0\nterrain: {{heights: {heights_file}, origin: [-50, -80], spacing: 8}}\n{extra}")
    return str(path)


def digest(path) -> str:
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


def one_line(capsys, *expected) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for text in expected:
        assert text in err, (text, err)
    return err


@pytest.mark.parametrize("flag", ["--bag", "--report"])
def test_a_run_never_writes_over_its_height_grid(tmp_path, flag, capsys):
    np.savetxt(tmp_path / "h.csv", np.zeros((20, 20)), delimiter=",")
    before = digest(tmp_path / "h.csv")
    target = {"--bag": ["--bag", str(tmp_path / "h.csv")],
              "--report": ["--bag", str(tmp_path / "r.mcap"), "--report", str(tmp_path / "h.csv")]}[flag]
    assert cli.main(["run", "--scene", grid_scene(tmp_path), *target, "--quiet"]) == 2
    one_line(capsys, f"{flag}: ", "must be another file than the input", "h.csv")
    assert digest(tmp_path / "h.csv") == before
    assert cli.main(["run", "--scene", grid_scene(tmp_path), "--bag", str(tmp_path / "r.mcap"), "--quiet"]) == 0
    assert digest(tmp_path / "h.csv") == before


def test_a_bag_named_like_the_report_is_not_taken_for_it(tmp_path, capsys):
    assert cli.main(["run", "--scene", str(short_scene(tmp_path)), "--bag", str(tmp_path / "x.md"), "--quiet"]) == 2
    one_line(capsys, "--bag: ", "x.md", "not ending in .md")
    assert not (tmp_path / "x.md").exists()


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bag")
    path = folder / "run.mcap"
    assert cli.main(["run", "--scene", str(short_scene(folder)), "--bag", str(path), "--quiet"]) == 0
    return path


@pytest.mark.parametrize("name", ["summary.json", "summary.md", "trajectory.png", "csv/odom.csv"])
def test_analyze_never_writes_over_a_bag_it_reads(bag, tmp_path, name, capsys):
    """A bag sitting where the report would write one of its files: refused before any is written."""
    target = tmp_path / "out" / name
    target.parent.mkdir(parents=True)
    target.write_bytes(bag.read_bytes())
    assert cli.main(["analyze", str(target), "-o", str(tmp_path / "out")]) == 2
    one_line(capsys, "--output: ", "must be another file than the input")
    assert target.read_bytes() == bag.read_bytes()
    assert sorted(p.name for p in (tmp_path / "out").rglob("*") if p.is_file()) == [target.name]


def test_a_bag_whose_chunk_fails_its_crc_is_refused_not_read(bag, tmp_path, capsys):
    """One bit of a pose flipped inside a chunk: the chunk's CRC no longer holds. Without the check
    the analysis read the changed number as the run's; now it is one line, exit 1, naming the tool
    that rebuilds what is intact. The intact copy is analysed (the check refuses only the damage)."""
    intact, damaged = damaged_bag(bag, tmp_path)
    assert cli.main(["analyze", str(intact), "-o", str(tmp_path / "a")]) == 0
    capsys.readouterr()
    assert cli.main(["analyze", str(damaged), "-o", str(tmp_path / "b")]) == 1
    one_line(capsys, "cannot read bag file", "CRC", f"mta recover {damaged} -o OUT.mcap")
    assert cli.main(["recover", str(damaged), "-o", str(tmp_path / "rebuilt.mcap")]) == 0


SCENE_FAULTS = [
    ("slip-on-a-grid", "fidelity: slip\n", "h.csv", ["fidelity: 'slip'", "kinematic or dynamic level on a height grid"]),
    ("heights-past-range", "", "big.npy", ["heights: 1e+308 at row 0, column 0", "within +-100000 m"]),
    ("under-one-tick", "", "h.csv", ["duration: 1e-300", "at least one tick"]),
    ("rtol-below-floor", "integrator: {method: RK45, rtol: 1.0e-300}\n", "h.csv", ["rtol: 1e-300", "in [1e-10, 1]"]),
    ("params-on-straight", "", "h.csv", ["a: 1 in steering.params", "must be removed: none is taken here"]),
]


@pytest.mark.parametrize("case,extra,heights,expected", SCENE_FAULTS, ids=[c[0] for c in SCENE_FAULTS])
def test_check_refuses_what_a_run_cannot_take(tmp_path, case, extra, heights, expected, capsys):
    np.savetxt(tmp_path / "h.csv", np.zeros((20, 20)), delimiter=",")
    np.save(tmp_path / "big.npy", np.full((20, 20), 1e308))
    path = grid_scene(tmp_path, heights, extra)
    text = open(path).read()
    if case == "under-one-tick":
        text = text.replace("duration: 2", "duration: 1e-300")
    if case == "params-on-straight":
        text = text.replace("{maneuver: straight}", "{maneuver: straight, params: {a: 1}}")
    open(path, "w").write(text)
    assert cli.main(["check", path]) == 2
    one_line(capsys, *expected)
    assert cli.main(["run", "--scene", path, "--bag", str(tmp_path / "r.mcap"), "--quiet"]) == 2
    one_line(capsys, *expected)


@pytest.mark.parametrize("command", ["check", "analyze"])
def test_a_named_pipe_is_refused_not_waited_on(tmp_path, command):
    fifo = tmp_path / ("pipe.yaml" if command == "check" else "pipe.mcap")
    os.mkfifo(fifo)
    done = mta(command, fifo, timeout=60)  # before: blocked until something wrote to the pipe
    assert_refused(done, "named pipe", code=2 if command == "check" else 1)


@pytest.mark.parametrize("frame", ["", "a b", "/map"])
def test_a_run_takes_the_nodes_rule_for_its_frame(tmp_path, frame, capsys):
    assert cli.main(["run", "--scene", str(short_scene(tmp_path)), "--bag", str(tmp_path / "r.mcap"),
                     "--frame-id", frame, "--quiet"]) == 2
    one_line(capsys, "--frame-id: ", "a frame name: 1 to 256 printable characters")
    assert not (tmp_path / "r.mcap").exists()


def test_check_takes_every_kind_of_file_the_commands_read(tmp_path, capsys):
    """Trains, scenes, fields (YAML, GeoJSON), field scenes and sweeps, each by its own reader: every
    shipped file is ok; a bad one of each kind is refused with that reader's own rule (before, a
    field or sweep was 'a train (with carts) or a scene (with train)')."""
    shipped = sorted(p for kind in ("trains", "scenes", "fields", "fieldwork", "sweeps")
                     for p in (CONFIG / kind).iterdir() if p.suffix in (".yaml", ".geojson"))
    assert cli.main(["check", *map(str, shipped)]) == 0
    assert capsys.readouterr().out.count("ok: ") == len(shipped)
    bad = {"field.yaml": ("name: f\nboundary: [[0, 0], [1, 0]]\n", "a ring of at least 3 distinct points"),
           "field.geojson": ('{"type": "Feature", "geometry": {"type": "Polygon", "coordinates": '
                             '[[[39.0, 45.0], [39.01, NaN], [39.0, 45.01], [39.0, 45.0]]]}}', "NaN"),
           "work.yaml": (f"field: {CONFIG / 'fields' / 'rectangle.yaml'}\nplan: {{angle_deg: .nan}}\n", "angle_deg"),
           "sweep.yaml": (f"name: s\ntrain: {TRAIN}\nscenes: [{CONFIG / 'scenes' / 'headland_turn.yaml'}]\n"
                          "vary:\n  - path: carts[9].length\n    values: [1, 2]\n", "carts[9]")}
    for name, (text, words) in bad.items():
        (tmp_path / name).write_text(text)
        assert cli.main(["check", str(tmp_path / name)]) == 2, name
        one_line(capsys, "error: ", words)


def test_a_scene_whose_duration_is_no_whole_number_of_ticks_is_noted(tmp_path, capsys):
    """5 s at 3.3 Hz runs 16 ticks, 4.848 s: check says so (it ran silently short)."""
    path = tmp_path / "s.yaml"
    path.write_text(f"train: {TRAIN}\nduration: 5\npublish_rate: 3.3\nsteering: {{maneuver: straight}}\n")
    assert cli.main(["check", str(path)]) == 0
    assert capsys.readouterr().out.splitlines()[1] == (
        f"note: {path}: duration: 5 s is not a whole number of ticks at 3.3 Hz: a run takes 16 ticks, 4.84848 s")


def test_a_train_that_is_a_folder_is_called_one(tmp_path, capsys):
    path = tmp_path / "s.yaml"
    path.write_text("train: .\nduration: 2\nsteering: {maneuver: straight}\n")
    assert cli.main(["check", str(path)]) == 2
    one_line(capsys, "train: '.'", "(a folder: ")


def test_a_sweep_choice_refused_is_named_by_its_value(tmp_path, capsys):
    """A choice's label in the results is its index; a refusal named it so ('= 1' for 'zigzag')."""
    path = tmp_path / "sweep.yaml"
    path.write_text(f"name: s\ntrain: {TRAIN}\nscenes: [{CONFIG / 'fieldwork' / 'rectangle.yaml'}]\n"
                    "vary:\n  - path: scene.plan.turn\n    choices: [u, zigzag]\n")
    assert cli.main(["check", str(path)]) == 2
    one_line(capsys, "vary[0] (scene.plan.turn = 'zigzag')", "turn: 'zigzag'", "one of auto, u, bulb, fishtail")
