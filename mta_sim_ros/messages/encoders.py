"""CDR bytes of the simulator's topics (``topics.TOPICS``) from an Outputs sample, per tick.

The node publishes and records these bytes; the offline run records the same objects' bytes, so
a bag of either holds the same encoding. Each message is a :class:`~mta_sim_ros.bag.template.
CdrTemplate` built once for the train (its cart names and frame fix the message's shape) and
filled with the sample's numbers: the bytes equal ``bag.cdr.encode`` of the plain dicts of
:func:`mta_sim_ros.messages.topics.output_messages` / :func:`~mta_sim_ros.messages.topics.command_messages`
(``test/test_messages.py`` compares them byte for byte and decodes them with rclpy and rosbags).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..bag.cdr import Slot
from ..bag.template import TIME_SLOTS, CdrTemplate
from ..bag.writer import stamp_parts
from .frames import surface_poses
from .topics import TOPICS

FLOAT64_TYPE = "std_msgs/msg/Float64"


def float64_template() -> CdrTemplate:
    """std_msgs/Float64 with its one number as the group "data"."""
    return CdrTemplate(FLOAT64_TYPE, {"data": Slot("data")})


class OutputEncoder:
    """The published topics of one Outputs sample as CDR bytes: hitch_poses, cart_velocities,
    traction_power, applied_steering and /clock, with the values of ``topics.output_messages``
    (on a height grid hitch_poses are 3D: ``__init__``)."""

    def __init__(self, cart_names: Sequence[str], frame_id: str = "map", relief=None):
        """``relief``: the train's height grid (terrain.HeightGrid), or None: then every pose lies
        in z = 0 and turns about z; on a grid each pose's z is the surface's height at A_k and its
        orientation the cart's on the surface at its axle B_k (frames.surface_rotation: the
        template gets slots for z and the quaternion's x, y only then)."""
        self.n, self.frame_id, self.relief = len(cart_names), frame_id, relief
        n = self.n
        if relief is None:
            poses = [{"position": {"x": Slot("pose", 4 * k), "y": Slot("pose", 4 * k + 1), "z": 0.0},
                      "orientation": {"x": 0.0, "y": 0.0, "z": Slot("pose", 4 * k + 2),
                                      "w": Slot("pose", 4 * k + 3)}}
                     for k in range(n)]
        else:  # x, y, z, then the quaternion's x, y, z, w
            poses = [{"position": {axis: Slot("pose", 7 * k + i) for i, axis in enumerate("xyz")},
                      "orientation": {axis: Slot("pose", 7 * k + 3 + i) for i, axis in enumerate("xyzw")}}
                     for k in range(n)]
        self.poses = CdrTemplate(TOPICS["hitch_poses"],
                                 {"header": {"stamp": TIME_SLOTS, "frame_id": frame_id}, "poses": poses})
        joint = [Slot("joint", i) for i in range(3 * n)]
        self.joints = CdrTemplate(TOPICS["cart_velocities"], {
            "header": {"stamp": TIME_SLOTS, "frame_id": ""}, "name": [str(c) for c in cart_names],
            "position": joint[:n], "velocity": joint[n:2 * n], "effort": joint[2 * n:]})
        self.scalar = float64_template()
        self.clock = CdrTemplate(TOPICS["/clock"], {"clock": TIME_SLOTS})
        self.pose_values = np.zeros((n, 4 if relief is None else 7))

    def encode(self, out) -> dict[str, bytes]:
        """topic -> CDR bytes, the topics and values of ``topics.output_messages(out, ...)``.

        Raises:
            ValueError: the sample has another number of carts than the encoder's names.
        """
        if len(out.heading) != self.n:
            raise ValueError(f"OutputEncoder: {self.n} cart names for {len(out.heading)} carts")
        sec, nanosec = stamp_parts(out.t)
        v = self.pose_values
        v[:, :2] = out.front
        if self.relief is None:
            for k, th in enumerate(out.heading.tolist()):  # bag.writer.yaw_quaternion's math, bit for bit
                v[k, 2], v[k, 3] = math.sin(th / 2.0), math.cos(th / 2.0)
        else:
            v[:] = surface_poses(self.relief, out)
        return {
            "hitch_poses": self.poses.fill(pose=v.ravel(), sec=sec, nanosec=nanosec),
            "cart_velocities": self.joints.fill(joint=np.concatenate((out.heading, out.com_speed, out.resistance)),
                                                sec=sec, nanosec=nanosec),
            "traction_power": self.scalar.fill(data=out.power),
            "applied_steering": self.scalar.fill(data=out.steering),
            "/clock": self.clock.fill(sec=sec, nanosec=nanosec),
        }


class CommandEncoder:
    """The inputs held over the tick that produced a sample (steering_angle, speed_setpoint) as
    CDR bytes, with the values of ``topics.command_messages``."""

    def __init__(self):
        self.scalar = float64_template()

    def encode(self, out) -> dict[str, bytes]:
        return {"steering_angle": self.scalar.fill(data=out.command),
                "speed_setpoint": self.scalar.fill(data=out.speed_setpoint)}
