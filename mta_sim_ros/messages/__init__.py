"""The simulator's messages as CDR bytes, ROS-free: what the node publishes and every bag records.

* :mod:`.outputs`: :class:`OutputEncoder` (the five output topics) and :class:`CommandEncoder`
  (the two commands), from an Outputs sample, per tick;
* :mod:`.markers`: :class:`TrainMarkers`, the drawing of the train (visualization_msgs/MarkerArray);
* :mod:`.diagnostics`: :func:`encode_diagnostics`, the DiagnosticArray of /diagnostics;
* :mod:`.frames`: :class:`FrameEncoder`, the train's frames and model for ROS tools (/tf,
  /tf_static, joint_states, odom, robot_description), per tick and latched.

All of it goes through one serializer, :mod:`mta_sim_ros.bag.cdr`; only numpy and the standard
library besides, so ``mta run`` works without a ROS install and writes the node's bytes.
"""
from .diagnostics import DIAGNOSTICS_TYPE, HARDWARE_ID, diagnostic_array, encode_diagnostics, format_value
from .encoders import CommandEncoder, OutputEncoder, float64_template
from .frames import FrameEncoder, poses_frame
from .markers import MARKERS_TYPE, TrainMarkers, cart_color, train_markers


class Encoders:
    """Every message a node run sends, as ``node.run_session.RunSession`` asks for them: the output,
    marker and frame encoders (built at start and when frame_id changes), the diagnostics and
    Float64."""

    outputs = staticmethod(OutputEncoder)
    markers = staticmethod(TrainMarkers)
    frames = staticmethod(FrameEncoder)
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
    "FrameEncoder",
    "OutputEncoder",
    "TrainMarkers",
    "cart_color",
    "diagnostic_array",
    "encode_diagnostics",
    "format_value",
    "poses_frame",
    "train_markers",
]
