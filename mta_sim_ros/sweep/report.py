"""The report of a sweep: Pareto fronts, scatter matrices, the best schemes, Sobol indices
(results.py defines them).

``make_report(folder)`` writes into ``folder/report/`` (or ``out``), per scene of the results:

* ``pareto_<scene>.png``: x against y for every ok run of the scene (grey) and the Pareto front
  (highlighted, connected in order of x);
* ``scatter_<scene>.png``: a scatter matrix of the ok runs: the number factors, x, y,
  energy_kWh and max_hitch_angle_deg (histograms on the diagonal);
* and one ``report.md``: runs by verdict and the reasons of the runs that are not ok, then per
  scene the Pareto front, the best schemes by x and, for a Saltelli sweep, the Sobol indices of
  x and y.
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
    factor_columns,
    file_part,
    load_results,
    ok_finite,
    pareto_front,
    scene_names,
    sobol_indices,
    stored_design,
    sweep_name,
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
    name = sweep_name(folder)
    written: list[Path] = []
    sections = []
    for s in scenes if scene is None else [scene]:
        rows = df[(df["scene"] == s).to_numpy(dtype=bool)]
        front = pareto_front(rows, x, y, minimize)
        pareto_png = out / f"pareto_{file_part(s)}.png"
        scatter_png = out / f"scatter_{file_part(s)}.png"
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
    finite = int(ok_finite(rows, x, y).sum())
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
