"""The report of a sweep: Pareto fronts, scatter matrices, the best schemes, Sobol indices
(results.py defines them).

``make_report(folder)`` writes into ``folder/report/`` (or ``out``), per scene of the results, for
the scene's objectives (those asked for, else the first of a field's time, fuel and skipped area,
or of a manoeuvre's energy per hectare, headland width, off-tracking..., that vary over its runs):

* ``pareto_<scene>.png``: the first objective against the second for every ok run of the scene
  (grey) and the Pareto front (highlighted, connected in order of the first);
* ``scatter_<scene>.png``: a scatter matrix of the ok runs: the number factors, the objectives,
  energy_kWh and max_hitch_angle_deg (histograms on the diagonal), leaving out what does not vary
  (a constant, a metric no run has: said in the report, not drawn as a distribution);
* and one ``report.md``: runs by verdict and the reasons of the runs that are not ok, then per
  scene the Pareto front, the best schemes by each objective and, for a Saltelli sweep, the Sobol
  indices of the first two.
"""
from __future__ import annotations

import math
import numbers
import os
from pathlib import Path

import numpy as np

from .. import validate
from ..run.batch import OK, STOPPED
from ..validate import InputError, fail, show
from .engine import DROPPED, REFUSED, RESULTS, SPEC_COPY
from .results import (
    MAXIMIZED,
    Design,
    axis_label,
    best_runs,
    check_metric,
    default_objectives,
    defined,
    defined_metrics,
    factor_columns,
    file_part,
    load_results,
    ok_finite,
    pareto_front,
    scene_names,
    sobol_indices,
    stored_design,
    sweep_name,
    varying,
)

VERDICTS = (OK, STOPPED, DROPPED, REFUSED)
#: metrics the scatter matrix shows besides the factors, x and y
SCATTER_METRICS = ("energy_kWh", "max_hitch_angle_deg")
#: runs drawn in grey at most (a seeded sample beyond that); the front is always drawn whole
MAX_POINTS = 100_000
#: runs of a scatter matrix at most (a seeded sample beyond that)
MAX_SCATTER = 20_000
#: reasons listed per verdict (the most frequent), the rest counted together
MAX_REASONS = 20
FIGURE_DPI = 100


# --------------------------------------------------------------------------- the report


def make_report(folder: str | os.PathLike, x: str | None = None, y: str | None = None,
                scene: str | None = None, best: int = 10, out: str | os.PathLike | None = None,
                minimize: tuple[bool, bool] | None = None) -> list[Path]:
    """Write the report of the sweep in ``folder`` (module docstring) into ``out`` (default
    ``folder/report/``) for ``scene`` (None: every scene of the results); ``best`` runs in each
    table of the best ones; ``minimize`` per objective (None: minimized unless in MAXIMIZED).

    The objectives: ``x`` and ``y`` where given, else per scene the metrics results.default_objectives
    picks (a field scene: time, fuel, skipped area; a manoeuvre: energy per hectare, headland width,
    ...). A metric asked for that no run of a scene has finite is said in that scene's section with
    the metrics it does have, and the scene's defaults stand in; asked for and finite in no scene at
    all, it is refused (InputError naming the metrics that are). Returns the paths written,
    report.md last."""
    df = load_results(folder)
    for given, field in ((x, "--x"), (y, "--y")):
        if given is not None:
            check_metric(df, given, field)
            if not defined(df, given):
                fail(field, show(given), f"a metric some ok run has finite: one of {', '.join(defined_metrics(df))}")
    if x is not None and y == x:
        fail("--y", show(y), f"another metric than --x ({x})")
    if not (isinstance(best, numbers.Integral) and not isinstance(best, bool) and validate.COUNT.test(best)):
        fail("--best", show(best), f"a whole number {validate.COUNT.text}")
    scenes = scene_names(df)
    if scene is not None and scene not in scenes:
        fail("--scene", show(scene), f"a scene of the results: one of {', '.join(scenes)}"
             f"{validate.closest(scene, scenes)}")
    folder = Path(folder)
    out = validate.output_folder(folder / "report" if out is None else out, "--out")
    try:
        design = stored_design(folder, df)
    except InputError:  # results without the spec text they ran: no Sobol indices
        design = Design(f"unknown (no readable {SPEC_COPY})", 0, tuple(factor_columns(df)))
    name = sweep_name(folder)
    written: list[Path] = []
    sections = []
    for s in scenes if scene is None else [scene]:
        rows = df[(df["scene"] == s).to_numpy(dtype=bool)]
        objectives, said = scene_objectives(rows, x, y)
        sense = tuple(m not in MAXIMIZED for m in objectives) if minimize is None else tuple(minimize) + (True,)
        pareto_png = out / f"pareto_{file_part(s)}.png"
        scatter_png = out / f"scatter_{file_part(s)}.png"
        front = None
        if len(objectives) >= 2:
            front = pareto_front(rows, objectives[0], objectives[1], sense[:2])
            plot_pareto(rows, front, objectives[0], objectives[1], pareto_png, f"{name}: {s}")
            written.append(pareto_png)
        drawn, degenerate = plot_scatter(rows, objectives, scatter_png, f"{name}: {s}")
        written.append(scatter_png)
        sobol = None
        if design.method == "saltelli":
            sobol = {}
            for metric in objectives[:2]:
                try:
                    sobol[metric] = sobol_indices(design, df, metric, s)
                except InputError as err:
                    sobol[metric] = str(err)
        sections.append(_scene_section(s, rows, front, objectives, sense, best, said, degenerate, pareto_png,
                                       scatter_png, sobol, factor_columns(df)))
    md = out / "report.md"
    md.write_text(_header(name, folder, df, design, x, y) + _verdicts(df) + "".join(sections), encoding="utf-8")
    return written + [md]


def scene_objectives(rows, x: str | None, y: str | None) -> tuple[list[str], list[str]]:
    """(the scene's objectives, what is said of the ones asked for that it lacks)."""
    said = []
    asked = [m for m in (x, y) if m is not None]
    missing = [m for m in asked if not defined(rows, m)]
    for m in missing:
        said.append(f"{m} is not defined in this scene (no ok run has it finite); defined here: "
                    f"{', '.join(defined_metrics(rows)) or 'none'}")
    kept = [m for m in asked if m not in missing]
    objectives = kept + [m for m in default_objectives(rows) if m not in kept]
    objectives = objectives[:max(2, len(kept))] if asked else objectives
    if asked and kept != asked:
        said.append(f"objectives here: {', '.join(objectives)}")
    return objectives, said


def _header(name: str, folder: Path, df, design: Design, x, y) -> str:
    scenes = scene_names(df)
    schemes = df["scheme"].nunique()
    asked = ", ".join(m for m in (x, y) if m) or "per scene, the first that vary of a field's (time, fuel, " \
        "skipped area) or a manoeuvre's (energy per ha, headland width, off-tracking)"
    lines = [f"# Sweep {name}", "",
             f"Results: `{folder / RESULTS}`: {len(df)} runs, {schemes} schemes x {len(scenes)} scenes "
             f"({', '.join(scenes)}); sampling {design.method}"
             + {"saltelli": f" (N = {design.count})", "random": f" (count {design.count})"}.get(design.method, "")
             + ".",
             f"Factors: {', '.join(factor_columns(df)) or '(none)'}.",
             f"Objectives: {asked}.", ""]
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


def _scene_section(scene: str, rows, front, objectives: list[str], sense, best: int, said: list[str],
                   degenerate: list[str], pareto_png: Path, scatter_png: Path, sobol, factors: list[str]) -> str:
    lines = [f"## Scene {scene}", ""] + [f"- {_cell(n)}" for n in said] + ([""] if said else [])
    if not objectives:
        return "\n".join(lines + ["No metric of this scene has a finite value in an ok run.", "", ""])
    words = [f"{m} ({'minimized' if m_ else 'maximized'})" for m, m_ in zip(objectives, sense)]
    lines += [f"Objectives: {', '.join(words)}.", ""] + _accuracy(rows)
    if front is not None:
        lines += [f"![Pareto front]({pareto_png.name})", ""]
    lines += [f"![Scatter matrix]({scatter_png.name})", ""]
    if degenerate:
        lines += ["Not drawn as distributions (constant or undefined over this scene's ok runs): "
                  + ", ".join(_cell(d) for d in degenerate) + ".", ""]
    shown = factors + objectives + ["run"]
    if front is not None:
        x, y = objectives[:2]
        lines += [f"### Pareto front of {x} and {y}", ""]
        if front.empty:
            lines.append(f"No ok run of this scene has both {x} and {y} finite.")
        else:
            lines.append(f"{len(front)} of the {int(ok_finite(rows, x, y).sum())} ok runs with both finite, "
                         f"best {x} first.")
            lines += [""] + _table(front, shown)
        lines.append("")
    for i, metric in enumerate(objectives):
        others = [m for m in objectives if m != metric]
        top = best_runs(rows, metric, others[0] if others else metric, scene, best, (sense[i], sense[(i + 1) % len(sense)]))
        lines += [f"### The best {best} schemes by {metric}", ""]
        if top.empty:
            lines.append(f"No ok run of this scene has {metric} finite.")
        else:
            lines.append(f"{'Lowest' if sense[i] else 'Highest'} {metric} first"
                         + (f", ties by {others[0]}." if others else "."))
            ranked = top.copy()
            ranked.insert(0, "rank", np.arange(1, len(top) + 1))
            lines += [""] + _table(ranked, ["rank"] + shown)
        lines.append("")
    if sobol is not None:
        lines += ["### Sobol indices", "",
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


def _accuracy(rows) -> list[str]:
    """What the runs of a scene state of their accuracy (``position_error_m``, run/accuracy.py)."""
    if "position_error_m" not in rows:
        return []
    errors = rows.loc[rows["verdict"] == OK, "position_error_m"].astype(float)
    errors = errors[np.isfinite(errors)]
    if errors.empty:
        return []
    return [f"Accuracy: the runs' estimated position error (`position_error_m`, docs/accuracy.md) is at most "
            f"{_number(float(errors.max()))} m, median {_number(float(errors.median()))} m, over {len(errors)} ok "
            "runs.", ""]


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
    shown, sampled = _sample(rows[ok_finite(rows, x, y)], MAX_POINTS)
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


def plot_scatter(rows, metrics: list[str], path: Path, title: str) -> tuple[list[str], list[str]]:
    """A scatter matrix of the ok runs: the number factors, ``metrics`` and SCATTER_METRICS, each
    pair from the runs where both are finite, histograms on the diagonal. A column that does not
    vary over the ok runs (constant, or finite in none) is not a distribution: it is left out.
    Returns (the columns drawn, those left out)."""
    from pandas.api.types import is_numeric_dtype

    ok = rows[(rows["verdict"] == OK).to_numpy(dtype=bool)]
    names = [c for c in factor_columns(rows) if is_numeric_dtype(rows[c])]
    names += [m for m in list(metrics) + list(SCATTER_METRICS) if m in rows.columns]
    names = list(dict.fromkeys(names))
    degenerate = [c for c in names if not varying(rows, c)]
    names = [c for c in names if c not in degenerate]
    ok, sampled = _sample(ok, MAX_SCATTER)
    n = len(names)
    cell = min(1.9, 16.0 / max(n, 1))
    fig = _figure(max(cell * n, 4.0), max(cell * n, 3.0))
    if n == 0:
        ax = fig.add_subplot()
        ax.set_axis_off()
        ax.text(0.5, 0.5, "no column varies over the ok runs", ha="center", va="center")
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
    return names, degenerate
