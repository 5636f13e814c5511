"""Sweeps (mta sweep): the same rows serially, on the embedded LocalCluster and on an external Dask
cluster of real processes on loopback; nothing finished lost to a killed worker or a killed sweep;
bad specs named in one line."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from mta_sim_ros import cli
from mta_sim_ros.config import resolve_config_path
from mta_sim_ros.sweep import engine, spec as sweep_spec

TRAIN = resolve_config_path("trains/default.yaml")
STRAIGHT = resolve_config_path("scenes/straight_pass.yaml")
HEADLAND = resolve_config_path("scenes/headland_turn.yaml")
BIN = Path(sys.executable).parent

BASE = f"""\
name: small
train: {TRAIN}
scenes: [{STRAIGHT}, {HEADLAND}]
sample: {{method: grid}}
vary:
  - path: carts[0].hitch_offset
    values: [1.0, 2.0]
  - path: carts[2].length
    low: 5.0
    high: 7.0
    steps: 2
batch: 2
"""


def write_spec(folder: Path, text: str = BASE, name: str = "spec.yaml") -> Path:
    path = folder / name
    path.write_text(text)
    return path


def same_rows(a, b) -> None:
    """Two result tables hold the same rows, bit for bit (NaN included)."""
    assert a.schema.equals(b.schema)
    assert a.num_rows == b.num_rows
    for name in a.column_names:
        x, y = a.column(name).to_numpy(zero_copy_only=False), b.column(name).to_numpy(zero_copy_only=False)
        if x.dtype.kind == "f":
            assert np.array_equal(x.view(np.int64), y.view(np.int64)), name
        else:
            assert list(x) == list(y), name


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    folder = tmp_path_factory.mktemp("serial")
    spec = sweep_spec.load(write_spec(folder))
    result = engine.run_sweep(spec, folder / "out", serial=True, quiet=True)
    return spec, pq.read_table(result.results)


def test_a_grid_runs_every_scheme_on_every_scene(serial):
    spec, table = serial
    rows = table.to_pylist()
    assert [r["run"] for r in rows] == list(range(8))
    assert {(r["carts[0].hitch_offset"], r["carts[2].length"]) for r in rows} == {(1.0, 5.0), (1.0, 7.0),
                                                                                  (2.0, 5.0), (2.0, 7.0)}
    assert [r["scene"] for r in rows] == ["straight_pass", "headland_turn"] * 4
    assert all(r["verdict"] == "ok" and r["level"] == "dynamic" for r in rows)
    assert len({r["train_hash"] for r in rows}) == 4
    # the metrics move with the scheme: a longer seeder off-tracks more in the turn
    turn = {(r["carts[0].hitch_offset"], r["carts[2].length"]): r for r in rows if r["scene"] == "headland_turn"}
    assert turn[1.0, 7.0]["cart3_offtracking_m"] > turn[1.0, 5.0]["cart3_offtracking_m"]


@pytest.mark.slow
def test_a_sweep_on_the_local_cluster_equals_it_run_serially(serial, tmp_path):
    spec, expected = serial
    result = engine.run_sweep(spec, tmp_path / "cluster", workers=2, quiet=True)
    assert "LocalCluster, 2 worker processes" in result.engine
    same_rows(pq.read_table(result.results), expected)
    assert len(list((tmp_path / "cluster" / "parts").glob("*.parquet"))) == 4  # batch 2 runs: one scheme a task


@dataclass
class Cluster:
    scheduler_file: Path
    client: object  # distributed.Client
    procs: list

    def __iter__(self):  # scheduler_file, client = cluster
        return iter((self.scheduler_file, self.client))


@pytest.fixture
def cluster(tmp_path):
    """A Dask scheduler and two workers (with their nannies), each its own process, on 127.0.0.1."""
    scheduler_file = tmp_path / "scheduler.json"
    env = dict(os.environ, DASK_DISTRIBUTED__WORKER__DAEMON="False")
    # --dashboard-address: the HTTP servers (health, metrics) run without a dashboard too, on 0.0.0.0
    # unless told
    procs = [subprocess.Popen([str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", "0",
                               "--no-dashboard", "--dashboard-address", "127.0.0.1:0",
                               "--scheduler-file", str(scheduler_file)], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)]
    try:
        deadline = time.monotonic() + 60
        while not scheduler_file.exists():
            assert time.monotonic() < deadline, "the scheduler did not start"
            time.sleep(0.1)
        for _ in range(2):
            procs.append(subprocess.Popen([str(BIN / "dask"), "worker", "--scheduler-file", str(scheduler_file),
                                           "--nthreads", "1", "--nworkers", "1", "--host", "127.0.0.1",
                                           "--no-dashboard", "--dashboard-address", "127.0.0.1:0"], env=env, stdout=subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL, start_new_session=True))
        from distributed import Client

        with Client(scheduler_file=str(scheduler_file), timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
            yield Cluster(scheduler_file, client, procs)
    finally:
        for p in reversed(procs):
            with pytest.raises(ProcessLookupError) if p.poll() is not None else _nothing():
                os.killpg(p.pid, signal.SIGTERM)
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


@pytest.mark.slow
def test_a_sweep_on_an_external_cluster_gives_the_same_rows(serial, cluster, tmp_path):
    spec, expected = serial
    scheduler_file, client = cluster
    address = client.scheduler.address
    assert address.startswith("tcp://127.0.0.1:")
    for info in client.scheduler_info()["workers"].values():
        assert info["host"] == "127.0.0.1"
    by_file = engine.run_sweep(spec, tmp_path / "file", scheduler_file=str(scheduler_file), quiet=True)
    assert "Dask cluster at tcp://127.0.0.1" in by_file.engine
    same_rows(pq.read_table(by_file.results), expected)
    by_address = engine.run_sweep(spec, tmp_path / "address", scheduler=address, quiet=True)
    same_rows(pq.read_table(by_address.results), expected)


@pytest.mark.slow
def test_the_cluster_and_the_local_cluster_listen_on_loopback_only(serial, cluster, tmp_path):
    """The network rule for the sweep's processes: every TCP and UDP socket of the scheduler, the
    nannies and the workers (external, and the embedded LocalCluster's) is bound to 127.0.0.1."""
    import psutil
    from test_loopback import LOOPBACK, sockets

    spec, _ = serial
    scheduler_file, client = cluster
    engine.run_sweep(spec, tmp_path / "external", scheduler_file=str(scheduler_file), quiet=True)
    pids = set()
    for proc in cluster.procs:
        pids |= {proc.pid} | {child.pid for child in psutil.Process(proc.pid).children(recursive=True)}
    pids |= set(client.run(os.getpid).values())
    seen = [s for pid in pids for s in sockets(pid)]
    assert any(s.kind.startswith("tcp") for s in seen)
    assert all(s.address in LOOPBACK for s in seen), [str(s) for s in seen if s.address not in LOOPBACK]

    with engine.cluster_client(2, None, None) as (local_client, what):  # the engine's own LocalCluster
        assert "LocalCluster" in what
        mine = {os.getpid()} | set(local_client.run(os.getpid).values())
        mine |= {child.pid for child in psutil.Process().children(recursive=True)}
        seen = [s for pid in mine for s in sockets(pid)]
        own = [s for s in seen if s.kind.startswith("tcp")]
        assert own and all(s.address in LOOPBACK for s in own), [str(s) for s in own if s.address not in LOOPBACK]


MANY = BASE.replace("values: [1.0, 2.0]", "values: [0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0, 2.25]").replace(
    "steps: 2", "steps: 4").replace(f"scenes: [{STRAIGHT}, {HEADLAND}]", f"scenes: [{HEADLAND}]").replace(
    "batch: 2", "batch: 1")


@pytest.mark.slow
def test_killing_a_worker_loses_nothing(cluster, tmp_path):
    """32 one-run tasks on two workers; one worker process is killed (SIGKILL) once some parts are
    written: its task runs again elsewhere, and the rows equal a serial sweep's."""
    scheduler_file, client = cluster
    spec = sweep_spec.load(write_spec(tmp_path, MANY))
    out = tmp_path / "killed"
    done = {}
    thread = threading.Thread(target=lambda: done.update(
        result=engine.run_sweep(spec, out, scheduler_file=str(scheduler_file), quiet=True)))
    thread.start()
    deadline = time.monotonic() + 120
    while len(list((out / "parts").glob("*.parquet"))) < 3 if (out / "parts").exists() else True:
        assert time.monotonic() < deadline and thread.is_alive(), "no parts were written"
        time.sleep(0.01)
    pids = client.run(os.getpid)
    victim = sorted(pids.values())[0]
    os.kill(victim, signal.SIGKILL)
    thread.join(timeout=300)
    assert not thread.is_alive()
    expected = engine.run_sweep(spec, tmp_path / "serial", serial=True, quiet=True)
    same_rows(pq.read_table(done["result"].results), pq.read_table(expected.results))


@pytest.mark.slow
def test_a_killed_sweep_resumes_without_running_what_it_finished(tmp_path):
    """``mta sweep`` killed (SIGKILL) after some parts: the parts stay as they were, the second call
    runs only the missing schemes, and the results equal an uninterrupted sweep's."""
    spec_path = write_spec(tmp_path, MANY)
    out = tmp_path / "out"
    proc = subprocess.Popen([str(BIN / "mta"), "sweep", str(spec_path), "--out", str(out), "--serial", "--quiet"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while len(list(out.glob("parts/*.parquet"))) < 4:
        assert time.monotonic() < deadline and proc.poll() is None, proc.stderr.read()
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    proc.stderr.close()
    kept = {p.name: p.read_bytes() for p in out.glob("parts/*.parquet")}
    assert 4 <= len(kept) < 32
    # a part cut short is only ever a .tmp (which the resume does not read): every .parquet is whole
    assert {p.suffix for p in out.glob("parts/*")} <= {".parquet", ".tmp"}
    assert all(pq.read_table(out / "parts" / name).num_rows > 0 for name in kept)
    spec = sweep_spec.load(spec_path)
    result = engine.run_sweep(spec, out, serial=True, quiet=True)
    assert result.resumed == len(kept) and result.ran == 32 - len(kept)
    for name, data in kept.items():
        assert (out / "parts" / name).read_bytes() == data
    whole = engine.run_sweep(spec, tmp_path / "whole", serial=True, quiet=True)
    same_rows(pq.read_table(result.results), pq.read_table(whole.results))


def test_resuming_into_the_results_of_another_spec_is_refused(serial, tmp_path, capsys):
    first = write_spec(tmp_path, BASE, "a.yaml")
    assert cli.main(["sweep", str(first), "--out", str(tmp_path / "out"), "--serial", "--quiet"]) == 0
    other = write_spec(tmp_path, BASE.replace("steps: 2", "steps: 3"), "b.yaml")
    capsys.readouterr()
    assert cli.main(["sweep", str(other), "--out", str(tmp_path / "out"), "--serial", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--out" in err and "another spec" in err


def test_resuming_after_the_base_train_changed_is_refused(tmp_path, capsys):
    """The same spec text, its base train changed between two calls (as `mta sweep export -o` onto
    it once did): the second call refuses in one line naming the train, and leaves the results as
    they were; with the train as it was, it resumes (nothing left to run)."""
    train = tmp_path / "train.yaml"
    train.write_text(Path(TRAIN).read_text())
    spec = write_spec(tmp_path, BASE.replace(str(TRAIN), str(train)))
    out = tmp_path / "out"
    assert cli.main(["sweep", str(spec), "--out", str(out), "--serial", "--quiet"]) == 0
    before = {p.name: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    original = train.read_text()
    train.write_text(original.replace("mass: 16000", "mass: 17000"))
    capsys.readouterr()
    assert cli.main(["sweep", str(spec), "--out", str(out), "--serial", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "train changed since its runs" in err, err
    assert {p.name: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    train.write_text(original)
    assert cli.main(["sweep", str(spec), "--out", str(out), "--serial", "--quiet"]) == 0


def test_a_file_where_the_parts_folder_goes_is_refused_in_one_line(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "parts").write_text("a file")
    assert cli.main(["sweep", str(write_spec(tmp_path)), "--out", str(out), "--serial", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "parts is a folder (a file stands there)" in err, err


def test_constraints_drop_schemes_before_they_run(tmp_path):
    text = BASE + "constraints:\n  - {quantity: total_length, max: 18}\n"
    spec = sweep_spec.load(write_spec(tmp_path, text))
    rows = pq.read_table(engine.run_sweep(spec, tmp_path / "out", serial=True, quiet=True).results).to_pylist()
    # total length: l_1 + l_2 + l_3 + a_1 + a_2 = 3 + 5 + l_3 + a_1 + 1.5: over 18 only for a_1 = 2, l_3 = 7
    dropped = [r for r in rows if r["verdict"] == "dropped"]
    assert {(r["carts[0].hitch_offset"], r["carts[2].length"]) for r in dropped} == {(2.0, 7.0)}
    assert all(r["reason"] == "total_length 18.5 > max 18" for r in dropped)
    assert all(np.isnan(r["energy_kWh"]) for r in dropped) and len(dropped) == 2


def test_random_and_saltelli_samples_are_seeded(tmp_path):
    text = BASE.replace("{method: grid}", "{method: random, count: 5, seed: 7}").replace("    steps: 2\n", "")
    a = sweep_spec.schemes(sweep_spec.load(write_spec(tmp_path, text, "a.yaml")))
    b = sweep_spec.schemes(sweep_spec.load(write_spec(tmp_path, text, "b.yaml")))
    assert a == b and len(a) == 5
    assert all(v in (1.0, 2.0) and 5.0 <= w <= 7.0 for v, w in a)
    salt = text.replace("{method: random, count: 5, seed: 7}", "{method: saltelli, count: 8, seed: 3}")
    s = sweep_spec.load(write_spec(tmp_path, salt, "c.yaml"))
    assert len(sweep_spec.schemes(s)) == 8 * (2 * 2 + 2) == sweep_spec.scheme_count(s)


def test_an_order_and_a_choice_of_trains_are_factors(tmp_path):
    text = f"""\
train: {TRAIN}
scenes: [{HEADLAND}]
vary:
  - order: carts
  - path: train
    choices: [{TRAIN}, {resolve_config_path("trains/stiff_steering.yaml")}]
"""
    spec = sweep_spec.load(write_spec(tmp_path, text))
    rows = pq.read_table(engine.run_sweep(spec, tmp_path / "out", serial=True, quiet=True).results).to_pylist()
    assert len(rows) == 4
    assert sorted({r["order"] for r in rows}) == ["air_cart,seeder", "seeder,air_cart"]
    assert len({r["train_hash"] for r in rows}) == 4
    assert {r["train"] for r in rows} == {TRAIN, resolve_config_path("trains/stiff_steering.yaml")}
    mixed = text.replace("stiff_steering.yaml", "offset_hitch.yaml")
    with pytest.raises(sweep_spec.SweepSpecError, match="vary.0..order: carts .* trains of one length"):
        sweep_spec.load(write_spec(tmp_path, mixed, "mixed.yaml"))


BAD = [
    ("vary:\n  - path: carts[7].length\n    values: [1]\n", "path: 'carts[7].length'", "no 7 there"),
    ("vary:\n  - path: carts[0].lenght\n    values: [1]\n", "path: 'carts[0].lenght'", "a field of the base train"),
    ("vary:\n  - path: carts[2].length\n    low: 5\n    high: 4\n    steps: 2\n", "high: 4", ">= low 5"),
    ("vary:\n  - path: carts[2].length\n    low: -1\n    high: 4\n    steps: 2\n", "vary[0] (carts[2].length = -1)",
     "length: -1"),
    ("vary:\n  - path: carts[2].length\n    values: [4, nan]\n", "values", "finite"),
    ("vary:\n  - path: carts[2].length\n    low: 4\n    high: 5\n", "steps", "given"),
    ("sample: {method: sobol}\nvary:\n  - path: carts[2].length\n    values: [4]\n", "method: 'sobol'",
     "one of grid, random, saltelli"),
    ("sample: {method: saltelli, count: 6}\nvary:\n  - path: carts[2].length\n    low: 4\n    high: 5\n",
     "count: 6", "a power of 2"),
    ("varry: []\n", "varry", "did you mean vary?"),
    ("vary:\n  - {quantity: 1}\n", "quantity", "unknown field"),
    ("vary:\n  - path: carts[2].length\n    values: [4]\nconstraints:\n  - {quantity: width, max: 1}\n",
     "quantity: 'width'", "one of total_length"),
    ("vary:\n  - path: carts[2].length\n    values: [4]\nbags: [99]\n", "bags[0]: 99", "a run index in [0, 0]"),
]


@pytest.mark.parametrize("tail, field, rule", BAD)
def test_a_bad_spec_is_refused_in_one_line_naming_the_field(tail, field, rule, tmp_path, capsys):
    text = f"train: {TRAIN}\nscenes: [{STRAIGHT}]\n" + tail
    path = write_spec(tmp_path, text)
    assert cli.main(["sweep", str(path), "--out", str(tmp_path / "out"), "--serial"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("mta sweep: ") and field in err and rule in err, err
    assert not (tmp_path / "out").exists()  # refused before anything is written


def test_missing_files_and_bad_yaml_are_refused(tmp_path, capsys):
    cases = [(f"train: {tmp_path / 'none.yaml'}\nscenes: [{STRAIGHT}]\nvary: [{{path: x, values: [1]}}]\n", "train"),
             (f"train: {TRAIN}\nscenes: []\nvary: [{{path: x, values: [1]}}]\n", "scenes"),
             ("train: [unclosed\n", "yaml")]
    for text, field in cases:
        path = write_spec(tmp_path, text)
        assert cli.main(["sweep", str(path), "--serial"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and field in err, err
    assert cli.main(["sweep", str(tmp_path / "absent.yaml")]) == 2
    assert "absent.yaml" in capsys.readouterr().err


@pytest.mark.slow
def test_a_run_asked_for_writes_its_bag_and_the_bag_repeats_the_row(tmp_path):
    """``bags: [3]``: run 3 (scheme 1, the headland turn) also as ``mta run`` writes it, from its
    exported files; mta analyze's off-tracking of that bag (its own search, on the recorded poses)
    equals the row's."""
    from mta_sim_ros.analysis import load_bag, off_tracking

    text = BASE.replace("  - path: carts[2].length\n    low: 5.0\n    high: 7.0\n    steps: 2\n", "") + "bags: [3]\n"
    path = write_spec(tmp_path, text)
    out = tmp_path / "out"
    assert cli.main(["sweep", str(path), "--out", str(out), "--serial", "--quiet"]) == 0
    row = pq.read_table(out / "results.parquet").to_pylist()[3]
    assert row["scene"] == "headland_turn" and row["carts[0].hitch_offset"] == 2.0
    bag = out / "bags" / "run-3.mcap"
    data = load_bag(bag)
    tracked = {entry["cart"]: entry["max_abs_m"] for entry in off_tracking(data)}
    assert tracked["air_cart"] == pytest.approx(row["cart2_offtracking_m"], abs=1e-9)
    assert tracked["seeder"] == pytest.approx(row["cart3_offtracking_m"], abs=1e-9)


def test_a_results_folder_with_a_part_not_of_this_sweep_is_refused_in_one_line(serial, tmp_path, capsys):
    """A damaged part, another sweep's part, a copy of a part: refused, naming the file, and nothing
    of the folder is changed; removed, the same command completes."""
    path = write_spec(tmp_path)
    out = tmp_path / "out"
    assert cli.main(["sweep", str(path), "--out", str(out), "--serial", "--quiet"]) == 0
    parts = sorted((out / "parts").glob("*.parquet"))
    other = tmp_path / "other"
    assert cli.main(["sweep", str(write_spec(tmp_path, BASE.replace("steps: 2", "steps: 3"), "o.yaml")), "--out",
                     str(other), "--serial", "--quiet"]) == 0
    cases = [(b"PAR1 not a parquet file", "ArrowInvalid"),
             (sorted((other / "parts").glob("*.parquet"))[-1].read_bytes(), "holds schemes outside 0..3"),
             (parts[0].read_bytes(), "holds schemes another part holds")]
    results = (out / "results.parquet").read_bytes()
    capsys.readouterr()
    for data, rule in cases:
        planted = out / "parts" / "part-000000900-000000901.parquet"
        planted.write_bytes(data)
        assert cli.main(["sweep", str(path), "--out", str(out), "--serial", "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "part-000000900-000000901.parquet" in err and rule in err, err
        assert (out / "results.parquet").read_bytes() == results
        planted.unlink()
    assert cli.main(["sweep", str(path), "--out", str(out), "--serial", "--quiet"]) == 0
