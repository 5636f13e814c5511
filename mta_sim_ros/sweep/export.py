"""One scheme of a sweep written back as files: ``export(folder, run, out)`` writes the train of
one run's scheme as a train file (and its scenes when the scheme varies scene fields), so ``mta
run``, ``mta session`` and the node take it as is.
"""
from __future__ import annotations

import copy
import numbers
import os
from pathlib import Path

import numpy as np

from .. import validate
from ..validate import fail, show
from .engine import DROPPED, REFUSED, SPEC_COPY, SPEC_PATH
from .results import factor_columns, file_part, load_results, quoted, stored_spec, sweep_name


def export(folder: str | os.PathLike, run, out: str | os.PathLike, spec_path: str | os.PathLike | None = None,
           all_scenes: bool = False) -> list[Path]:
    """Write the scheme of run ``run`` of the sweep in ``folder`` as a train file at ``out``: the
    mapping ``spec.scheme_data`` gives (with ``name:`` added if the base train had none, so the
    train loads as the same one), a comment header naming the sweep, the run, the factors' values
    and the train hash. A scheme that varies scene fields also gets each scene, beside ``out`` as
    ``<out stem>.<scene>.yaml``, its ``train:`` the exported file (and its ``fidelity:`` the
    sweep's, unless the sweep's is auto, so the scene runs as the sweep ran it); ``all_scenes``
    writes them for any scheme (a bag of the run needs its scene). Returns the paths written, the
    train file first.

    The schemes come from the spec: ``spec_path`` (its text must be the ``spec.yaml`` the sweep
    kept: else the spec changed since the sweep), or when None the file the sweep read
    (``spec_path.txt``) if its text is still that, or else the kept ``spec.yaml`` itself if
    every file it names is an absolute path (relative ones meant the spec's own folder, which the
    results do not record). The train rebuilt must have the run's train hash. A run that is not
    in the results, or whose scheme was dropped or refused, raises InputError."""
    from ..physics import loader
    from . import engine
    from . import spec as sweep_spec

    folder = Path(folder)
    df = load_results(folder)
    row = _run_row(df, run)
    if row["verdict"] in (DROPPED, REFUSED):
        fail("--run", show(run), f"a run whose scheme was run: it was {row['verdict']} "
             f"({validate.one_line(str(row['reason']))[:300]})")
    spec = _export_spec(folder, spec_path)
    schemes = sweep_spec.schemes(spec)
    index = int(row["scheme"])
    if not 0 <= index < len(schemes):
        fail("scheme", show(index), f"a scheme of the spec ({len(schemes)} of them): the spec changed since the sweep")
    scheme = schemes[index]
    labels = sweep_spec.scheme_label(spec, scheme)
    if list(labels) != factor_columns(df) or any(_differs(labels[k], row[k]) for k in labels):
        fail("--run", show(run), f"a run of the spec's scheme {index}: the factors' values differ (the spec "
             "changed since the sweep)")
    train_data, source, scenes = sweep_spec.scheme_data(spec, scheme)
    train = loader.train_from_data(copy.deepcopy(train_data), source)
    digest = engine.train_hash(train)
    recorded = row["train_hash"] if isinstance(row["train_hash"], str) else ""
    if recorded and digest != recorded:
        fail("train_hash", digest, f"the run's {recorded} (the train rebuilt from {spec.source} is "
             "another: a file the spec names changed since the sweep)")
    if "name" not in train_data:
        train_data = {"name": train.name, **train_data}
    inputs = [spec.source, spec.train_source, *(src for _, _, src in spec.scenes),
              *(src for _, src in spec.train_files.values())]  # never written over: a spec reads them
    out = validate.distinct_output(validate.output_file(out, "--out"), "--out", inputs)
    name = sweep_name(folder)
    header = [f"Train of scheme {index} of sweep {name} (results {folder}, run {int(row['run'])}, "
              f"scene {row['scene']}, verdict {row['verdict']}), exported by mta_sim_ros.sweep.export.",
              f"spec: {spec.source}; base train: {source}",
              "factors: " + ", ".join(f"{k} = {_shown(v)}" for k, v in labels.items()),
              f"train_hash: {digest}"]
    _write_yaml(out, header, train_data)
    written = [out]
    if all_scenes or any(f.target == "scene" for f in spec.factors):
        scene_values = ", ".join(f"{k} = {_shown(v)}" for f, (k, v) in zip(spec.factors, labels.items())
                                 if f.target == "scene")
        for scene_name, data, scene_source in scenes:
            path = validate.distinct_output(validate.output_file(
                out.with_name(f"{out.stem}.{file_part(scene_name)}.yaml"), "--out"), "--out", inputs)
            data = {"name": scene_name, **data} if "name" not in data else data
            data["train"] = os.path.relpath(out.resolve(), path.resolve().parent)
            if spec.fidelity != "auto":
                data["fidelity"] = spec.fidelity
            _write_yaml(path, [f"Scene {scene_name} of scheme {index} of sweep {name} (results {folder}), exported "
                               "by mta_sim_ros.sweep.export.", f"base scene: {scene_source}",
                               f"scene factors: {scene_values}"
                               + (f"; fidelity: {spec.fidelity}, the sweep's" if spec.fidelity != "auto" else "")],
                        data)
            written.append(path)
    return written


def _run_row(df, run):
    """The row of run index ``run`` (InputError if it is not one of the results')."""
    runs = df["run"].to_numpy()
    span = f"0 to {int(runs.max())}" if len(runs) and np.array_equal(runs, np.arange(len(runs))) else "see results.csv"
    if not (isinstance(run, numbers.Integral) and not isinstance(run, bool)):
        fail("--run", show(run), f"a run index of the results ({span})")
    hits = df[runs == int(run)]
    if hits.empty:
        fail("--run", show(int(run)), f"a run index of the results ({span})")
    return hits.iloc[0]


def _export_spec(folder: Path, spec_path):
    """The spec of the sweep in ``folder``, loaded (export's docstring)."""
    from . import spec as sweep_spec

    text, data = stored_spec(folder)
    recorded = folder / SPEC_PATH
    if spec_path is None and recorded.is_file():  # where the sweep read it, if it is still that spec
        where = recorded.read_text(encoding="utf-8", errors="replace").strip()
        if os.path.isfile(where) and validate.read_text(where) == text:
            spec_path = where
    if spec_path is None:
        named = _named_files(data)
        relative = [p for p in named if not (isinstance(p, str) and os.path.isabs(p))]
        if relative:
            fail("--spec", "(not given)", f"the sweep's spec file: the results keep its text ({folder / SPEC_COPY}) "
                 f"but not its folder, and it names files by relative paths ({show(relative[0])})")
        spec_path = folder / SPEC_COPY
    spec = sweep_spec.load(spec_path)
    if spec.text != text:
        fail("--spec", quoted(spec_path), f"the spec of the sweep in {folder}: the spec changed since the sweep "
             f"(its text is not {folder / SPEC_COPY})")
    return spec


def _named_files(data: dict) -> list:
    """The files a spec mapping names: its train, its scenes, the train files of a train choice."""
    scenes = data.get("scenes")
    named = [data.get("train")] + (list(scenes) if isinstance(scenes, list) else [scenes])
    for factor in data.get("vary") or []:
        if isinstance(factor, dict) and factor.get("path") == "train" and isinstance(factor.get("choices"), list):
            named += factor["choices"]
    return named


def _differs(value, cell) -> bool:
    """Whether a scheme's factor value is not the results' cell (numbers exactly, labels as text)."""
    if isinstance(value, str):
        return value != cell
    return not float(value) == float(cell)


def _shown(value) -> str:
    """A factor's value in a header: a number exactly (repr), a label as it is."""
    return repr(float(value)) if validate.is_number(value) else validate.one_line(str(value))


def _write_yaml(path: Path, header: list[str], data: dict) -> None:
    import yaml

    text = "".join(f"# {validate.one_line(line)}\n" for line in header)
    text += yaml.safe_dump(data, sort_keys=False, allow_unicode=True)
    temp = path.with_name(path.name + ".tmp")
    temp.write_text(text, encoding="utf-8")
    os.replace(temp, path)
