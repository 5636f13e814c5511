"""The report of one or several recorded runs (``mta analyze``): the folder of figures, summary
and CSV files; several bags are overlaid in the figures and compared with the first one."""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Sequence

from ..validate import distinct_output, output_folder
from .bagdata import AnalyzeError, load_bag
from .compare import compare
from .markdown import markdown
from .measures import summarize
from .plots import figures_of, plot_all
from .tables import csv_paths, write_csv


def default_folder(bags: Sequence[str | os.PathLike]) -> Path:
    stems = [Path(b).stem for b in bags]
    if len(stems) == 1:
        return Path("reports") / stems[0]
    return Path("reports") / ("compare_" + "_".join(stems))


def _labels(bags: Sequence[str | os.PathLike]) -> list[str]:
    labels, seen = [], {}
    for b in bags:
        stem = Path(b).stem
        seen[stem] = seen.get(stem, 0) + 1
        labels.append(stem if seen[stem] == 1 else f"{stem}_{seen[stem]}")
    return labels


def analyze(bags: Sequence[str | os.PathLike], folder: str | os.PathLike | None = None) -> dict:
    """Write the report of one or more bags; returns ``{"folder", "summaries", "differences",
    "figures", "csv"}``. Several bags are overlaid in the figures and compared with the first one.
    """
    if not bags:
        raise AnalyzeError("no bag given")
    folder = output_folder(folder if folder is not None else default_folder(bags), "--output")
    labels = _labels(bags)
    datas = [load_bag(b, lab) for b, lab in zip(bags, labels)]
    csv_folders = [folder / "csv" if len(datas) == 1 else folder / "csv" / d.label for d in datas]
    for path in [folder / "summary.json", folder / "summary.md"] + [folder / name for name, _ in figures_of(datas)] \
            + [p for d, f in zip(datas, csv_folders) for p in csv_paths(d, f)]:
        distinct_output(path, "--output", bags)  # no report file written over a bag it reads
    summaries = [summarize(d) for d in datas]
    differences = {f"{d.label} - {datas[0].label}": compare(datas[0], d) for d in datas[1:]}
    figures = plot_all(datas, folder)
    csv_files = []
    for d, f in zip(datas, csv_folders):
        csv_files += write_csv(d, f)
    report = {"bags": [str(b) for b in bags], "labels": labels,
              "summaries": summaries[0] if len(datas) == 1 else dict(zip(labels, summaries)),
              "differences": differences}
    (folder / "summary.json").write_text(json.dumps(report, indent=2, default=float) + "\n")
    (folder / "summary.md").write_text(markdown(summaries, labels, differences, figures, csv_files, folder))
    return {"folder": folder, "summaries": summaries, "differences": differences, "figures": figures,
            "csv": csv_files}
