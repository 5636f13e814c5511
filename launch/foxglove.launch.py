"""foxglove_bridge for the Foxglove app, listening on 127.0.0.1 only (the package's network rule).

    ros2 launch mta_sim_ros foxglove.launch.py [port:=8765]

Open Foxglove, "Open connection", Foxglove WebSocket ``ws://localhost:8765``, then import the
layout config/foxglove/mta_layout.json (share/mta_sim_ros/config/foxglove/ on an install). From
another machine, forward the port over SSH (``ssh -L 8765:localhost:8765 HOST``): the bridge
never listens beyond loopback. ``use_sim_time`` follows the simulator's /clock; ``loopback:=true``
(the default) keeps DDS on this host (loopback.launch.py). Without foxglove_bridge installed the
launch fails in one line and starts nothing (launch_support.py). ``sim.launch.py foxglove:=true``
includes this file.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription, OpaqueFunction
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

from mta_sim_ros.node.launch_support import require_packages, shutdown_on_failure


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('port', default_value='8765', description="the bridge's WebSocket port"),
        DeclareLaunchArgument('use_sim_time', default_value='true', choices=['true', 'false'],
                              description='follow /clock (the simulator, a bag played back)'),
        IncludeLaunchDescription(PythonLaunchDescriptionSource(
            PathJoinSubstitution([FindPackageShare('mta_sim_ros'), 'launch', 'loopback.launch.py']))),
        OpaqueFunction(function=launch_setup),
    ])


def launch_setup(context):
    require_packages({'foxglove_bridge': 'the Foxglove bridge'}, 'foxglove.launch.py')
    return [Node(package='foxglove_bridge', executable='foxglove_bridge', name='foxglove_bridge', output='screen',
                 on_exit=shutdown_on_failure,
                 parameters=[{'address': '127.0.0.1', 'port': LaunchConfiguration('port'),
                              'use_sim_time': LaunchConfiguration('use_sim_time')}])]
