"""The train's frames for ROS tools (REP-105): /tf, /tf_static, joint_states, odom and
robot_description as CDR bytes, from an Outputs sample, ROS-free.

:class:`FrameEncoder` is built once for a robot model (``urdf.Robot``: its frame and joint names)
and the frame of hitch_poses, and filled per tick from templates like the other outputs:

* ``/tf`` (tf2_msgs/TFMessage), every tick: ``<prefix>odom -> <prefix>base_link`` (B_1, th_1:
  ground truth), and with ``cart_frames`` the movable joints: the steering (tractor ->
  front_wheels, psi_1 about z) and each hitch (cart k-1 -> cart k's hitch, the hitch angle about
  -z);
* ``/tf_static`` (tf2_msgs/TFMessage, latched): ``frame_id -> <prefix>odom``, the identity (the
  simulator's odometry is ground truth: odom and the frame of hitch_poses coincide), unless
  frame_id is the odom frame. On a terrain (a tilted plane) odom is the plane's own frame (x, y
  along the ground, z its normal: the model's coordinates), this transform its tilt in the world
  (terrain.PlaneFrame), and hitch_poses and the markers are stamped in odom (``poses_frame``):
  every pose is then a 3D pose in frame_id through tf, and the controllers reading hitch_poses keep
  the model's coordinates; with ``cart_frames`` the fixed joints (base_link -> tractor,
  each cart's hitch -> its body at B_k);
* ``joint_states`` (sensor_msgs/JointState), every tick: the hitch joints' positions (hitch
  angles th_{k-1} - th_k) and rates, then the steering joint's psi_1 and its rate (the actuator's
  psi_1' under the held command and rate limit, Outputs.steering_rate); no efforts;
* ``odom`` (nav_msgs/Odometry), every tick: frame ``<prefix>odom``, child ``<prefix>base_link``;
  the pose of B_1 with th_1, the twist in the child frame (REP-105): linear.x = s'_B1, the speed of
  the rear axle along the tractor's axis, angular.z = th'_1; linear.y = 0 (no side slip at B_1 on
  the kinematic and dynamic levels; on the slip level the tractor's side slip is not reported);
  every covariance 0 (ground truth);
* ``robot_description`` (std_msgs/String, latched): the URDF.

``cart_frames`` = False leaves the joints' frames to robot_state_publisher (which reads
robot_description and joint_states), so they are not published twice.
"""
from __future__ import annotations

import math

import numpy as np

from ..bag.cdr import Slot, encode
from ..bag.template import TIME_SLOTS, CdrTemplate
from ..bag.writer import stamp, stamp_parts
from ..physics.terrain import PlaneFrame, quaternion_of

TF_TYPE = "tf2_msgs/msg/TFMessage"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
ODOMETRY_TYPE = "nav_msgs/msg/Odometry"
STRING_TYPE = "std_msgs/msg/String"

IDENTITY = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}


def poses_frame(robot, frame_id: str, plane) -> str:
    """The frame hitch_poses and the markers are stamped in: frame_id, or on a terrain odom, the
    plane's frame (the module docstring)."""
    return robot.odom if plane is not None else frame_id


def tilt(time, parent: str, child: str, plane) -> dict:
    """The TransformStamped parent -> child of a plane's frame (terrain.PlaneFrame) in the world."""
    frame = PlaneFrame.of(plane)
    R = np.array([frame.x, frame.y, frame.z]).T
    qx, qy, qz, qw = quaternion_of(R)
    return {"header": {"stamp": time, "frame_id": parent}, "child_frame_id": child,
            "transform": {"translation": {"x": 0.0, "y": 0.0, "z": frame.z0},
                          "rotation": {"x": qx, "y": qy, "z": qz, "w": qw}}}


def transform(time, parent: str, child: str, x=0.0, y=0.0, qz=0.0, qw=1.0) -> dict:
    """A geometry_msgs/TransformStamped in the plane: translation (x, y, 0), a turn about z whose
    quaternion is (0, 0, qz, qw); numbers or Slots."""
    return {"header": {"stamp": time, "frame_id": parent}, "child_frame_id": child,
            "transform": {"translation": {"x": x, "y": y, "z": 0.0},
                          "rotation": {"x": 0.0, "y": 0.0, "z": qz, "w": qw}}}


class FrameEncoder:
    """The frames' messages of one robot model (module docstring): ``encode(out)`` per tick
    (/tf, joint_states, odom), ``latched(t)`` (/tf_static stamped t, robot_description)."""

    def __init__(self, robot, frame_id: str = "map", cart_frames: bool = True, plane=None):
        """``robot``: a urdf.Robot; ``frame_id``: the frame of hitch_poses; ``cart_frames``:
        publish the joints' frames too (False: robot_state_publisher does); ``plane``: the train's
        terrain (None: level)."""
        self.robot, self.frame_id, self.cart_frames, self.plane = robot, frame_id, cart_frames, plane
        self.n = n = len(robot.carts)
        q = [Slot("q", i) for i in range(2 * (n + 1))]  # z, w of: base_link, the steering, each hitch
        moving = [transform(TIME_SLOTS, robot.odom, robot.base, Slot("xy", 0), Slot("xy", 1), q[0], q[1])]
        if cart_frames:
            joints = [robot.steering_joint, *robot.hitch_joints]
            moving += [transform(TIME_SLOTS, j.parent, j.child, j.x, 0.0, q[2 + 2 * i], q[3 + 2 * i])
                       for i, j in enumerate(joints)]
        self.tf = CdrTemplate(TF_TYPE, {"transforms": moving})
        self.q_values = np.zeros(len(q) if cart_frames else 2)
        joint = [Slot("joint", i) for i in range(2 * n)]
        self.joints = CdrTemplate(JOINT_STATE_TYPE, {
            "header": {"stamp": TIME_SLOTS, "frame_id": ""}, "name": robot.joint_names,
            "position": joint[:n], "velocity": joint[n:], "effort": []})
        self.joint_values = np.zeros(2 * n)
        odom = [Slot("odom", i) for i in range(6)]  # x, y, qz, qw, vx, wz
        self.odom = CdrTemplate(ODOMETRY_TYPE, {
            "header": {"stamp": TIME_SLOTS, "frame_id": robot.odom}, "child_frame_id": robot.base,
            "pose": {"pose": {"position": {"x": odom[0], "y": odom[1], "z": 0.0},
                              "orientation": {"x": 0.0, "y": 0.0, "z": odom[2], "w": odom[3]}}},
            "twist": {"twist": {"linear": {"x": odom[4], "y": 0.0, "z": 0.0},
                                "angular": {"x": 0.0, "y": 0.0, "z": odom[5]}}}})
        self.description = encode(STRING_TYPE, {"data": robot.urdf})

    def static_transforms(self, t: float) -> dict:
        """The TFMessage of /tf_static (module docstring) as plain dicts, stamped t."""
        robot, time = self.robot, stamp(t)
        fixed = []
        if self.frame_id != robot.odom:
            fixed.append(transform(time, self.frame_id, robot.odom) if self.plane is None
                         else tilt(time, self.frame_id, robot.odom, self.plane))
        if self.cart_frames:
            fixed += [transform(time, j.parent, j.child, j.x) for j in robot.fixed_joints]
        return {"transforms": fixed}

    def latched(self, t: float) -> dict[str, bytes]:
        """topic -> CDR bytes of the latched topics: /tf_static stamped t and robot_description."""
        return {"/tf_static": encode(TF_TYPE, self.static_transforms(t)), "robot_description": self.description}

    def encode(self, out) -> dict[str, bytes]:
        """topic -> CDR bytes of /tf, joint_states and odom at ``out`` (module docstring).

        Raises:
            ValueError: the sample has another number of carts than the robot.
        """
        n = self.n
        if len(out.heading) != n:
            raise ValueError(f"FrameEncoder: {n} carts in the robot model, {len(out.heading)} in the outputs")
        sec, nanosec = stamp_parts(out.t)
        hitch = out.hitch_angle
        th1, psi = float(out.heading[0]), float(out.steering)
        bx, by = out.axle[0].tolist()
        qz, qw = math.sin(th1 / 2.0), math.cos(th1 / 2.0)
        q = self.q_values
        q[0], q[1] = qz, qw
        if self.cart_frames:
            q[2], q[3] = math.sin(psi / 2.0), math.cos(psi / 2.0)
            half = hitch * -0.5  # a hitch turns about -z: by -phi about z
            np.sin(half, out=q[4::2])
            np.cos(half, out=q[5::2])
        v = self.joint_values
        v[:n - 1] = hitch
        v[n - 1] = psi
        rate = out.yaw_rate
        v[n:2 * n - 1] = rate[:-1] - rate[1:]  # d/dt (th_{k-1} - th_k)
        v[2 * n - 1] = out.steering_rate
        return {
            "/tf": self.tf.fill(xy=(bx, by), q=q, sec=sec, nanosec=nanosec),
            "joint_states": self.joints.fill(joint=v, sec=sec, nanosec=nanosec),
            "odom": self.odom.fill(odom=(bx, by, qz, qw, float(out.axle_speed[0]), float(rate[0])),
                                   sec=sec, nanosec=nanosec),
        }
