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

On a height grid (``train.relief``) the model's x, y are horizontal world coordinates, odom is
world-aligned (frame_id -> odom the identity) and the poses are 3D: each cart stands on the surface
at its rear axle centre B_k with the rotation (world from body) :func:`surface_rotation` of its
heading and the gradient there (body x along the ground over the heading, z the surface's normal).
odom and /tf odom -> base_link carry B_1's height and the tractor's full rotation; with
``cart_frames`` each hitch joint carries the relative rotation R_{k-1}^T R_k of the two carts (its
translation along the cart in front's x axis as on the level). robot_state_publisher can only turn
the URDF's hitch joints about z, so with ``cart_frames`` = False the towed carts are shown in the
tractor's tilt. A point off the grid is read at its nearest point on the grid's edge
(:func:`surface_at`). The templates get the extra slots (heights, the quaternions' x and y) only on
a height grid: on the level and on a plane the bytes are those of the planar messages.
"""
from __future__ import annotations

import math

import numpy as np

from ..bag.cdr import Slot, encode
from ..bag.template import TIME_SLOTS, CdrTemplate
from ..bag.writer import stamp, stamp_parts
from ..physics.terrain import PlaneFrame, Surface, quaternion_of

TF_TYPE = "tf2_msgs/msg/TFMessage"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
ODOMETRY_TYPE = "nav_msgs/msg/Odometry"
STRING_TYPE = "std_msgs/msg/String"

IDENTITY = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}


def poses_frame(robot, frame_id: str, plane) -> str:
    """The frame hitch_poses and the markers are stamped in: frame_id, or on a terrain odom, the
    plane's frame (the module docstring)."""
    return robot.odom if plane is not None else frame_id


def surface_at(relief, x: float, y: float) -> Surface:
    """The height grid's surface at (x, y), the point first moved onto the grid (its nearest
    point on the grid's edge: a hitch or an axle may reach past it while the centres of mass,
    which the run checks, are on it)."""
    xs, ys = relief.xs, relief.ys
    return relief.at(min(max(float(x), xs[0]), xs[-1]), min(max(float(y), ys[0]), ys[-1]))


def surface_rotation(heading: float, surface: Surface) -> np.ndarray:
    """The 3 x 3 rotation (world from body) of a cart of horizontal heading ``heading`` on a
    surface of gradient G = (gx, gy): body x = (cos th, sin th, G . e) normalised, body z =
    (-gx, -gy, 1) / sqrt(1 + |G|^2), body y = z cross x."""
    gx, gy = surface.dzdx, surface.dzdy
    c, s = math.cos(heading), math.sin(heading)
    along = gx * c + gy * s
    u, w = math.sqrt(1.0 + along * along), math.sqrt(1.0 + gx * gx + gy * gy)
    x = (c / u, s / u, along / u)
    z = (-gx / w, -gy / w, 1.0 / w)
    y = (z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0])
    return np.array([x, y, z]).T


def cart_rotations(relief, out) -> list[np.ndarray]:
    """Each cart's rotation on the height grid at its rear axle centre B_k (``out.axle``)."""
    return [surface_rotation(th, surface_at(relief, bx, by))
            for (bx, by), th in zip(out.axle.tolist(), out.heading.tolist())]


def surface_poses(relief, out) -> list[tuple[float, ...]]:
    """(x, y, z, qx, qy, qz, qw) of every hitch pose on a height grid: A_k (``out.front``) at the
    surface's height there, the cart's rotation on the surface at B_k (``cart_rotations``)."""
    poses = []
    for (ax, ay), rotation in zip(out.front.tolist(), cart_rotations(relief, out)):
        poses.append((ax, ay, surface_at(relief, ax, ay).z, *quaternion_of(rotation)))
    return poses


def tilt(time, parent: str, child: str, plane) -> dict:
    """The TransformStamped parent -> child of a plane's frame (terrain.PlaneFrame) in the world."""
    frame = PlaneFrame.of(plane)
    R = np.array([frame.x, frame.y, frame.z]).T
    qx, qy, qz, qw = quaternion_of(R)
    return {"header": {"stamp": time, "frame_id": parent}, "child_frame_id": child,
            "transform": {"translation": {"x": 0.0, "y": 0.0, "z": frame.z0},
                          "rotation": {"x": qx, "y": qy, "z": qz, "w": qw}}}


def transform(time, parent: str, child: str, x=0.0, y=0.0, qz=0.0, qw=1.0, z=0.0, qx=0.0, qy=0.0) -> dict:
    """A geometry_msgs/TransformStamped: translation (x, y, z), rotation (qx, qy, qz, qw); numbers
    or Slots. With the defaults a transform in the plane: a turn about z."""
    return {"header": {"stamp": time, "frame_id": parent}, "child_frame_id": child,
            "transform": {"translation": {"x": x, "y": y, "z": z},
                          "rotation": {"x": qx, "y": qy, "z": qz, "w": qw}}}


class FrameEncoder:
    """The frames' messages of one robot model (module docstring): ``encode(out)`` per tick
    (/tf, joint_states, odom), ``latched(t)`` (/tf_static stamped t, robot_description)."""

    def __init__(self, robot, frame_id: str = "map", cart_frames: bool = True, plane=None, relief=None):
        """``robot``: a urdf.Robot; ``frame_id``: the frame of hitch_poses; ``cart_frames``:
        publish the joints' frames too (False: robot_state_publisher does); ``plane``: the train's
        terrain (None: level); ``relief``: the train's height grid (None: none; the poses are 3D)."""
        self.robot, self.frame_id, self.cart_frames, self.plane = robot, frame_id, cart_frames, plane
        self.relief = relief
        self.n = n = len(robot.carts)
        self.tf = CdrTemplate(TF_TYPE, {"transforms": self._moving()})
        joint = [Slot("joint", i) for i in range(2 * n)]
        self.joints = CdrTemplate(JOINT_STATE_TYPE, {
            "header": {"stamp": TIME_SLOTS, "frame_id": ""}, "name": robot.joint_names,
            "position": joint[:n], "velocity": joint[n:], "effort": []})
        self.joint_values = np.zeros(2 * n)
        odom = [Slot("odom", i) for i in range(9 if relief is not None else 6)]  # x, y, qz, qw, vx, wz[, z, qx, qy]
        z, qx, qy = odom[6:] if relief is not None else (0.0, 0.0, 0.0)
        self.odom = CdrTemplate(ODOMETRY_TYPE, {
            "header": {"stamp": TIME_SLOTS, "frame_id": robot.odom}, "child_frame_id": robot.base,
            "pose": {"pose": {"position": {"x": odom[0], "y": odom[1], "z": z},
                              "orientation": {"x": qx, "y": qy, "z": odom[2], "w": odom[3]}}},
            "twist": {"twist": {"linear": {"x": odom[4], "y": 0.0, "z": 0.0},
                                "angular": {"x": 0.0, "y": 0.0, "z": odom[5]}}}})
        self.odom_values = np.zeros(len(odom))
        self.description = encode(STRING_TYPE, {"data": robot.urdf})

    def _moving(self) -> list[dict]:
        """The transforms of /tf with Slots: on the level and a plane a turn about z each (group q:
        z, w per transform), on a height grid full quaternions (q: x, y, z, w per transform) and
        base_link's height (group z)."""
        robot, n = self.robot, self.n
        joints = [robot.steering_joint, *robot.hitch_joints] if self.cart_frames else []
        if self.relief is None:
            q = [Slot("q", i) for i in range(2 * (n + 1))]  # z, w of: base_link, the steering, each hitch
            self.q_values = np.zeros(len(q) if self.cart_frames else 2)
            return [transform(TIME_SLOTS, robot.odom, robot.base, Slot("xy", 0), Slot("xy", 1), q[0], q[1]),
                    *(transform(TIME_SLOTS, j.parent, j.child, j.x, 0.0, q[2 + 2 * i], q[3 + 2 * i])
                      for i, j in enumerate(joints))]
        q = [Slot("q", i) for i in range(4 * (n + 1))]  # x, y, z, w of: base_link, the steering, each hitch
        self.q_values = np.zeros(len(q) if self.cart_frames else 4)
        return [transform(TIME_SLOTS, robot.odom, robot.base, Slot("xy", 0), Slot("xy", 1), q[2], q[3],
                          Slot("z"), q[0], q[1]),
                *(transform(TIME_SLOTS, j.parent, j.child, j.x, 0.0, q[6 + 4 * i], q[7 + 4 * i],
                            qx=q[4 + 4 * i], qy=q[5 + 4 * i]) for i, j in enumerate(joints))]

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
        hitch, rate = out.hitch_angle, out.yaw_rate
        psi = float(out.steering)
        bx, by = out.axle[0].tolist()
        o = self.odom_values
        o[0], o[1], o[4], o[5] = bx, by, float(out.axle_speed[0]), float(rate[0])
        if self.relief is None:
            tf = self._planar(out, hitch, psi, bx, by, sec, nanosec)
        else:
            tf = self._spatial(out, psi, bx, by, sec, nanosec)
        v = self.joint_values
        v[:n - 1] = hitch
        v[n - 1] = psi
        v[n:2 * n - 1] = rate[:-1] - rate[1:]  # d/dt (th_{k-1} - th_k)
        v[2 * n - 1] = out.steering_rate
        return {
            "/tf": tf,
            "joint_states": self.joints.fill(joint=v, sec=sec, nanosec=nanosec),
            "odom": self.odom.fill(odom=o, sec=sec, nanosec=nanosec),
        }

    def _planar(self, out, hitch, psi: float, bx: float, by: float, sec: int, nanosec: int) -> bytes:
        """/tf on the level or a plane (turns about z); odom's quaternion into ``odom_values``."""
        th1 = float(out.heading[0])
        q = self.q_values
        q[0], q[1] = math.sin(th1 / 2.0), math.cos(th1 / 2.0)
        self.odom_values[2:4] = q[:2]
        if self.cart_frames:
            q[2], q[3] = math.sin(psi / 2.0), math.cos(psi / 2.0)
            half = hitch * -0.5  # a hitch turns about -z: by -phi about z
            np.sin(half, out=q[4::2])
            np.cos(half, out=q[5::2])
        return self.tf.fill(xy=(bx, by), q=q, sec=sec, nanosec=nanosec)

    def _spatial(self, out, psi: float, bx: float, by: float, sec: int, nanosec: int) -> bytes:
        """/tf on a height grid (module docstring); odom's height and quaternion into ``odom_values``."""
        q, o = self.q_values, self.odom_values
        ground = surface_at(self.relief, bx, by)
        z = ground.z
        if self.cart_frames:
            rotations = cart_rotations(self.relief, out)
            q[4:8] = (0.0, 0.0, math.sin(psi / 2.0), math.cos(psi / 2.0))
            for k in range(1, self.n):
                q[4 + 4 * k:8 + 4 * k] = quaternion_of(rotations[k - 1].T @ rotations[k])
        else:
            rotations = [surface_rotation(float(out.heading[0]), ground)]
        q[:4] = quaternion_of(rotations[0])
        o[6], o[7], o[8] = z, q[0], q[1]
        o[2], o[3] = q[2], q[3]
        return self.tf.fill(xy=(bx, by), z=z, q=q, sec=sec, nanosec=nanosec)
