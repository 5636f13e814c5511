"""Writing outputs: several files as one (all or none), a device written directly, strict JSON.
No ROS; the bottom rules (validate.py checks the paths before this writes them)."""
from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Callable


def write_together(paths: dict[str, Path], write: Callable[[dict[str, Path]], None]) -> None:
    """Write several output files as one: ``write(partial paths)`` writes each file of ``paths``
    (name -> path) to a partial file beside it (``.NAME.partial``), then each is renamed onto its
    place. A failure leaves no partial file and no output changed."""
    temporary = {name: path.with_name(f".{path.name}.partial") for name, path in paths.items()}
    try:
        write(temporary)
        for name, path in paths.items():
            os.replace(temporary[name], path)
    finally:
        for tmp in temporary.values():
            tmp.unlink(missing_ok=True)


def finite_or_none(value):
    """``value`` with every float that is not finite (NaN, inf) made None, through dicts, lists and
    tuples: what a JSON reader takes (JSON has no NaN; null says 'not measured')."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(v) for v in value]
    return value


def json_text(value, indent: int | None = 2) -> str:
    """``value`` as strict JSON (non-finite numbers null: finite_or_none), ending in a newline."""
    import json

    return json.dumps(finite_or_none(value), indent=indent, allow_nan=False) + "\n"


def write_output(path: Path, write: Callable[[Path], None]) -> None:
    """``write(a path)`` into the output ``path``: a regular file (or a new one) through its partial
    file (write_together: a failure leaves it as it was); anything else that takes writes (a device
    such as /dev/stdout, a pipe) directly, never replaced by a file. OSError when it fails."""
    target = Path(path)
    if target.exists() and not target.is_file():
        write(target)
        return
    write_together({"out": target}, lambda tmp: write(tmp["out"]))
