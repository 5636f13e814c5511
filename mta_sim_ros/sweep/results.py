"""A finished sweep's results read back: the table, its factors and metrics, Pareto fronts, the
best schemes, Sobol indices. report.py writes them out, export.py turns one run back into files.

Definitions:

objective
    a metric column of the results (``batch.metric_names``), minimized unless the caller says
    otherwise; ``report.make_report`` maximizes the ones in MAXIMIZED (more is better) by default.
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
"""
from __future__ import annotations

import math
import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import validate
from ..run.batch import OK
from ..validate import InputError, fail, show
from .engine import RESULTS, SPEC_COPY

#: columns every results table has (engine.columns)
REQUIRED = ("run", "scheme", "scene", "train_hash", "verdict", "reason")
#: numeric columns that are neither factors nor metrics
NOT_METRICS = ("run", "scheme", "simulated_s", "seed")
#: metrics where more is better: report.make_report maximizes them unless told otherwise
MAXIMIZED = ("min_jackknife_margin_deg", "min_rollover_margin", "min_tip_margin", "min_grip_margin", "worked_area_ha",
             "distance_m", "coverage_pct", "field_efficiency_pct", "working_distance_km")
#: what a report compares when it is not told: per scene, the first of these that vary over its ok
#: runs (then those defined but constant): a field worked whole, and a manoeuvre scene
FIELD_OBJECTIVES = ("total_time_h", "fuel_l", "skipped_area_ha", "energy_kWh", "double_worked_ha")
SCENE_OBJECTIVES = ("energy_per_ha_kWh", "headland_width_m", "max_offtracking_m", "swept_width_m", "peak_power_kW",
                    "energy_kWh", "max_hitch_angle_deg")
#: the units of a metric, by the last part of its name
UNITS = {"kWh": "kWh", "kW": "kW", "kN": "kN", "ha": "ha", "deg": "deg", "m": "m", "s": "s"}
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
        fail("folder", quoted(folder), "a sweep's folder (mta sweep --out): no such folder")
    if not path.is_file():
        fail("folder", quoted(folder), f"a finished sweep's folder, holding {RESULTS} (not found: {path}; "
             "the engine writes it when every run is done)")
    try:
        df = pd.read_parquet(path)
    except (OSError, ValueError, pyarrow.ArrowException) as err:
        fail("results", quoted(path), f"a readable Parquet file of a sweep's results "
             f"({validate.one_line(str(err))[:200]})")
    missing = [c for c in REQUIRED if c not in df.columns]
    if missing:
        fail("results", quoted(path), f"a sweep's results: no column {', '.join(missing)}")
    return df.sort_values("run", kind="stable").reset_index(drop=True)


def quoted(path) -> str:
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


def finite_values(rows, name: str) -> np.ndarray:
    """The finite values of column ``name`` over the ok rows."""
    v = rows[name].to_numpy(dtype=float)[(rows["verdict"] == OK).to_numpy(dtype=bool)]
    return v[np.isfinite(v)]


def defined(rows, name: str) -> bool:
    """A metric some ok row has finite."""
    return name in rows.columns and finite_values(rows, name).size > 0


def varying(rows, name: str) -> bool:
    """A metric with two or more different finite values over the ok rows (else degenerate: not a
    distribution to draw, nor an objective to trade)."""
    return name in rows.columns and np.unique(finite_values(rows, name)).size > 1


def defined_metrics(rows) -> list[str]:
    return [m for m in metric_columns(rows) if defined(rows, m)]


def default_objectives(rows, count: int = 3) -> list[str]:
    """The objectives of a scene's rows when none are given: the first ``count`` of FIELD_OBJECTIVES
    (a field scene: one with total_time_h defined) or SCENE_OBJECTIVES that vary over its ok runs,
    then the defined constant ones; at least two where two metrics are defined at all."""
    preferred = FIELD_OBJECTIVES if defined(rows, "total_time_h") else SCENE_OBJECTIVES
    # the runs' stated accuracy is not something a scheme is chosen for (it is the report's own line)
    pool = list(preferred) + [m for m in defined_metrics(rows) if m not in preferred and m != "position_error_m"]
    chosen = [m for m in pool if varying(rows, m)][:count]
    chosen += [m for m in pool if defined(rows, m) and m not in chosen][:max(0, 2 - len(chosen))]
    return chosen


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
    ok = df[ok_finite(df, x, y)]
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


def ok_finite(df, *names: str) -> np.ndarray:
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
    rows = df[(df["scene"] == scene).to_numpy(dtype=bool) & ok_finite(df, x)]
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
        fail("folder", quoted(folder), f"a sweep's folder, holding the {SPEC_COPY} the engine keeps "
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


# --------------------------------------------------------------------------- names


def sweep_name(folder: Path) -> str:
    """The ``name:`` of the spec text kept with the results, else the results folder's name."""
    try:
        _, data = stored_spec(folder)
    except InputError:
        return folder.resolve().name
    name = data.get("name")
    return name if isinstance(name, str) and name else folder.resolve().name


def file_part(name: str) -> str:
    """A scene's name as part of a file name: characters other than letters, digits, '_', '-', '.'
    as '_'."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)
