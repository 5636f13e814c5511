"""The simulator's topics: names, types, and the messages (plain dicts) made from its outputs.

One table serves the offline run and the node, so their bags hold the same topics. Names are
relative in the node (``--ros-args -r __ns:=/unit1`` moves them) and stored fully qualified in a
bag recorded in the root namespace, as rosbag2 does.

| topic              | type                        | content                                          |
|--------------------|-----------------------------|--------------------------------------------------|
| hitch_poses        | geometry_msgs/msg/PoseArray | A_k of every cart, oriented along th_k (m, rad)  |
| cart_velocities    | sensor_msgs/msg/JointState  | name = cart, velocity = s'_Ck (m/s),             |
|                    |                             | position = heading th_k (rad),                   |
|                    |                             | effort = resistance F_Bk at the axle (N)         |
| traction_power     | std_msgs/msg/Float64        | N = F_A1 V (W)                                   |
| steering_angle     | std_msgs/msg/Float64        | steering command held over the tick (rad)        |
| applied_steering   | std_msgs/msg/Float64        | psi_1, the angle the actuator has reached (rad)  |
| speed_setpoint     | std_msgs/msg/Float64        | speed set-point held over the tick (m/s)         |
| /clock             | rosgraph_msgs/msg/Clock     | simulation time                                  |

The train's frames and model for ROS tools (REP-105; ``messages/frames.py``, ``urdf.py``), in the
node's and the offline run's bags too; <p> is the frame prefix of the node's namespace (''
in /, ``unit1/`` in /unit1):

| topic              | type                        | content                                          |
|--------------------|-----------------------------|--------------------------------------------------|
| /tf                | tf2_msgs/msg/TFMessage      | <p>odom -> <p>base_link (B_1, th_1) and the      |
|                    |                             | steering and hitch joints' frames                |
| /tf_static         | tf2_msgs/msg/TFMessage      | frame_id -> <p>odom (identity), fixed joints;    |
|                    |                             | latched                                          |
| joint_states       | sensor_msgs/msg/JointState  | hitch angles th_{k-1} - th_k, then psi_1, and    |
|                    |                             | their rates (rad, rad/s)                         |
| odom               | nav_msgs/msg/Odometry       | B_1 and th_1 in <p>odom, twist in <p>base_link   |
| robot_description  | std_msgs/msg/String         | the URDF; latched                                |
"""
from __future__ import annotations

from ..bag import clock, float64, joint_state, pose_array, qos_profiles_yaml
from .frames import surface_poses

TOPICS = {
    "hitch_poses": "geometry_msgs/msg/PoseArray",
    "cart_velocities": "sensor_msgs/msg/JointState",
    "traction_power": "std_msgs/msg/Float64",
    "steering_angle": "std_msgs/msg/Float64",
    "applied_steering": "std_msgs/msg/Float64",
    "speed_setpoint": "std_msgs/msg/Float64",
    "/clock": "rosgraph_msgs/msg/Clock",
}

# The inputs of the simulator (the node subscribes to these; the others it publishes).
COMMAND_TOPICS = ("steering_angle", "speed_setpoint")

# The node's commands in the conventions controllers speak (commands.py: one rule for all), and
# the implement's (lowered or lifted: run.simulation.Simulation.set_lowered): topic -> type. The
# node subscribes ackermann_cmd only where ackermann_msgs is installed.
MESSAGE_COMMANDS = {"cmd_vel": "geometry_msgs/msg/Twist",
                    "ackermann_cmd": "ackermann_msgs/msg/AckermannDriveStamped",
                    "implement_lowered": "std_msgs/msg/Bool"}
#: cmd_vel's type with the node's parameter cmd_vel_stamped (nav2's enable_stamped_cmd_vel, the
#: Jazzy ros2_controllers' drive controllers): the twist with a header
STAMPED_CMD_VEL_TYPE = "geometry_msgs/msg/TwistStamped"

# Bag only (the node records it, never publishes it): the steering command the node holds from
# this tick on because its command watchdog took over (0.0 when a stale command is replaced by
# 'straight') or gave back (the last received command), so a re-simulation holds what the node held.
WATCHDOG_TOPIC = "steering_watchdog"
WATCHDOG_TYPE = "std_msgs/msg/Float64"

# The node's extras: a drawing of the train (10 Hz by default) and its 1 Hz diagnostics.
MARKERS_TYPE = "visualization_msgs/msg/MarkerArray"
DIAGNOSTICS_TYPE = "diagnostic_msgs/msg/DiagnosticArray"

# The train's frames and robot model for ROS tools (the table above): /tf and /tf_static are global by
# convention (tf2 listens there), the others relative (robot_state_publisher reads robot_description
# and joint_states in its own namespace).
FRAME_TOPICS = {
    "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "joint_states": "sensor_msgs/msg/JointState",
    "odom": "nav_msgs/msg/Odometry",
    "robot_description": "std_msgs/msg/String",
}

#: The node's run: its bag metadata record ``mta_sim_ros`` (the scene and train as read, method,
#: step, rate, clock_offset, ...) as a JSON object of strings, published latched at each run's start
#: (start, reset), so that a bag of any recorder (ros2 bag record, a conversion by rosbags) can be
#: analysed and re-simulated as the node's own bag can (analysis/bagdata.run_record reads either).
RUN_METADATA_TOPIC = "run_metadata"
RUN_METADATA_TYPE = "std_msgs/msg/String"

#: Topics published once (at start, and again when they change) with QoS transient-local, depth 1,
#: so a late subscriber gets them; each bag holds them from its start.
LATCHED_TOPICS = ("/tf_static", "robot_description", RUN_METADATA_TOPIC)
#: Their offered_qos_profiles in a bag (mta replay republishes them latched).
LATCHED_QOS_YAML = qos_profiles_yaml(durability="transient_local", depth=1)

#: Every topic of a node's bag (relative names as the node uses them) -> type.
BAG_TOPICS = {**TOPICS, **FRAME_TOPICS, **MESSAGE_COMMANDS, "markers": MARKERS_TYPE, "/diagnostics": DIAGNOSTICS_TYPE,
              WATCHDOG_TOPIC: WATCHDOG_TYPE, RUN_METADATA_TOPIC: RUN_METADATA_TYPE}


def qualified(topic: str, namespace: str = "/") -> str:
    """Fully qualified name of a relative topic in ``namespace``."""
    if topic.startswith("/"):
        return topic
    return namespace.rstrip("/") + "/" + topic


def output_messages(out, cart_names, frame_id: str = "map", relief=None) -> dict[str, dict]:
    """The published messages (plain dicts, topic -> message) for one Outputs sample; on a height
    grid (``relief``) hitch_poses are 3D (frames.surface_poses)."""
    t = out.t
    if relief is None:
        poses = pose_array(t, frame_id, [(p[0], p[1], th) for p, th in zip(out.front, out.heading)])
    else:
        poses = {"header": pose_array(t, frame_id, [])["header"],
                 "poses": [{"position": dict(zip("xyz", p[:3])), "orientation": dict(zip("xyzw", p[3:]))}
                           for p in surface_poses(relief, out)]}
    return {
        "hitch_poses": poses,
        "cart_velocities": joint_state(t, cart_names, out.heading, out.com_speed, efforts=out.resistance),
        "traction_power": float64(out.power),
        "applied_steering": float64(out.steering),
        "/clock": clock(t),
    }


def command_messages(out) -> dict[str, dict]:
    """The inputs held over the tick that produced ``out``, as the node would receive them."""
    return {"steering_angle": float64(out.command), "speed_setpoint": float64(out.speed_setpoint)}
