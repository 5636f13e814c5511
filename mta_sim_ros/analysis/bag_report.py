"""The report of one or several recorded runs (``mta analyze``): the folder of figures, summary
and CSV files; several bags are overlaid in the figures and compared with the first one."""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Sequence

from ..validate import output_folder
from .bagdata import AnalyzeError, load_bag
from .compare import compare
from .markdown import markdown
from .measures import summarize
from .plots import plot_all
from .tables import write_csv


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
    summaries = [summarize(d) for d in datas]
    differences = {f"{d.label} - {datas[0].label}": compare(datas[0], d) for d in datas[1:]}
    figures = plot_all(datas, folder)
    csv_files = []
    for d in datas:
        csv_files += write_csv(d, folder / "csv" if len(datas) == 1 else folder / "csv" / d.label)
    report = {"bags": [str(b) for b in bags], "labels": labels,
              "summaries": summaries[0] if len(datas) == 1 else dict(zip(labels, summaries)),
              "differences": differences}
    (folder / "summary.json").write_text(json.dumps(report, indent=2, default=float) + "\n")
    (folder / "summary.md").write_text(markdown(summaries, labels, differences, figures, csv_files, folder))
    return {"folder": folder, "summaries": summaries, "differences": differences, "figures": figures,
            "csv": csv_files}
