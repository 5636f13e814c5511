"""What a run publishes, as CDR bytes: each tick's outputs and frames, the train's markers every
few ticks, the latched topics. No ROS here: the bytes are made by injected :class:`Encoders`
(``messages.Encoders`` by default, the one encoder the offline run uses too), and the same bytes
go to DDS and to the bag.
"""
from __future__ import annotations

from typing import Mapping, Protocol, Sequence

from ..messages.frames import poses_frame


class OutputsEncoder(Protocol):
    def encode(self, out) -> dict[str, bytes]:
        """topic -> CDR bytes of the published outputs (topics.TOPICS but the commands) of one
        sim.Outputs; the dict is handed to the bag writer as it is: a new one each call."""


class MarkersEncoder(Protocol):
    def encode(self, out) -> bytes:
        """CDR bytes of the visualization_msgs/MarkerArray of the train at out.t."""


class FramesEncoder(Protocol):
    def encode(self, out) -> dict[str, bytes]:
        """topic -> CDR bytes of the per-tick frames (/tf, joint_states, odom) of one sim.Outputs."""

    def latched(self, t: float) -> dict[str, bytes]:
        """topic -> CDR bytes of the latched topics (/tf_static stamped t, robot_description)."""


class Encoders(Protocol):
    """The seam between the session and a CDR encoding. Frame-dependent encoders are made at start
    and again when frame_id changes, never per tick."""

    def outputs(self, cart_names: Sequence[str], frame_id: str, relief=None) -> OutputsEncoder:
        """``relief``: the train's height grid (hitch_poses are 3D on it), or None."""

    def markers(self, train, frame_id: str) -> MarkersEncoder:
        """The drawing of ``train`` (on its plane or height grid, if any)."""

    def frames(self, robot, frame_id: str, cart_frames: bool, plane=None, relief=None) -> FramesEncoder:
        """The frames of ``robot`` (urdf.Robot); ``cart_frames``: its joints' frames too; ``plane``:
        the train's terrain (frames.py: frame_id -> odom carries its tilt); ``relief``: its height
        grid (frames.py: the poses are 3D)."""

    def diagnostics(self, t: float, name: str, level: int, message: str,
                    values: Mapping[str, object]) -> bytes:
        """A diagnostic_msgs/DiagnosticArray stamped t with one status (status.Status)."""

    def float64(self, x: float) -> bytes:
        """A std_msgs/Float64 (commands and watchdog take-overs, as recorded)."""


class TickMessages:
    """The messages of a run of ``scene``'s train, its frames those of ``robot`` (urdf.Robot): the
    markers every ``marker_every`` ticks, the latched topics as last published (``latched``)."""

    def __init__(self, encoders: Encoders, scene, robot, marker_every: int):
        self.enc, self.train, self.robot, self.marker_every = encoders, scene.train, robot, marker_every
        self.cart_names = [c.name for c in scene.train.carts]
        self.ticks_since_markers = 0
        self.latched: dict[str, bytes] = {}  # what the latched topics last published (urdf, /tf_static)

    def make(self, frame_id: str, cart_frames: bool) -> None:
        """The tick's encoders for ``frame_id`` (at start and when it changes); on a terrain the
        poses and markers are in the plane's frame, odom (frames.poses_frame); on a height grid
        (``train.relief``) in frame_id, 3D. The relief is passed only when there is one, so an
        Encoders written before height grids still serves the level and the plane."""
        plane, relief = self.train.terrain, getattr(self.train, "relief", None)
        grid = {"relief": relief} if relief is not None else {}
        poses = poses_frame(self.robot, frame_id, plane)
        self.outputs = self.enc.outputs(self.cart_names, poses, **grid)
        self.markers = self.enc.markers(self.train, poses)
        self.frames = self.enc.frames(self.robot, frame_id, cart_frames, plane, **grid)

    def of_tick(self, out) -> dict[str, bytes]:
        """topic -> CDR bytes of one tick's outputs and frames (/tf, joint_states, odom)."""
        msgs = self.outputs.encode(out)
        msgs.update(self.frames.encode(out))
        return msgs

    def add_markers(self, msgs: dict[str, bytes], out) -> None:
        """The markers into ``msgs`` if this tick is one that draws them."""
        self.ticks_since_markers += 1
        if self.ticks_since_markers >= self.marker_every:
            self.ticks_since_markers = 0
            msgs["markers"] = self.markers.encode(out)

    def latch(self, topics: Sequence[str], t: float) -> dict[str, bytes]:
        """topic -> CDR bytes of these latched topics (topics.LATCHED_TOPICS) as they are now,
        stamped ``t``: kept in ``latched``."""
        msgs = {topic: b for topic, b in self.frames.latched(t).items() if topic in topics}
        self.latched.update(msgs)
        return msgs
