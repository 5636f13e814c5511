"""What /diagnostics says about a run, as plain data: a level, a message and named values.
No ROS here: an encoder (session.Encoders.diagnostics) makes the DiagnosticArray of it."""
from __future__ import annotations

from dataclasses import dataclass

#: diagnostic_msgs/DiagnosticStatus levels.
OK, WARN, ERROR = 0, 1, 2


@dataclass(frozen=True)
class Status:
    level: int
    message: str
    values: dict


def status(halted: str, problems: list[str], values: dict) -> Status:
    """ERROR while the model is halted (until a reset), else WARN while anything is wrong, else
    OK; the message lists what is wrong, the halt first ('running' when nothing is)."""
    problems = [p for p in (halted, *problems) if p]
    level = ERROR if halted else WARN if problems else OK
    return Status(level, "; ".join(problems) or "running", values)
