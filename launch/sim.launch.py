"""The tractor-train simulator on a ROS 2 Jazzy install, and what may run beside it.

    ros2 launch mta_sim_ros sim.launch.py [NAME:=VALUE ...]      (--show-args lists the arguments)

starts ``sim_node`` (package mta_sim_ros) with ``params_file`` in ``namespace`` and, on request:

* ``robot_state_publisher:=true``: robot_state_publisher publishes the carts' frames from the
  node's ``joint_states``, and the node leaves them to it (``publish_cart_frames: false``; it still
  publishes ``odom -> base_link``). Jazzy's robot_state_publisher takes the URDF from its
  ``robot_description`` parameter only, not from a topic, so it starts with a one-link
  placeholder and ``mta rsp_feed`` sets the train's URDF, which the node publishes on
  ``robot_description``, on that parameter (mta_sim_ros/tools/rsp_feed.py). Its own republished
  copy goes to ``robot_state_publisher/robot_description``, away from the node's topic;
* ``driver:=maneuver``: ``mta maneuver`` plays the scene's steering table (``maneuver:=NAME``
  and ``maneuver_params:="k=v k=v"``: a named manoeuvre instead), then exits;
  ``driver:=follow``: ``mta follow``, the pure-pursuit example controller (``driver_args``: more
  options of either command, e.g. ``driver_args:="--passes 2"``), or a field plan worked live
  (``driver_args:="--field fieldwork/rectangle.yaml"``, the node's ``params_file`` the one
  ``mta follow --field ... --write-scene DIR`` wrote: the train at the route's start, lockstep):
  it publishes the plan, the field's boundary and the coverage, which RViz and Foxglove show;
* ``rviz:=true``: RViz2 with config/rviz/mta.rviz (``rviz.launch.py``);
* ``foxglove:=true``: foxglove_bridge on 127.0.0.1 (``foxglove.launch.py``).

The frames carry the namespace (``/unit1``: ``unit1/odom``, ``unit1/base_link``, ...), so several
trains share one tf tree; RViz gets ``<namespace>/odom`` as its fixed frame. ``scene`` and
``frame_id`` (the frame of hitch_poses and markers, which the node joins to its odom frame)
override the params file's ``scene_file`` and ``frame_id`` when given.

``loopback:=true`` (the default) keeps DDS on this host for every process started here: the
package's network rule (loopback.launch.py: discovery on localhost only, and the Fast DDS
profile config/fastdds_loopback.xml that binds its sockets to 127.0.0.1).
"""
import os
import shlex

from ament_index_python.packages import get_package_share_directory
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription, OpaqueFunction
from launch.conditions import IfCondition, evaluate_condition_expression
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

from launch import LaunchDescription
from mta_sim_ros.node.launch_support import require_packages, shutdown_on_failure
from mta_sim_ros.node.params import BY_NAME, ConfigError, read_params_file

PACKAGE = 'mta_sim_ros'

#: robot_state_publisher refuses to start without a URDF: this one link until mta rsp_feed sets
#: the train's (%s: the frame prefix)
PLACEHOLDER_URDF = ('<?xml version="1.0"?><robot name="mta_waiting_for_robot_description">'
                    '<link name="%sbase_link"/></robot>')


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument(
            'params_file',
            default_value=PathJoinSubstitution([FindPackageShare(PACKAGE), 'config', 'sim.yaml']),
            description="the node's ROS parameters file"),
        DeclareLaunchArgument(
            'namespace', default_value='',
            description='namespace of every node started here (and prefix of the frames)'),
        DeclareLaunchArgument(
            'scene', default_value='',
            description="scene file (overrides the params file's scene_file; the driver plays it); "
                        "'' = the params file's"),
        DeclareLaunchArgument(
            'frame_id', default_value='',
            description="frame of hitch_poses and markers (overrides the params file's frame_id); '' = the params file's"),
        DeclareLaunchArgument(
            'robot_state_publisher', default_value='false', choices=['true', 'false'],
            description="cart frames from robot_state_publisher, fed with the node's robot_description"),
        DeclareLaunchArgument(
            'driver', default_value='none', choices=['none', 'maneuver', 'follow'],
            description='what steers the node: nothing (publish steering_angle yourself), '
                        "mta maneuver (the scene's steering, or a named manoeuvre) or mta follow (pure pursuit)"),
        DeclareLaunchArgument(
            'maneuver', default_value='',
            description="driver:=maneuver: a named manoeuvre instead of the scene's steering "
                        '(straight, step, ramp, sine, slalom, lane_change, headland_turn)'),
        DeclareLaunchArgument(
            'maneuver_params', default_value='',
            description='driver:=maneuver: the manoeuvre\'s parameters, "k=v k=v"'),
        DeclareLaunchArgument(
            'driver_args', default_value='',
            description='more options of mta maneuver or mta follow, e.g. "--passes 2 --report follow.json"'),
        DeclareLaunchArgument(
            'rviz', default_value='false', choices=['true', 'false'],
            description='start RViz2 with config/rviz/mta.rviz'),
        DeclareLaunchArgument(
            'foxglove', default_value='false', choices=['true', 'false'],
            description='start foxglove_bridge on 127.0.0.1'),
        DeclareLaunchArgument(
            'foxglove_port', default_value='8765',
            description="foxglove_bridge's WebSocket port"),
        IncludeLaunchDescription(PythonLaunchDescriptionSource(
            PathJoinSubstitution([FindPackageShare(PACKAGE), 'launch', 'loopback.launch.py']))),
        OpaqueFunction(function=launch_setup),
    ])


def launch_setup(context):
    """The actions, once the arguments are known: the node's parameters depend on several."""
    def arg(name):
        return LaunchConfiguration(name).perform(context)

    def flag(name):
        return evaluate_condition_expression(context, [LaunchConfiguration(name)])

    share = get_package_share_directory(PACKAGE)
    namespace = arg('namespace').strip('/')
    prefix = namespace + '/' if namespace else ''  # the node's frame prefix (mta_sim_ros.urdf)
    try:  # the params file's faults in one line now, not from inside the node
        given = read_params_file(arg('params_file'))
    except ConfigError as err:
        raise RuntimeError(f'params_file: {err}') from None
    scene = arg('scene') or given.get('scene_file', BY_NAME['scene_file'].default)
    overrides = {'scene_file': scene}
    if arg('frame_id'):
        overrides['frame_id'] = arg('frame_id')
    with_rsp = flag('robot_state_publisher')
    if with_rsp:
        overrides['publish_cart_frames'] = False
    # every optional package asked for, before any node starts (launch_support.py; ros2/launch#747)
    asked = {'robot_state_publisher': 'robot_state_publisher:=true', 'rviz2': 'rviz:=true',
             'foxglove_bridge': 'foxglove:=true'}
    wanted = {'robot_state_publisher': with_rsp, 'rviz2': flag('rviz'), 'foxglove_bridge': flag('foxglove')}
    require_packages({p: a for p, a in asked.items() if wanted[p]}, 'sim.launch.py')

    actions = [Node(
        package=PACKAGE, executable='sim_node', namespace=namespace, output='screen', on_exit=shutdown_on_failure,
        parameters=[arg('params_file'), overrides])]
    if with_rsp:
        actions += [
            Node(package='robot_state_publisher', executable='robot_state_publisher',
                 name='robot_state_publisher', namespace=namespace, output='screen', on_exit=shutdown_on_failure,
                 parameters=[{'robot_description': PLACEHOLDER_URDF % prefix, 'use_sim_time': True}],
                 remappings=[('robot_description', 'robot_state_publisher/robot_description')]),
            Node(package=PACKAGE, executable='mta', name='mta_rsp_feed', namespace=namespace, output='screen',
                 on_exit=shutdown_on_failure,
                 arguments=['rsp_feed', '--target', 'robot_state_publisher']),
        ]
    extra = shlex.split(arg('driver_args'))
    if arg('driver') == 'maneuver':
        named = ['--maneuver', arg('maneuver')] if arg('maneuver') else []
        for item in arg('maneuver_params').split():
            named += ['--param', item]
        actions.append(Node(
            package=PACKAGE, executable='mta', name='mta_maneuver', namespace=namespace, output='screen',
            on_exit=shutdown_on_failure,
            arguments=['maneuver', '--scene', scene, *named, *extra]))
    elif arg('driver') == 'follow':
        actions.append(Node(
            package=PACKAGE, executable='mta', name='mta_follow', namespace=namespace, output='screen',
            on_exit=shutdown_on_failure,
            arguments=['follow', '--scene', scene, *extra]))
    actions += [
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(os.path.join(share, 'launch', 'rviz.launch.py')),
            launch_arguments={'namespace': namespace, 'fixed_frame': prefix + 'odom', 'use_sim_time': 'true'}.items(),
            condition=IfCondition(LaunchConfiguration('rviz'))),
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(os.path.join(share, 'launch', 'foxglove.launch.py')),
            launch_arguments={'port': arg('foxglove_port'), 'use_sim_time': 'true'}.items(),
            condition=IfCondition(LaunchConfiguration('foxglove'))),
    ]
    return actions
