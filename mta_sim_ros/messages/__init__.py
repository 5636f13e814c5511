"""The simulator's messages as CDR bytes, ROS-free: what the node publishes and every bag records.

* :mod:`.outputs`: :class:`OutputEncoder` (the five output topics) and :class:`CommandEncoder`
  (the two commands), from an Outputs sample, per tick;
* :mod:`.markers`: :class:`TrainMarkers`, the drawing of the train (visualization_msgs/MarkerArray);
* :mod:`.diagnostics`: :func:`encode_diagnostics`, the DiagnosticArray of /diagnostics.

All of it goes through one serializer, :mod:`mta_sim_ros.bag.cdr`; only numpy and the standard
library besides, so ``mta run`` works without a ROS install and writes the node's bytes.
"""
from .diagnostics import DIAGNOSTICS_TYPE, HARDWARE_ID, diagnostic_array, encode_diagnostics, format_value
from .markers import MARKERS_TYPE, TrainMarkers, cart_widths, train_markers
from .outputs import CommandEncoder, OutputEncoder, float64_template


class Encoders:
    """Every message a node run sends, as ``session.RunSession`` asks for them: the output and
    marker encoders (built at start and when frame_id changes), the diagnostics and Float64."""

    outputs = staticmethod(OutputEncoder)
    markers = staticmethod(TrainMarkers)
    diagnostics = staticmethod(encode_diagnostics)

    def __init__(self):
        self._float64 = float64_template()

    def float64(self, x: float) -> bytes:
        return self._float64.fill(data=x)

__all__ = [
    "DIAGNOSTICS_TYPE",
    "HARDWARE_ID",
    "MARKERS_TYPE",
    "CommandEncoder",
    "Encoders",
    "OutputEncoder",
    "TrainMarkers",
    "cart_widths",
    "diagnostic_array",
    "encode_diagnostics",
    "format_value",
    "train_markers",
]
