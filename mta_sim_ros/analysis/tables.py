"""Every message of a recorded run as CSV: one file per topic, one row per message, ``time_s`` (the
log time, exact decimal) then the fields, floats written with ``repr`` so that reading them back
gives the bag's values exactly."""
from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import Any

from .bagdata import BagData, last_component, quaternion_yaw


def _num(x) -> str:
    """A cell: floats as repr (round-trips exactly), the rest as str."""
    if isinstance(x, float):
        return repr(x)
    return str(x)


def _time_s(ns: int) -> str:
    """Log time as an exact decimal string of seconds."""
    sign = "-" if ns < 0 else ""
    sec, frac = divmod(abs(int(ns)), 10**9)
    return f"{sign}{sec}.{frac:09d}"


def _flatten(msg, prefix: str = "") -> list[tuple[str, Any]]:
    """(column, value) pairs of a decoded message: nested fields joined with '.', lists indexed."""
    if isinstance(msg, (list, tuple)):
        items = []
        for i, x in enumerate(msg):
            items += _flatten(x, f"{prefix}{i}.")
        return items
    slots = getattr(type(msg), "__slots__", None)
    if slots is not None and not isinstance(msg, (str, bytes)):
        items = []
        for name in slots:
            items += _flatten(getattr(msg, name), f"{prefix}{name}.")
        return items
    if isinstance(msg, (bytes, bytearray)):
        msg = msg.hex()
    return [(prefix.rstrip("."), msg)]


def csv_rows(data: BagData, topic: str) -> tuple[list[str], list[list[Any]]]:
    """Header and rows (values, not yet text) of one topic, as :func:`write_csv` writes them.

    hitch_poses: ``A<k>_<cart>_x_m, _y_m, _heading_rad`` per cart (heading from the quaternion);
    cart_velocities: ``<cart>_com_speed_mps, <cart>_heading_rad, <cart>_resistance_N``;
    traction_power ``power_W``; steering_angle ``steering_command_rad``; applied_steering
    ``applied_steering_rad``; speed_setpoint ``speed_setpoint_mps``; clock ``clock_sec, clock_nanosec``.
    Any other topic: its fields flattened (``markers.0.pose.position.x``), the union of the columns
    of all its messages, blank where a message lacks one. Header stamps are left out of the known
    topics (the log time is the stamp).
    """
    msgs = data.messages[topic]
    last = last_component(topic)
    names = data.cart_names
    if data.topics.get(last) == topic:
        if last == "hitch_poses":
            header = [f"A{k + 1}_{name}_{q}" for k, name in enumerate(names) for q in ("x_m", "y_m", "heading_rad")]
            rows = [[t] + [v for p in m.poses for v in (p.position.x, p.position.y, quaternion_yaw(p.orientation))]
                    for t, m in msgs]
            return ["time_s"] + header, rows
        if last == "cart_velocities":
            header = [f"{name}_{q}" for name in names for q in ("com_speed_mps", "heading_rad", "resistance_N")]
            rows = []
            for t, m in msgs:
                by = {nm: (v, p, e) for nm, v, p, e in
                      zip(m.name, m.velocity, m.position, list(m.effort) or [""] * len(m.name))}
                rows.append([t] + [x for name in names for x in by.get(name, ("", "", ""))])
            return ["time_s"] + header, rows
        column = {"traction_power": "power_W", "steering_angle": "steering_command_rad",
                  "applied_steering": "applied_steering_rad", "speed_setpoint": "speed_setpoint_mps"}.get(last)
        if column:
            return ["time_s", column], [[t, m.data] for t, m in msgs]
        if last == "clock":
            return ["time_s", "clock_sec", "clock_nanosec"], [[t, m.clock.sec, m.clock.nanosec] for t, m in msgs]
    flat = [(t, dict(_flatten(m))) for t, m in msgs]
    columns: dict[str, None] = {}
    for _, f in flat:
        columns.update(dict.fromkeys(f))
    return ["time_s", *columns], [[t] + [f.get(c, "") for c in columns] for t, f in flat]


def csv_name(topic: str) -> str:
    """File name of a topic's CSV: the name without the leading '/', '/' -> '__'."""
    return topic.strip("/").replace("/", "__") + ".csv"


def csv_paths(data: BagData, folder: str | os.PathLike) -> list[Path]:
    """The CSV files ``write_csv`` writes for ``data`` into ``folder``, one a topic, in order."""
    return [Path(folder) / csv_name(topic) for topic in sorted(data.messages)]


def write_csv(data: BagData, folder: str | os.PathLike) -> list[Path]:
    """One CSV per topic of the bag into ``folder``; returns the files written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for topic, path in zip(sorted(data.messages), csv_paths(data, folder)):
        header, rows = csv_rows(data, topic)
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(header)
            for row in rows:
                w.writerow([_time_s(row[0])] + [_num(x) for x in row[1:]])
        written.append(path)
    return written


def read_csv(path: str | os.PathLike) -> tuple[list[str], list[list[str]]]:
    """Header and rows (as text) of a CSV written by :func:`write_csv`."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]
