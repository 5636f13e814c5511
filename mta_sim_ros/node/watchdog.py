"""The steering command watchdog: who decides the steering, the latest command or the watchdog
once that command is stale. No ROS here.

A command older than ``timeout`` wall seconds (strictly; 0 = never stale) is stale. With action
``hold`` the stale command goes on being held (only /diagnostics says so); with ``straight`` the
watchdog takes over and steers 0 until a new command arrives. The run session records each change
of who decides (topics.WATCHDOG_TOPIC), so ``mta replay --resimulate`` holds what the node held.
"""
from __future__ import annotations

from .commands import CommandInput


class SteeringWatchdog:
    def __init__(self, steering: CommandInput, timeout: float, action: str):
        self.steering, self.timeout, self.action = steering, timeout, action
        self.straight = False  # steering 0 held in place of a stale command

    def stale(self) -> bool:
        """The latest steering command is older than the timeout."""
        return self.timeout > 0 and self.steering.age() > self.timeout

    def update(self) -> bool:
        """Decide for the coming tick; True when who decides has changed since the last call."""
        straight = self.action == "straight" and self.stale()
        changed = straight != self.straight
        self.straight = straight
        return changed

    @property
    def command(self) -> float:
        """The steering to hold: 0 while the watchdog steers straight, else the latest command."""
        return 0.0 if self.straight else self.steering.value

    def forget(self) -> None:
        """Back to 'the command decides' without a change (a new run: its bag records a take-over
        that still holds at its first tick)."""
        self.straight = False
