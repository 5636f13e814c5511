"""The train as a ROS robot model: its frames, joints and URDF (robot_description), ROS-free.

What RViz, Foxglove's 3D panel, robot_state_publisher and nav2 expect of a robot (REP-105 frames,
REP-103 axes), made from the train file alone:

* every frame lies in the ground plane (z = 0), x forward along its cart's axis, z up;
* ``<prefix>base_link``: the tractor's rear axle centre B_1, x along th_1 (REP-105's base frame;
  its odometry is ``<prefix>odom -> <prefix>base_link``). The root of the tree; it has no mass,
  as KDL (robot_state_publisher) wants of a root link;
* ``<prefix><cart>``: each cart's body, origin at its rear axle centre B_k, x along th_k: the box
  and the inertia of the cart. The tractor's is joined to base_link by a fixed joint
  (``<prefix><tractor>_joint``, identity);
* ``<prefix><cart>_hitch`` (k >= 2): the hitch point A_k, x along th_k, joined to the cart in front
  (``<prefix><cart before>``, at x = -a_{k-1}) by the revolute joint ``<prefix><cart>_hitch_joint``
  about -z, so that its position is the project's hitch angle th_{k-1} - th_k (positive when the
  cart trails to the right of the one in front), limited to the cart's max_hitch_angle (the model's
  jackknife limit); the cart's body hangs from it by the fixed joint ``<prefix><cart>_joint`` at
  x = -l_k (A_k to B_k);
* ``<prefix><tractor>_front_wheels``: the steered front axle centre A_1, x along the wheels,
  joined to the tractor at x = l_1 by the revolute joint ``<prefix><tractor>_steering_joint``
  about +z (position psi_1, positive = left), limited to the actuator's max_angle.

The prefix comes from the node's namespace (:func:`frame_prefix`: ``/unit1`` -> ``unit1/``), so
several trains share one tf tree; the URDF's names carry it (run robot_state_publisher with no
frame_prefix of its own).

What the train file lacks is assumed (and said in the URDF's comments):

* a cart's box runs along its axis from A_k back to the rearmost of B_k and its rear hitch A_{k+1}
  (the outline of the markers, ``messages.markers``), as wide as ``outline.cart_widths`` (the
  widest draft width acting on it, else 2.5 m), BOX_HEIGHT high, standing on the ground;
* the centre of mass C_k sits at BOX_HEIGHT / 2 above the ground; izz is the train's yaw
  inertia J_k; ixx and iyy are those of a uniform box of the cart's mass and height whose
  footprint has the drawn box's proportions, scaled so that its yaw inertia is J_k (so the three
  always make a physical inertia: each at most the sum of the other two);
* a passive hitch has no actuator: effort and velocity limits 0; the steering's effort limit is
  0 (unknown), its velocity limit the actuator's max_rate.

Names are refused (one line, InputError) when a frame would not be a name tf2 takes
(validate.FRAME_ID) or two frames or joints would share a name.
"""
from __future__ import annotations

import dataclasses
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass

from ..validate import FRAME_ID, Rule, fail, show
from ..physics.outline import BOX_HEIGHT, box_of, cart_widths
from .markers import cart_color

#: Height of every cart's box, m (a train file gives none).
#: The steered wheels' box: length along the wheels and height (a tyre's diameter), m; it is as
#: wide as the tractor plus WHEEL_WIDTH.
WHEEL_DIAMETER = 1.2
WHEEL_WIDTH = 0.5


#: a ROS namespace as a node takes it (``/``, ``/unit1``, ``fleet/unit1``)
NAMESPACE = Rule("a ROS namespace: names of letters, digits and _ (not starting with a digit) separated by /",
                 lambda v: re.fullmatch(r"/?([A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*)?/?", v) is not None)


def frame_prefix(namespace: str) -> str:
    """The prefix of every frame and joint of a node in ``namespace``: '' in the root namespace,
    ``unit1/`` in ``/unit1``, ``fleet/unit1/`` in ``/fleet/unit1``."""
    name = namespace.strip("/")
    return name + "/" if name else ""


@dataclass(frozen=True)
class Joint:
    """A URDF joint: its child's frame is the parent's moved by ``x`` along the parent's x axis
    (then turned about ``axis_z`` * z by the joint's position, for a revolute joint)."""

    name: str
    kind: str  # "revolute" or "fixed"
    parent: str
    child: str
    x: float  # m, the joint's origin on the parent's x axis
    axis_z: float = 1.0  # +1 or -1: the joint turns about +z or -z
    limit: float = 0.0  # rad, |position| <= limit (revolute)
    velocity: float = 0.0  # rad/s, velocity limit (revolute; 0 = passive)


@dataclass(frozen=True)
class Robot:
    """The frames and joints of a train (module docstring) and its URDF text."""

    prefix: str
    odom: str  # <prefix>odom
    base: str  # <prefix>base_link
    carts: tuple[str, ...]  # <prefix><cart>, cart k's body at B_k
    hitches: tuple[str, ...]  # <prefix><cart>_hitch, A_k for k = 2..n
    front_wheels: str  # <prefix><tractor>_front_wheels, A_1 turned by psi_1
    joints: tuple[Joint, ...]
    hitch_joints: tuple[Joint, ...]  # k = 2..n, in train order
    steering_joint: Joint
    urdf: str

    @property
    def frames(self) -> list[str]:
        """Every frame of the robot, odom first."""
        return [self.odom, self.base, *self.carts, *self.hitches, self.front_wheels]

    def frame_id_rule(self, frame_id: str) -> str:
        """The rule ``frame_id`` (of hitch_poses: the parent of odom in the tf tree) breaks with
        this robot ('' if none): it must not be one of the robot's frames below odom."""
        if frame_id in self.frames[1:]:
            return (f"a frame that is none of the train's own below {self.odom} ({', '.join(self.frames[1:])}): "
                    f"/tf_static joins it to {self.odom}")
        return ""

    @property
    def fixed_joints(self) -> tuple[Joint, ...]:
        return tuple(j for j in self.joints if j.kind == "fixed")

    @property
    def joint_names(self) -> list[str]:
        """The movable joints in the order of joint_states: the hitches, then the steering."""
        return [j.name for j in self.hitch_joints] + [self.steering_joint.name]


def robot_model(train, prefix: str = "") -> Robot:
    """The robot model of ``train`` (model.spec.Train) with every name prefixed by ``prefix``.

    Raises:
        InputError: a frame or joint name tf2 would not take, or one used twice (says which cart).
    """
    carts = train.carts
    tractor = carts[0].name
    p = prefix
    body = tuple(p + c.name for c in carts)
    hitches = tuple(p + c.name + "_hitch" for c in carts[1:])
    wheels = p + tractor + "_front_wheels"
    steering = Joint(p + tractor + "_steering_joint", "revolute", body[0], wheels, carts[0].length, 1.0,
                     train.actuator.max_angle, train.actuator.max_rate)
    joints = [Joint(p + tractor + "_joint", "fixed", p + "base_link", body[0], 0.0), steering]
    hitch_joints = []
    for k in range(1, len(carts)):
        hitch = Joint(p + carts[k].name + "_hitch_joint", "revolute", body[k - 1], hitches[k - 1],
                      -carts[k - 1].hitch_offset, -1.0, carts[k].max_hitch_angle, 0.0)
        hitch_joints.append(hitch)
        joints += [hitch, Joint(p + carts[k].name + "_joint", "fixed", hitches[k - 1], body[k], -carts[k].length)]
    robot = Robot(prefix=p, odom=p + "odom", base=p + "base_link", carts=body, hitches=hitches, front_wheels=wheels,
                  joints=tuple(joints), hitch_joints=tuple(hitch_joints), steering_joint=steering, urdf="")
    _check_names(robot, train)
    return dataclasses.replace(robot, urdf=_urdf(robot, train))


def _check_names(robot: Robot, train) -> None:
    """Every frame a name tf2 takes, every frame and every joint name once."""
    where = train.source or train.name

    def cart_of(name: str) -> int:  # the cart whose name made this one (the longest that fits)
        found = [k for k, c in enumerate(train.carts) if name.startswith(robot.prefix + c.name)]
        return max(found, key=lambda k: len(train.carts[k].name), default=0)

    frames = robot.frames
    for name in frames:
        if not FRAME_ID.test(name):
            k = cart_of(name)
            fail("name", show(train.carts[k].name), f"a name whose frame {show(name)} is {FRAME_ID.text}",
                 f"carts[{k}]", where)
    for kind, names in (("frame", frames), ("joint", [j.name for j in robot.joints])):
        seen = set()
        for name in names:
            if name in seen:
                k = cart_of(name)
                fail("name", show(train.carts[k].name), f"a name that makes no {kind} twice: {show(name)} "
                     f"(a cart may not be named odom or base_link, nor <another cart>_hitch)", f"carts[{k}]", where)
            seen.add(name)


def _num(x: float) -> str:
    """A number as URDF text, exactly (repr: the float reads back bit for bit)."""
    return repr(float(x))


def inertia_of(train, k: int) -> tuple[float, float, float]:
    """(ixx, iyy, izz) of cart k about C_k, kg m^2: izz = J_k, ixx and iyy of a box of the drawn
    box's proportions and height scaled to that yaw inertia (module docstring)."""
    cart = train.carts[k]
    _, length, width, height = box_of(train, k)
    m = cart.mass
    scale = 12.0 * cart.yaw_inertia / (m * (length ** 2 + width ** 2))  # s^2: s^2 m (L^2 + W^2) / 12 = J
    return (m * (scale * width ** 2 + height ** 2) / 12.0, m * (scale * length ** 2 + height ** 2) / 12.0,
            cart.yaw_inertia)


def _geometry(link: ET.Element, tag: str, xyz: tuple, size: tuple, material: str | None = None) -> None:
    part = ET.SubElement(link, tag)
    ET.SubElement(part, "origin", xyz=" ".join(map(_num, xyz)), rpy="0 0 0")
    ET.SubElement(ET.SubElement(part, "geometry"), "box", size=" ".join(map(_num, size)))
    if material:
        ET.SubElement(part, "material", name=material)


def _file_name(source: str | None) -> str:
    """The train file's name, without its folder: the robot model is the same wherever the file
    lies (and says nothing of the machine it was made on)."""
    return os.path.basename(source) if source else "its train file"


def _urdf(robot: Robot, train) -> str:
    root = ET.Element("robot", name=train.name)
    root.append(ET.Comment(_comment_text(
        f" {train.name} from {_file_name(train.source)}, made by mta_sim_ros.urdf. Frames: every one "
        "at z = 0, x forward along its cart's axis; <cart> at its rear axle B_k, <cart>_hitch at its hitch "
        "A_k, base_link = the tractor's rear axle. Assumed (the train file gives none): box height "
        f"{BOX_HEIGHT} m, centre of mass at half of it, ixx and iyy of a uniform box scaled to the train's "
        "yaw inertia izz. Hitch joints turn about -z: their position is the hitch angle th_(k-1) - th_k. ")))
    for k in range(len(train.carts)):
        color = cart_color(k)
        r, g, b, a = color["r"], color["g"], color["b"], color["a"]
        ET.SubElement(ET.SubElement(root, "material", name=f"{robot.prefix}cart_{k}"), "color",
                      rgba=" ".join(map(_num, (r, g, b, a))))
    ET.SubElement(ET.SubElement(root, "material", name=f"{robot.prefix}tyre"), "color", rgba="0.1 0.1 0.1 1.0")
    ET.SubElement(root, "link", name=robot.base)
    for k, cart in enumerate(train.carts):
        link = ET.SubElement(root, "link", name=robot.carts[k])
        centre, length, width, height = box_of(train, k)
        _geometry(link, "visual", (centre, 0.0, height / 2.0), (length, width, height), f"{robot.prefix}cart_{k}")
        _geometry(link, "collision", (centre, 0.0, height / 2.0), (length, width, height))
        inertial = ET.SubElement(link, "inertial")
        ET.SubElement(inertial, "origin", xyz=f"{_num(cart.com_offset)} 0.0 {_num(height / 2.0)}", rpy="0 0 0")
        ET.SubElement(inertial, "mass", value=_num(cart.mass))
        ixx, iyy, izz = inertia_of(train, k)
        ET.SubElement(inertial, "inertia", ixx=_num(ixx), ixy="0.0", ixz="0.0", iyy=_num(iyy), iyz="0.0",
                      izz=_num(izz))
    for name in robot.hitches:
        ET.SubElement(root, "link", name=name)
    wheels = ET.SubElement(root, "link", name=robot.front_wheels)
    wheel_box = (WHEEL_DIAMETER, cart_widths(train)[0] + WHEEL_WIDTH, WHEEL_DIAMETER)
    _geometry(wheels, "visual", (0.0, 0.0, WHEEL_DIAMETER / 2.0), wheel_box, f"{robot.prefix}tyre")
    for j in robot.joints:
        joint = ET.SubElement(root, "joint", name=j.name, type=j.kind)
        ET.SubElement(joint, "parent", link=j.parent)
        ET.SubElement(joint, "child", link=j.child)
        ET.SubElement(joint, "origin", xyz=f"{_num(j.x)} 0.0 0.0", rpy="0 0 0")
        if j.kind == "revolute":
            ET.SubElement(joint, "axis", xyz=f"0 0 {int(j.axis_z)}")
            ET.SubElement(joint, "limit", lower=_num(-j.limit), upper=_num(j.limit), effort="0.0",
                          velocity=_num(j.velocity))
    ET.indent(root)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _comment_text(text: str) -> str:
    """Text an XML comment may hold: no '--' (a train file's path may have one)."""
    while "--" in text:
        text = text.replace("--", "- -")
    return text
