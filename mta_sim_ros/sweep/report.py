"""A sweep's results read back: Pareto fronts, Sobol indices, the best schemes, one scheme exported.

``make_report(folder)`` writes into ``folder/report/`` (or ``out``), per scene of the results:

* ``pareto_<scene>.png``: x against y for every ok run of the scene (grey) and the Pareto front
  (highlighted, connected in order of x);
* ``scatter_<scene>.png``: a scatter matrix of the ok runs: the number factors, x, y,
  energy_kWh and max_hitch_angle_deg (histograms on the diagonal);
* and one ``report.md``: runs by verdict and the reasons of the runs that are not ok, then per
  scene the Pareto front, the best schemes by x and, for a Saltelli sweep, the Sobol indices of
  x and y.

Definitions:

objective
    a metric column of the results (``batch.metric_names``), minimized unless the caller says
    otherwise; ``make_report`` maximizes the ones in MAXIMIZED (more is better) by default.
Pareto front
    among the ok runs of one scene whose x and y are both finite, the runs no other such run
    dominates; run j dominates run i when j is at least as good in both objectives and better in
    one. Two runs equal in both do not dominate each other: both are on the front or neither.
best schemes by x
    the ok runs of one scene with a finite x, best x first, ties by y (NaN last), then by run.
Sobol indices
    first-order S1 and total ST (with their 95 % bootstrap half-widths) of a metric over one
    scene, by SALib's estimators (``SALib.analyze.sobol``, second order on, as the Saltelli sample
    was drawn) on the metric of every scheme of the scene, ordered by scheme. The design is read
    from the results, not from the spec's files: the factors are the columns between ``scene``
    and ``train_hash`` (each on [0, 1], which is what ``spec.sobol_problem`` gives too, the unit
    cube the sample was drawn on) and the base count N is the ``sample.count`` of the spec text
    the sweep kept (``spec.yaml``); a scene must hold N (2 D + 2) runs, every one ok with the
    metric finite.

``export(folder, run, out)`` writes the train of one run's scheme as a train file (and its scenes
when the scheme varies scene fields), so ``mta run``, ``mta session`` and the node take it as is.
"""
from __future__ import annotations

import copy
import math
import numbers
import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import validate
from ..run.batch import OK, STOPPED
from ..validate import InputError, fail, show
from .engine import DROPPED, REFUSED, RESULTS, SPEC_COPY, SPEC_PATH

VERDICTS = (OK, STOPPED, DROPPED, REFUSED)
#: columns every results table has (engine.columns)
REQUIRED = ("run", "scheme", "scene", "train_hash", "verdict", "reason")
#: numeric columns that are neither factors nor metrics
NOT_METRICS = ("run", "scheme", "simulated_s", "seed")
#: metrics where more is better: make_report maximizes them unless told otherwise
MAXIMIZED = ("min_jackknife_margin_deg", "worked_area_ha", "distance_m")
#: metrics the scatter matrix shows besides the factors, x and y
SCATTER_METRICS = ("energy_kWh", "max_hitch_angle_deg")
#: the units of a metric, by the last part of its name
UNITS = {"kWh": "kWh", "kW": "kW", "kN": "kN", "ha": "ha", "deg": "deg", "m": "m", "s": "s"}
#: runs drawn in grey at most (a seeded sample beyond that); the front is always drawn whole
MAX_POINTS = 100_000
#: runs of a scatter matrix at most (a seeded sample beyond that)
MAX_SCATTER = 20_000
#: reasons listed per verdict (the most frequent), the rest counted together
MAX_REASONS = 20
FIGURE_DPI = 100
#: the seed of SALib's bootstrap of the confidence intervals (SALib ignores a seed of 0)
SOBOL_SEED = 1


# --------------------------------------------------------------------------- the results


def load_results(folder: str | os.PathLike) -> "pandas.DataFrame":
    """The rows of a finished sweep, ``folder/results.parquet``, sorted by run. A missing folder
    or file, one Parquet cannot read, or a table without the columns the engine writes raises
    InputError (one line, naming the path)."""
    import pandas as pd
    import pyarrow

    path = Path(folder) / RESULTS
    if not Path(folder).is_dir():
        fail("folder", _path(folder), "a sweep's folder (mta sweep --out): no such folder")
    if not path.is_file():
        fail("folder", _path(folder), f"a finished sweep's folder, holding {RESULTS} (not found: {path}; "
             "the engine writes it when every run is done)")
    try:
        df = pd.read_parquet(path)
    except (OSError, ValueError, pyarrow.ArrowException) as err:
        fail("results", _path(path), f"a readable Parquet file of a sweep's results "
             f"({validate.one_line(str(err))[:200]})")
    missing = [c for c in REQUIRED if c not in df.columns]
    if missing:
        fail("results", _path(path), f"a sweep's results: no column {', '.join(missing)}")
    return df.sort_values("run", kind="stable").reset_index(drop=True)


def _path(path) -> str:
    """A path in a fault, whole and quoted (``show`` would cut a long one)."""
    return validate.one_line(repr(str(path)))


def factor_columns(df) -> list[str]:
    """The factors' columns: those between ``scene`` and ``train_hash`` (engine.columns; none if
    the table lacks either)."""
    names = list(df.columns)
    if "scene" not in names or "train_hash" not in names:
        return []
    return names[names.index("scene") + 1:names.index("train_hash")]


def metric_columns(df) -> list[str]:
    """The metric columns: the numeric columns that are not factors, nor run, scheme,
    simulated_s, seed."""
    from pandas.api.types import is_bool_dtype, is_numeric_dtype

    factors = set(factor_columns(df))
    return [c for c in df.columns if c not in factors and c not in NOT_METRICS
            and is_numeric_dtype(df[c]) and not is_bool_dtype(df[c])]


def scene_names(df) -> list[str]:
    """The scenes of the results, in the order of their runs."""
    return list(dict.fromkeys(df.sort_values("run", kind="stable")["scene"].tolist()))


def check_metric(df, name, field: str) -> str:
    """``name`` if it is a metric column of ``df``, else InputError naming ``field`` (``--x``) and
    the closest metric."""
    known = metric_columns(df)
    if not isinstance(name, str) or name not in known:
        fail(field, show(name), f"a metric of the results: one of {', '.join(known)}{validate.closest(name, known)}")
    return name


def axis_label(name: str) -> str:
    """A column's name as an axis label, its unit from the name's last part: energy_per_ha_kWh ->
    'energy per ha (kWh/ha)', headland_width_m -> 'headland width (m)'; other names as they are."""
    stem, _, last = name.rpartition("_")
    if not stem or last not in UNITS:
        return name
    unit = UNITS[last] + ("/ha" if stem.endswith("_per_ha") else "")
    return f"{stem.replace('_', ' ')} ({unit})"


# --------------------------------------------------------------------------- Pareto front


def pareto_front(df, x: str, y: str, minimize: tuple[bool, bool] = (True, True)):
    """The Pareto front (module docstring) of x and y over the rows of ``df`` that are ok with x
    and y finite; ``minimize`` says, per objective, whether less is better (else more). Rows of
    ``df`` (their index kept), best x first, ties by y, then by run. Exact, O(n log n): sorted
    by (x, y) in the better-first sense, a row is on the front when its y is the best of the rows
    with its x and better than every y of the rows with a better x."""
    check_metric(df, x, "--x")
    check_metric(df, y, "--y")
    ok = df[_ok_finite(df, x, y)]
    a = _signed(ok[x], minimize[0])
    b = _signed(ok[y], minimize[1])
    order = np.lexsort((ok["run"].to_numpy(), b, a))
    a, b = a[order], b[order]
    if not len(a):
        return ok
    start = np.r_[True, a[1:] != a[:-1]]  # the first row of each run of equal x
    group = np.cumsum(start) - 1
    group_best = b[start]  # sorted by y within an x, the first row has the best y
    better_x_best = np.r_[math.inf, np.minimum.accumulate(group_best)[:-1]]  # best y of the better x's
    keep = (b == group_best[group]) & (group_best[group] < better_x_best[group])
    return ok.iloc[order[keep]]


def _ok_finite(df, *names: str) -> np.ndarray:
    """The rows that are ok with every column of ``names`` finite."""
    mask = (df["verdict"] == OK).to_numpy(dtype=bool)
    for name in names:
        mask = mask & np.isfinite(df[name].to_numpy(dtype=float))
    return mask


def _signed(values, minimize: bool) -> np.ndarray:
    """Values turned so that less is better."""
    v = values.to_numpy(dtype=float)
    return v if minimize else -v


def best_runs(df, x: str, y: str, scene: str, count: int, minimize: tuple[bool, bool] = (True, True)):
    """The ``count`` best ok runs of ``scene`` by x (module docstring: ties by y, NaN last, then run)."""
    rows = df[(df["scene"] == scene).to_numpy(dtype=bool) & _ok_finite(df, x)]
    a = _signed(rows[x], minimize[0])
    b = _signed(rows[y], minimize[1])
    b = np.where(np.isnan(b), math.inf, b)
    order = np.lexsort((rows["run"].to_numpy(), b, a))
    return rows.iloc[order[:count]]


# --------------------------------------------------------------------------- Sobol indices


@dataclass(frozen=True)
class Design:
    """What Sobol indices need of a sweep: its sampling method, Saltelli's base count N and the
    factors' names (the results' factor columns, in order)."""

    method: str
    count: int
    factors: tuple

    def problem(self) -> dict:
        """SALib's problem: each factor on [0, 1] (the unit cube the sample was drawn on)."""
        return {"num_vars": len(self.factors), "names": list(self.factors),
                "bounds": [[0.0, 1.0]] * len(self.factors)}


def stored_spec(folder: str | os.PathLike) -> tuple[str, dict]:
    """(text, mapping) of the spec the sweep in ``folder`` kept (``spec.yaml``)."""
    path = Path(folder) / SPEC_COPY
    if not path.is_file():
        fail("folder", _path(folder), f"a sweep's folder, holding the {SPEC_COPY} the engine keeps "
             f"(not found: {path})")
    text = validate.read_text(path)
    return text, validate.parse_mapping(text, str(path))


def stored_design(folder: str | os.PathLike, df) -> Design:
    """The Design of the sweep in ``folder``: the method and count of its kept spec text, the
    factors of its results' columns (no file the spec names is read)."""
    _, data = stored_spec(folder)
    sample = data.get("sample") if isinstance(data.get("sample"), dict) else {}
    method = sample.get("method", "grid")
    count = sample.get("count", 0)
    return Design(str(method), int(count) if validate.is_finite(count) else 0, tuple(factor_columns(df)))


def sobol_indices(spec, df, metric: str, scene: str) -> dict:
    """Sobol indices (module docstring) of ``metric`` over the runs of ``scene``:
    ``{factor: {"S1", "S1_conf", "ST", "ST_conf"}}``, floats. ``spec``: the sweep's spec
    (``spec.Spec``, method saltelli) or its Design (``stored_design``). The scene must hold
    every scheme, N (2 D + 2) runs, each ok with the metric finite; else InputError saying how
    many lack it. The bootstrap intervals are drawn from a fixed seed (the same table each time)."""
    from SALib.analyze import sobol

    design = _design(spec)
    if design.method != "saltelli":
        fail("sample.method", show(design.method), "saltelli for Sobol indices (the estimators need Saltelli's "
             "sequence)")
    if tuple(factor_columns(df)) != design.factors:
        fail("factors", show(list(design.factors)), f"the factor columns of the results "
             f"({', '.join(factor_columns(df))}): the spec is not the sweep's")
    check_metric(df, metric, "metric")
    rows = df[(df["scene"] == scene).to_numpy(dtype=bool)].sort_values("scheme", kind="stable")
    if rows.empty:
        fail("scene", show(scene), f"a scene of the results: one of {', '.join(scene_names(df))}"
             f"{validate.closest(scene, scene_names(df))}")
    d = len(design.factors)
    expected = design.count * (2 * d + 2)
    schemes = rows["scheme"].to_numpy()
    if len(rows) != expected or not np.array_equal(schemes, np.arange(expected)):
        fail("scene", show(scene), f"a scene with every scheme of the Saltelli sample: N (2 D + 2) = "
             f"{design.count} x {2 * d + 2} = {expected} runs, schemes 0 to {expected - 1} (it has {len(rows)})")
    y = rows[metric].to_numpy(dtype=float)
    not_ok = (rows["verdict"] != OK).to_numpy(dtype=bool)
    lacking = not_ok | ~np.isfinite(y)
    if lacking.any():
        fail(metric, f"missing in {int(lacking.sum())} of {len(rows)} runs of scene {scene!r} "
             f"({int(not_ok.sum())} not ok, {int((~not_ok & ~np.isfinite(y)).sum())} not finite)",
             "given by every run for Sobol indices (Saltelli's estimators need every sample)")
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a constant metric: 0/0, the indices NaN
        result = sobol.analyze(design.problem(), y, calc_second_order=True, print_to_console=False, seed=SOBOL_SEED)
    indices = {name: {key: float(result[key][i]) for key in ("S1", "S1_conf", "ST", "ST_conf")}
               for i, name in enumerate(design.factors)}
    if not all(math.isfinite(v) for factor in indices.values() for v in factor.values()):
        fail(metric, f"variance {float(np.var(y)):.3g} over {len(y)} runs of {scene}",
             "a metric that varies for Sobol indices (SALib's estimators gave non-finite ones)")
    return indices


def _design(spec) -> Design:
    if isinstance(spec, Design):
        return spec
    from . import spec as sweep_spec

    if isinstance(spec, sweep_spec.Spec):
        return Design(spec.method, spec.count, tuple(sweep_spec.sobol_problem(spec)["names"]))
    raise TypeError(f"sobol_indices: spec must be a sweep Spec or a Design, not {type(spec).__name__}")


# --------------------------------------------------------------------------- the report


def make_report(folder: str | os.PathLike, x: str = "energy_per_ha_kWh", y: str = "headland_width_m",
                scene: str | None = None, best: int = 10, out: str | os.PathLike | None = None,
                minimize: tuple[bool, bool] | None = None) -> list[Path]:
    """Write the report of the sweep in ``folder`` (module docstring) into ``out`` (default
    ``folder/report/``) for ``scene`` (None: every scene of the results); ``best`` runs in the
    table of the best ones; ``minimize`` per objective (None: minimized unless in MAXIMIZED).
    Returns the paths written, report.md last."""
    df = load_results(folder)
    check_metric(df, x, "--x")
    check_metric(df, y, "--y")
    if y == x:
        fail("--y", show(y), f"another metric than --x ({x})")
    if not (isinstance(best, numbers.Integral) and not isinstance(best, bool) and validate.COUNT.test(best)):
        fail("--best", show(best), f"a whole number {validate.COUNT.text}")
    scenes = scene_names(df)
    if scene is not None and scene not in scenes:
        fail("--scene", show(scene), f"a scene of the results: one of {', '.join(scenes)}"
             f"{validate.closest(scene, scenes)}")
    if minimize is None:
        minimize = (x not in MAXIMIZED, y not in MAXIMIZED)
    folder = Path(folder)
    out = validate.output_folder(folder / "report" if out is None else out, "--out")
    try:
        design = stored_design(folder, df)
    except InputError:  # results without the spec text they ran: no Sobol indices
        design = Design(f"unknown (no readable {SPEC_COPY})", 0, tuple(factor_columns(df)))
    name = _sweep_name(folder)
    written: list[Path] = []
    sections = []
    for s in scenes if scene is None else [scene]:
        rows = df[(df["scene"] == s).to_numpy(dtype=bool)]
        front = pareto_front(rows, x, y, minimize)
        pareto_png = out / f"pareto_{_file_part(s)}.png"
        scatter_png = out / f"scatter_{_file_part(s)}.png"
        plot_pareto(rows, front, x, y, pareto_png, f"{name}: {s}")
        plot_scatter(rows, [x, y], scatter_png, f"{name}: {s}")
        written += [pareto_png, scatter_png]
        sobol = None
        if design.method == "saltelli":
            sobol = {}
            for metric in (x, y):
                try:
                    sobol[metric] = sobol_indices(design, df, metric, s)
                except InputError as err:
                    sobol[metric] = str(err)
        sections.append(_scene_section(s, rows, front, best_runs(df, x, y, s, best, minimize), x, y, best, minimize,
                                       pareto_png, scatter_png, sobol, factor_columns(df)))
    md = out / "report.md"
    md.write_text(_header(name, folder, df, design, x, y, minimize) + _verdicts(df) + "".join(sections),
                  encoding="utf-8")
    return written + [md]


def _sweep_name(folder: Path) -> str:
    """The ``name:`` of the spec text kept with the results, else the results folder's name."""
    try:
        _, data = stored_spec(folder)
    except InputError:
        return folder.resolve().name
    name = data.get("name")
    return name if isinstance(name, str) and name else folder.resolve().name


def _file_part(name: str) -> str:
    """A scene's name as part of a file name: characters other than letters, digits, '_', '-', '.'
    as '_'."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)


def _header(name: str, folder: Path, df, design: Design, x: str, y: str, minimize) -> str:
    scenes = scene_names(df)
    schemes = df["scheme"].nunique()
    sense = ["minimized" if m else "maximized" for m in minimize]
    lines = [f"# Sweep {name}", "",
             f"Results: `{folder / RESULTS}`: {len(df)} runs, {schemes} schemes x {len(scenes)} scenes "
             f"({', '.join(scenes)}); sampling {design.method}"
             + {"saltelli": f" (N = {design.count})", "random": f" (count {design.count})"}.get(design.method, "")
             + ".",
             f"Factors: {', '.join(factor_columns(df)) or '(none)'}.",
             f"Objectives: x = {x} ({sense[0]}), y = {y} ({sense[1]}).", ""]
    return "\n".join(lines) + "\n"


def _verdicts(df) -> str:
    counts = df["verdict"].value_counts()
    verdicts = list(VERDICTS) + sorted(v for v in counts.index if v not in VERDICTS)
    lines = ["## Runs by verdict", "", "| verdict | runs |", "|---|---:|"]
    lines += [f"| {_cell(v)} | {int(counts.get(v, 0))} |" for v in verdicts]
    bad = df[df["verdict"] != OK]
    if not bad.empty:
        lines += ["", "Reasons of the runs that are not ok (the same reason counted together):", "",
                  "| verdict | reason | runs |", "|---|---|---:|"]
        for verdict in verdicts[1:]:
            reasons = bad[bad["verdict"] == verdict]["reason"].fillna("").value_counts()
            reasons = sorted(reasons.items(), key=lambda item: (-item[1], item[0]))
            lines += [f"| {verdict} | {_cell(r) or '(none given)'} | {n} |" for r, n in reasons[:MAX_REASONS]]
            if len(reasons) > MAX_REASONS:
                rest = sum(n for _, n in reasons[MAX_REASONS:])
                lines.append(f"| {verdict} | ({len(reasons) - MAX_REASONS} other reasons) | {rest} |")
    return "\n".join(lines) + "\n\n"


def _scene_section(scene: str, rows, front, top, x: str, y: str, best: int, minimize, pareto_png: Path,
                   scatter_png: Path, sobol, factors: list[str]) -> str:
    finite = int(_ok_finite(rows, x, y).sum())
    lines = [f"## Scene {scene}", "", f"![Pareto front]({pareto_png.name})", "",
             f"![Scatter matrix]({scatter_png.name})", "", f"### Pareto front of {x} and {y}", ""]
    if front.empty:
        lines.append(f"No ok run of this scene has both {x} and {y} finite.")
    else:
        lines.append(f"{len(front)} of the {finite} ok runs with both finite, best {x} first.")
        lines += [""] + _table(front, factors + [x, y, "run"])
    lines += ["", f"### The best {best} schemes by {x}", ""]
    if top.empty:
        lines.append(f"No ok run of this scene has {x} finite.")
    else:
        lines.append(f"{'Lowest' if minimize[0] else 'Highest'} {x} first, ties by {y}.")
        ranked = top.copy()
        ranked.insert(0, "rank", np.arange(1, len(top) + 1))
        lines += [""] + _table(ranked, ["rank"] + factors + [x, y, "run"])
    if sobol is not None:
        lines += ["", "### Sobol indices", "",
                  "First-order S1 and total ST, with their 95 % confidence half-widths (SALib, 100 bootstrap "
                  "resamples).", "", "| metric | factor | S1 | S1 conf | ST | ST conf |",
                  "|---|---|---:|---:|---:|---:|"]
        notes = []
        for metric, indices in sobol.items():
            if isinstance(indices, str):
                notes.append(f"{metric}: no indices: {indices}")
                continue
            for factor, v in indices.items():
                lines.append(f"| {metric} | {_cell(factor)} | {_number(v['S1'])} | {_number(v['S1_conf'])} | "
                             f"{_number(v['ST'])} | {_number(v['ST_conf'])} |")
        if notes:
            lines += [""] + [f"- {_cell(n)}" for n in notes]
    return "\n".join(lines) + "\n\n"


def _table(rows, columns: list[str]) -> list[str]:
    """A Markdown table of ``columns`` of ``rows``."""
    lines = ["| " + " | ".join(_cell(c) for c in columns) + " |", "|" + "---|" * len(columns)]
    for _, row in rows.iterrows():
        lines.append("| " + " | ".join(_value(row[c]) for c in columns) + " |")
    return lines


def _value(v) -> str:
    if isinstance(v, (float, np.floating)):
        return _number(float(v))
    return _cell(str(v))


def _number(v: float) -> str:
    return "NaN" if math.isnan(v) else f"{v:.6g}"


def _cell(text: str) -> str:
    """Text for a Markdown table cell: one line, '|' escaped."""
    return validate.one_line(str(text)).replace("|", "\\|")


# --------------------------------------------------------------------------- figures


def _figure(width_in: float, height_in: float):
    from matplotlib.figure import Figure

    return Figure(figsize=(width_in, height_in), dpi=FIGURE_DPI, layout="constrained")


def _sample(rows, limit: int):
    """At most ``limit`` of ``rows`` (a seeded sample when there are more), and whether sampled."""
    if len(rows) <= limit:
        return rows, False
    pick = np.sort(np.random.default_rng(0).choice(len(rows), size=limit, replace=False))
    return rows.iloc[pick], True


def plot_pareto(rows, front, x: str, y: str, path: Path, title: str) -> Path:
    """x against y: the ok runs with both finite in grey, the front highlighted and connected."""
    from ..compat import legend_below

    fig = _figure(7.0, 5.0)
    ax = fig.add_subplot()
    shown, sampled = _sample(rows[_ok_finite(rows, x, y)], MAX_POINTS)
    if len(shown):
        ax.scatter(shown[x], shown[y], s=10, color="0.65", linewidths=0,
                   label=f"ok runs ({'a sample of ' if sampled else ''}{len(shown)})")
    if len(front):
        ax.plot(front[x], front[y], "-o", color="tab:red", markersize=5, linewidth=1.2,
                label=f"Pareto front ({len(front)})")
        legend_below(fig, ax, fontsize=9, ncol=2)
    else:
        ax.text(0.5, 0.5, f"no ok run has {x} and {y} finite", transform=ax.transAxes, ha="center", va="center")
    ax.set_xlabel(axis_label(x))
    ax.set_ylabel(axis_label(y))
    ax.set_title(title)
    ax.grid(True, linewidth=0.4, alpha=0.5)
    fig.savefig(path, dpi=FIGURE_DPI)
    return path


def plot_scatter(rows, metrics: list[str], path: Path, title: str) -> Path:
    """A scatter matrix of the ok runs: the number factors, ``metrics`` and SCATTER_METRICS (those
    of the results with some finite value); each pair from the runs where both are finite,
    histograms on the diagonal."""
    from pandas.api.types import is_numeric_dtype

    ok = rows[(rows["verdict"] == OK).to_numpy(dtype=bool)]
    names = [c for c in factor_columns(rows) if is_numeric_dtype(rows[c])]
    names += [m for m in list(metrics) + list(SCATTER_METRICS) if m in rows.columns]
    names = [c for c in dict.fromkeys(names) if np.isfinite(ok[c].to_numpy(dtype=float)).any()]
    ok, sampled = _sample(ok, MAX_SCATTER)
    n = len(names)
    cell = min(1.9, 16.0 / max(n, 1))
    fig = _figure(max(cell * n, 4.0), max(cell * n, 3.0))
    if n == 0:
        ax = fig.add_subplot()
        ax.set_axis_off()
        ax.text(0.5, 0.5, "no ok run with a finite value", ha="center", va="center")
    else:
        axes = fig.subplots(n, n, squeeze=False, sharex="col")
        for i, yi in enumerate(names):
            for j, xj in enumerate(names):
                ax = axes[i][j]
                if i == j:
                    v = ok[xj].to_numpy(dtype=float)
                    ax.hist(v[np.isfinite(v)], bins=20, color="tab:blue", alpha=0.7)
                else:
                    both = ok[np.isfinite(ok[xj].to_numpy(dtype=float)) & np.isfinite(ok[yi].to_numpy(dtype=float))]
                    ax.scatter(both[xj], both[yi], s=4, color="tab:blue", alpha=0.5, linewidths=0)
                ax.tick_params(labelsize=6)
                if i == n - 1:
                    ax.set_xlabel(axis_label(xj), fontsize=7)
                else:
                    ax.tick_params(labelbottom=False)
                if j == 0 and i != 0:
                    ax.set_ylabel(axis_label(yi), fontsize=7)
                elif j != 0 or i == 0:
                    ax.tick_params(labelleft=False)
    fig.suptitle(f"{title}: ok runs" + (f" (a sample of {len(ok)})" if sampled else f" ({len(ok)})"), fontsize=10)
    fig.savefig(path, dpi=FIGURE_DPI)
    return path


# --------------------------------------------------------------------------- export


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
    out = validate.output_file(out, "--out")
    name = _sweep_name(folder)
    header = [f"Train of scheme {index} of sweep {name} (results {folder}, run {int(row['run'])}, "
              f"scene {row['scene']}, verdict {row['verdict']}), exported by mta_sim_ros.sweep.report.",
              f"spec: {spec.source}; base train: {source}",
              "factors: " + ", ".join(f"{k} = {_shown(v)}" for k, v in labels.items()),
              f"train_hash: {digest}"]
    _write_yaml(out, header, train_data)
    written = [out]
    if all_scenes or any(f.target == "scene" for f in spec.factors):
        scene_values = ", ".join(f"{k} = {_shown(v)}" for f, (k, v) in zip(spec.factors, labels.items())
                                 if f.target == "scene")
        for scene_name, data, scene_source in scenes:
            path = validate.output_file(out.with_name(f"{out.stem}.{_file_part(scene_name)}.yaml"), "--out")
            data = {"name": scene_name, **data} if "name" not in data else data
            data["train"] = os.path.relpath(out.resolve(), path.resolve().parent)
            if spec.fidelity != "auto":
                data["fidelity"] = spec.fidelity
            _write_yaml(path, [f"Scene {scene_name} of scheme {index} of sweep {name} (results {folder}), exported "
                               "by mta_sim_ros.sweep.report.", f"base scene: {scene_source}",
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
        fail("--spec", _path(spec_path), f"the spec of the sweep in {folder}: the spec changed since the sweep "
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
