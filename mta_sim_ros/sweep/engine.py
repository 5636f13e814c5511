"""Running a sweep: schemes in batches, serially or on Dask, into resumable Parquet parts.

Each task runs one batch of schemes, every scene of each (``run_schemes``: a pure function of the
spec and the schemes, so a batch gives the same rows wherever it runs: serially, on the embedded
LocalCluster, on a cluster). The client writes each finished batch as a Parquet part
(``ResultStore``: temp file + rename, so a part is whole or absent) as it arrives; a re-run of the
same spec into the same folder runs only the schemes no part holds. A worker that dies loses the
batch it was running and Dask runs that batch again elsewhere (its ``allowed-failures``); the
client's death loses the batches in flight, never a part already written.

Engine: ``workers`` processes of one thread each on an embedded ``distributed.LocalCluster`` bound
to 127.0.0.1 (no dashboard), by default one per core; or the cluster of ``scheduler`` (an address)
or ``scheduler_file``. Each worker compiles (or loads from numba's disk cache) the kernels once,
at start (``warm_up``), not per run.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import math
import os
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

from .. import __version__
from ..run.batch import OK, metric_names, run_metrics
from ..run.lanes_batch import REFUSALS, run_metrics_many
from ..validate import InputError, fail, one_line, show
from ..field.scene import FieldScene
from . import spec as sweep_spec

#: seconds to reach a given scheduler, and for its first worker
CONNECT_TIMEOUT = 20


class EngineError(RuntimeError):
    """The engine failed (not a run: a task, the cluster); one line, said with exit code 1."""


#: verdicts besides batch.OK and batch.STOPPED
DROPPED, REFUSED = "dropped", "refused"
RESULTS, CSV, PARTS, SPEC_COPY = "results.parquet", "results.csv", "parts", "spec.yaml"
SPEC_PATH = "spec_path.txt"  # where the spec was read (its relative paths are from its folder)
INPUTS = "inputs.json"  # the digest of every input the runs read (input_digests): a resume must match it


def input_digests(spec) -> dict[str, str]:
    """{input: sha256} of what a sweep's runs read: the spec's text, the base train's and each
    scene's data as loaded, each train choice's, the package's version. The data, not the bytes:
    a comment changes no result."""
    def digest(value) -> str:
        return hashlib.sha256(json.dumps(value, sort_keys=True, default=str).encode()).hexdigest()

    out = {"spec": digest(spec.text), "train": digest(spec.train_data), "package_version": __version__}
    out.update({f"scene {name}": digest(data) for name, data, _ in spec.scenes})
    out.update({f"train choice {label}": digest(data) for label, (data, _) in spec.train_files.items()})
    return out


def columns(spec) -> list[tuple[str, str]]:
    """(name, kind) of every column of a sweep's rows, in order; kind: int, float, str."""
    out = [("run", "int"), ("scheme", "int"), ("scene", "str")]
    out += [(f.name, "float" if f.kind == "number" else "str") for f in spec.factors]
    out += [("train_hash", "str"), ("verdict", "str"), ("reason", "str"), ("level", "str"), ("simulated_s", "float")]
    out += [(m, "float") for m in all_metric_names(spec)]
    out += [("version", "str"), ("seed", "int")]
    return out


def all_metric_names(spec) -> list[str]:
    """The metric columns: a manoeuvre scene's (batch.metric_names), then a field scene's
    (field.coverage.NAMES) that are not among them, when the spec has field scenes. A run fills
    its own kind's columns; the others stay NaN."""
    names = metric_names(max_carts(spec))
    if sweep_spec.has_field_scenes(spec):
        from ..field.coverage import NAMES

        names += [n for n in NAMES if n not in names]
    return names


def max_carts(spec) -> int:
    trains = [spec.train_data] + [data for data, _ in spec.train_files.values()]
    return max(len(t.get("carts", [])) for t in trains)


def train_hash(train) -> str:
    """The resolved train (every number after loading, names, force lists), not its file: sha256, 16 hex."""
    return hashlib.sha256(repr(replace(train, source="")).encode()).hexdigest()[:16]


def run_schemes(spec, schemes: list[tuple[int, tuple]]) -> list[dict]:
    """The rows of the given (index, scheme) pairs, every scene of each, in order. The runs of scenes
    that are not field scenes run together (run.lanes_batch: those of one shape across SIMD lanes),
    each run's row as it would be alone."""
    rows: list = []
    names = all_metric_names(spec)
    scenes = spec.scene_names
    fidelity = None if spec.fidelity == "auto" else spec.fidelity
    todo = []  # (row's place, base, index, scene's place, scene, train)
    for index, scheme in schemes:
        base = {"scheme": index, **sweep_spec.scheme_label(spec, scheme), "version": __version__, "seed": spec.seed}
        try:
            train, built = sweep_spec.build(spec, scheme)
        except InputError as err:
            rows += [_row(base, index, j, scenes, names, REFUSED, str(err)) for j in range(len(scenes))]
            continue
        base["train_hash"] = train_hash(train)
        broken = "; ".join(filter(None, (c.broken(train) for c in spec.constraints)))
        if broken:
            rows += [_row(base, index, j, scenes, names, DROPPED, broken) for j in range(len(scenes))]
            continue
        for j, scene in enumerate(built):
            todo.append((len(rows), base, index, j, scene, train))
            rows.append(None)
    plain = [t for t in todo if not isinstance(t[4], FieldScene)]
    results = dict(zip((t[0] for t in plain), run_metrics_many([t[4] for t in plain], fidelity=fidelity)))
    for place, base, index, j, scene, train in todo:
        if place in results:
            result = results[place]
        else:
            try:
                result = run_field_scene(scene, train)
            except REFUSALS as err:
                result = err
        if isinstance(result, Exception):
            rows[place] = _row(base, index, j, scenes, names, REFUSED, str(result))
            continue
        row = _row(base, index, j, scenes, names, result.verdict, result.reason)
        row.update(level=result.level, simulated_s=result.simulated, **result.metrics)
        rows[place] = row
    return rows


def run_field_scene(scene, train):
    """A field scene worked whole by ``train`` (controllers/implement/work.py), as a batch.RunResult:
    its figures (field.coverage.NAMES), the verdict and reason of the run, the level (dynamic: the
    implement-tracking loop steps the article's model)."""
    from ..controllers.implement.design import Settings
    from ..controllers.implement.work import work_field
    from ..run.batch import RunResult
    from .spec import worked_by

    worked_by(scene, train)  # no implement, no speed followed: refused in one line
    work = work_field(scene.field, train, scene.options(train), Settings(**scene.drive))
    trace = work.run.trace
    figures = dict(work.result.values, position_error_m=work.accuracy.error)  # the run's stated accuracy
    return RunResult(figures, trace.verdict, trace.reason, float(trace.t[-1]), "dynamic", None)


def _row(base: dict, index: int, j: int, scenes: list, names: list, verdict: str, reason: str) -> dict:
    row = {"run": index * len(scenes) + j, "scene": scenes[j], **base, "verdict": verdict, "reason": reason,
           "level": "", "simulated_s": 0.0}
    row.setdefault("train_hash", "")
    for name in names:
        row[name] = math.nan
    return row


def warm_up() -> str:
    """Compile (or load from numba's cache) the kernels in this process: a short run of the
    default train. Returns what runs (``Simulation.compiled_note``)."""
    from ..config import resolve_config_path
    from ..physics.loader import load_scene
    from ..run.simulation import Simulation

    scene = load_scene(resolve_config_path("scenes/straight_pass.yaml"))
    scene = replace(scene, duration=0.1)
    run_metrics(scene, fidelity="dynamic")
    return Simulation(scene, fidelity="dynamic").compiled_note


# -- the results ---------------------------------------------------------------------------------

class ResultStore:
    """A sweep's folder: the spec it ran (``spec.yaml``, and where it was read: ``spec_path.txt``),
    one Parquet part per finished batch
    (``parts/``), and at the end ``results.parquet`` and ``results.csv`` (every row, by run)."""

    def __init__(self, folder: str | os.PathLike, spec):
        import pyarrow as pa

        self.folder = Path(folder)
        self.spec = spec
        self.columns = columns(spec)
        kinds = {"int": pa.int64(), "float": pa.float64(), "str": pa.string()}
        self.schema = pa.schema([(name, kinds[kind]) for name, kind in self.columns])
        self.parts = self.folder / PARTS
        copy = self.folder / SPEC_COPY
        if copy.exists():
            if copy.read_text(encoding="utf-8", errors="replace") != spec.text:
                fail("--out", show(str(self.folder)), f"a folder of results of this spec, or a new one: its "
                     f"{SPEC_COPY} is another spec (resuming runs only what the same spec has left)")
            self._same_inputs()
        else:
            self.folder.mkdir(parents=True, exist_ok=True)
            _write_atomic(copy, spec.text.encode())
            _write_atomic(self.folder / INPUTS, json.dumps(input_digests(spec), indent=1).encode())
        _write_atomic(self.folder / SPEC_PATH, (os.path.abspath(spec.source) + "\n").encode())
        if self.parts.exists() and not self.parts.is_dir():
            fail("--out", show(str(self.folder)), f"a results folder whose {PARTS} is a folder (a file stands there)")
        self.parts.mkdir(exist_ok=True)

    def _same_inputs(self) -> None:
        """A resume reads the same inputs as the runs already there (input_digests), else it would mix
        results of two trains in one file: refused in one line naming what changed."""
        path = self.folder / INPUTS
        try:
            recorded = json.loads(path.read_text())
        except (OSError, ValueError):
            recorded = None
        now = input_digests(self.spec)
        if not isinstance(recorded, dict):
            fail("--out", show(str(self.folder)), f"a folder of results whose {INPUTS} says what they were run "
                 "from (it is missing or unreadable: resume into a new folder)")
        changed = sorted(k for k in set(now) | set(recorded) if now.get(k) != recorded.get(k))
        if changed:
            fail("--out", show(str(self.folder)), "a folder of results run from the same inputs, or a new one: "
                 f"{', '.join(changed)} changed since its runs (resuming would mix two trains' results)")

    def done(self, schemes: int) -> set[int]:
        """The schemes some part holds (all their scenes: a part holds whole schemes). A part that
        is not one of this sweep's (unreadable, other columns, schemes past the ``schemes`` it has)
        is refused in one line naming it: removed, the same command runs its schemes again."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        out: set[int] = set()
        for part in sorted(self.parts.glob("part-*.parquet")):
            name = f"{PARTS}/{part.name}"
            rule = (f"a Parquet part of the sweep in {self.folder} (remove it, and the same command runs its "
                    "schemes again)")
            try:
                schema = pq.read_schema(part)
                if not schema.remove_metadata().equals(self.schema):
                    fail("part", name, f"{rule}: its columns are another sweep's")
                found = pq.read_table(part, columns=["scheme"]).column(0).to_pylist()
            except (pa.ArrowException, OSError, ValueError) as err:
                if isinstance(err, InputError):
                    raise
                fail("part", name, f"{rule}: {type(err).__name__}: {one_line(str(err))[:200]}")
            if not all(isinstance(i, int) and 0 <= i < schemes for i in found):
                fail("part", name, f"{rule}: it holds schemes outside 0..{schemes - 1}")
            if out.intersection(found):
                fail("part", name, f"{rule}: it holds schemes another part holds "
                     f"({min(out.intersection(found))}, ...)")
            out.update(found)
        return out

    def write(self, rows: list[dict]) -> Path:
        import pyarrow as pa
        import pyarrow.parquet as pq

        first, last = rows[0]["run"], rows[-1]["run"]
        path = self.parts / f"part-{first:09d}-{last:09d}.parquet"
        table = pa.Table.from_pylist([{name: row.get(name) for name, _ in self.columns} for row in rows],
                                     schema=self.schema)
        temp = path.with_suffix(".tmp")
        pq.write_table(table, temp)
        os.replace(temp, path)
        return path

    def finish(self) -> tuple[Path, Path, int]:
        """results.parquet and results.csv of every part, sorted by run; (paths, rows)."""
        import pyarrow as pa
        import pyarrow.csv as pcsv
        import pyarrow.parquet as pq

        parts = sorted(self.parts.glob("part-*.parquet"))
        tables = [pq.read_table(p, schema=self.schema) for p in parts]
        table = pa.concat_tables(tables) if tables else self.schema.empty_table()
        table = table.sort_by("run")
        results, csv = self.folder / RESULTS, self.folder / CSV
        temp = results.with_suffix(".tmp")
        pq.write_table(table, temp)
        os.replace(temp, results)
        temp = csv.with_suffix(".tmp")
        pcsv.write_csv(table, temp)
        os.replace(temp, csv)
        return results, csv, table.num_rows


def _write_atomic(path: Path, data: bytes) -> None:
    temp = path.with_suffix(path.suffix + ".tmp")
    temp.write_bytes(data)
    os.replace(temp, path)


# -- progress ------------------------------------------------------------------------------------------

class Progress:
    """Runs done, runs per second and time left: one line rewritten on a terminal, else a line
    every 10 % (nothing when ``quiet``)."""

    def __init__(self, total: int, quiet: bool = False, stream=sys.stderr):
        self.total, self.done, self.quiet, self.stream = total, 0, quiet, stream
        self.t0 = time.monotonic()
        self.tty = stream.isatty()
        self._said = -1

    def add(self, runs: int) -> None:
        self.done += runs
        if self.quiet:
            return
        elapsed = time.monotonic() - self.t0
        rate = self.done / elapsed if elapsed > 0 else 0.0
        left = (self.total - self.done) / rate if rate > 0 else math.inf
        line = (f"runs {self.done}/{self.total} ({100.0 * self.done / max(self.total, 1):.1f} %), "
                f"{rate:.1f} runs/s, {_clock(left)} left")
        if self.tty:
            self.stream.write("\r" + line + " " * 4)
            self.stream.flush()
        elif int(10 * self.done / max(self.total, 1)) > self._said:
            self._said = int(10 * self.done / max(self.total, 1))
            print(line, file=self.stream, flush=True)

    def close(self) -> None:
        if self.tty and not self.quiet:
            self.stream.write("\n")


def _clock(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "?"
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


# -- the engine ------------------------------------------------------------------------------------------

@dataclass
class SweepRun:
    """What a sweep did: schemes and runs in all, run now, already there; rows written; the engine."""

    schemes: int
    runs: int
    ran: int
    resumed: int
    rows: int
    engine: str
    wall: float
    results: Path
    csv: Path


def batches(todo: list[tuple[int, tuple]], runs_per_task: int, scenes: int) -> list[list[tuple[int, tuple]]]:
    size = max(1, runs_per_task // max(scenes, 1))
    return [todo[i:i + size] for i in range(0, len(todo), size)]


def run_sweep(spec, out: str | os.PathLike, workers: int | None = None, scheduler: str | None = None,
              scheduler_file: str | None = None, serial: bool = False, quiet: bool = False) -> SweepRun:
    """Run every scheme of ``spec`` not yet in ``out`` (module docstring) and write the results."""
    store = ResultStore(out, spec)
    all_schemes = sweep_spec.schemes(spec)
    done = store.done(len(all_schemes))
    todo = [(i, s) for i, s in enumerate(all_schemes) if i not in done]
    scenes = len(spec.scenes)
    tasks = batches(todo, spec.batch, scenes)
    progress = Progress(len(todo) * scenes, quiet)
    t0 = time.monotonic()
    if serial or not tasks:
        engine = "serial (this process)"
        for task in tasks:
            store.write(run_schemes(spec, task))
            progress.add(len(task) * scenes)
    else:
        with cluster_client(workers, scheduler, scheduler_file) as (client, engine):
            from distributed import as_completed

            try:
                client.run(warm_up)
                shared = client.scatter(spec, broadcast=True)
                futures = [client.submit(run_schemes, shared, task, pure=False) for task in tasks]
                for future in as_completed(futures):
                    rows = future.result()
                    store.write(rows)
                    progress.add(len(rows))
                    future.release()
            except (InputError, OSError):
                raise
            except Exception as err:  # a task failed on a worker (not a run: runs give rows)
                raise EngineError(f"{engine}: {type(err).__name__}: {one_line(str(err))[:300]} (the parts written "
                                  f"so far stay in {store.folder}: the same command resumes; every worker needs "
                                  "this package installed)") from None
    progress.close()
    results, csv, rows = store.finish()
    return SweepRun(len(all_schemes), len(all_schemes) * scenes, len(todo) * scenes, len(done) * scenes, rows,
                    engine, time.monotonic() - t0, results, csv)


@contextlib.contextmanager
def cluster_client(workers: int | None, scheduler: str | None, scheduler_file: str | None):
    """(a distributed Client, what it is): the cluster named, or an embedded LocalCluster."""
    from distributed import Client, LocalCluster

    if scheduler or scheduler_file:
        field, given = ("--scheduler", scheduler) if scheduler else ("--scheduler-file", scheduler_file)
        if scheduler_file:  # read here: distributed waits for a missing file without end
            scheduler = _scheduler_address(scheduler_file)
        try:
            client = Client(address=scheduler, timeout=f"{CONNECT_TIMEOUT}s")
        except (OSError, ValueError, TypeError, KeyError) as err:
            fail(field, show(given), f"{'the address' if scheduler else 'the scheduler file'} of a running Dask "
                 f"scheduler ({type(err).__name__}: {one_line(str(err))[:200]})")
        with client:
            try:
                client.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
            except TimeoutError:
                fail(field, show(given), f"a Dask cluster with workers: none joined in {CONNECT_TIMEOUT} s")
            count = len(client.scheduler_info(**({"n_workers": -1} if _takes_n_workers(client) else {}))["workers"])
            yield client, f"Dask cluster at {client.scheduler.address} ({count} workers)"
        return
    n = workers or os.cpu_count() or 1
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None,
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        yield client, f"Dask LocalCluster, {n} worker processes of 1 thread on 127.0.0.1"


def _scheduler_address(path: str) -> str:
    """The ``address`` of a Dask scheduler file (JSON, as ``dask scheduler --scheduler-file`` writes)."""
    import json

    try:
        with open(path, "rb") as stream:
            data = json.loads(stream.read(1 << 16).decode("utf-8"))
    except FileNotFoundError:
        fail("--scheduler-file", show(path), "an existing Dask scheduler file (dask scheduler --scheduler-file "
             "writes it)")
    except (OSError, ValueError) as err:  # UnicodeDecodeError and JSONDecodeError are ValueErrors
        fail("--scheduler-file", show(path), f"a readable Dask scheduler file ({type(err).__name__}: "
             f"{one_line(str(err))[:200]})")
    if not isinstance(data, dict) or not isinstance(data.get("address"), str):
        fail("--scheduler-file", show(path), "a Dask scheduler file: a JSON object with its \"address\"")
    return data["address"]


def _takes_n_workers(client) -> bool:
    import inspect

    return "n_workers" in inspect.signature(client.scheduler_info).parameters
