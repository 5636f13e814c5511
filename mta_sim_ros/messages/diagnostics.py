"""The simulator's health report as a diagnostic_msgs/DiagnosticArray, ROS-free.

One DiagnosticStatus per message (hardware_id :data:`HARDWARE_ID`), its values as KeyValue
strings: what /diagnostics carries at 1 Hz and the run bag records. Plain dicts
(:func:`diagnostic_array`) or CDR bytes (:func:`encode_diagnostics`, through ``bag.cdr``).
"""
from __future__ import annotations

import numbers
from typing import Mapping

from ..bag.cdr import encode
from ..bag.writer import header

DIAGNOSTICS_TYPE = "diagnostic_msgs/msg/DiagnosticArray"

#: hardware_id of every DiagnosticStatus the simulator reports.
HARDWARE_ID = "mta_sim_ros"

#: DiagnosticStatus levels (the message's byte constants OK, WARN, ERROR, STALE).
LEVELS = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}


def level_number(level: int | bytes) -> int:
    """DiagnosticStatus.level as a number 0..3, from an int or from one of rclpy's
    ``DiagnosticStatus.OK/WARN/ERROR/STALE`` constants (bytes of length 1).

    Raises:
        ValueError: anything else.
    """
    if isinstance(level, (bytes, bytearray)):
        if len(level) != 1:
            raise ValueError(f"diagnostic level must be 1 byte, got {level!r}")
        value = level[0]
    else:
        value = int(level)
    if value not in LEVELS:
        raise ValueError(f"diagnostic level must be one of {LEVELS}, got {level!r}")
    return value


def format_value(value: object) -> str:
    """A diagnostic value as text: non-integral numbers with %.6g, everything else with str()."""
    if isinstance(value, numbers.Real) and not isinstance(value, numbers.Integral):
        return f"{float(value):.6g}"
    return str(value)


def diagnostic_array(t: float, name: str, level: int | bytes, message: str,
                     values: Mapping[str, object]) -> dict:
    """diagnostic_msgs/DiagnosticArray stamped ``t`` with one DiagnosticStatus, as plain dicts.

    Args:
        level: 0 OK, 1 WARN, 2 ERROR, 3 STALE, as an int or a ``DiagnosticStatus`` constant.

    Raises:
        ValueError: unknown level.
    """
    status = {"level": level_number(level), "name": name, "message": message, "hardware_id": HARDWARE_ID,
              "values": [{"key": str(k), "value": format_value(v)} for k, v in values.items()]}
    return {"header": header(t, ""), "status": [status]}


def encode_diagnostics(t: float, name: str, level: int | bytes, message: str,
                       values: Mapping[str, object]) -> bytes:
    """The CDR bytes of :func:`diagnostic_array` (same arguments, same errors)."""
    return encode(DIAGNOSTICS_TYPE, diagnostic_array(t, name, level, message, values))
