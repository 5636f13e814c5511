"""Why an example controller stops before its goal: the simulator it steers halted.

The node stops its model on an error (its jackknife guard, the model's validity, the integrator:
node/run_session.py) and stays stopped until a reset; it then publishes no more poses, so a
controller waiting for its goal would wait for ever. Every example controller node (mta reverse,
mta follow) therefore listens to /diagnostics: a status named ``<node>: simulation`` at ERROR is
the node's halt (node/status.py), and its message the reason. The controller then ends, reports
what it measured up to there, and exits 1.
"""
from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node

#: the suffix of the node's /diagnostics status name (run_session.publish_diagnostics)
SIMULATION_STATUS = ": simulation"


class HaltWatch:
    """``reason``: "" while the simulator runs, else why it halted (the first ERROR heard)."""

    def __init__(self, node: Node):
        self.reason = ""
        node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, 10)

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name.endswith(SIMULATION_STATUS) and status.level == DiagnosticStatus.ERROR and not self.reason:
                self.reason = f"the simulator halted: {status.message}"

    def report(self, logger, figures: dict, summary: str) -> tuple[dict, int]:
        """(the figures with ``stopped``: the halt's reason or None, the exit code: 1 if halted) of
        a controller that ends, its ``summary`` logged (an error line after a halt)."""
        if self.reason:
            logger.error(f"{self.reason}; until then: {summary}")
        else:
            logger.info(summary)
        return {**figures, "stopped": self.reason or None}, 1 if self.reason else 0
