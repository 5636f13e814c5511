"""The package's network rule for what a launch file starts after including this one.

With ``loopback:=true`` (the default) every process started afterwards keeps DDS on this host:
discovery on localhost only and the Fast DDS profile config/fastdds_loopback.xml, which binds the
sockets to 127.0.0.1 (mta_sim_ros/node/loopback.py says which variables; docs/node.md, "The
network rule", what they do), and no static peers elsewhere. sim.launch.py, rviz.launch.py and
foxglove.launch.py include it first; an include does not scope the environment, so the settings
hold for the rest of the including file.
"""
from launch.actions import DeclareLaunchArgument, SetEnvironmentVariable, UnsetEnvironmentVariable
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration

from launch import LaunchDescription
from mta_sim_ros.node.loopback import loopback_env


def generate_launch_description():
    loopback = IfCondition(LaunchConfiguration('loopback'))
    return LaunchDescription([
        DeclareLaunchArgument(
            'loopback', default_value='true', choices=['true', 'false'],
            description='keep DDS on this host (discovery range LOCALHOST, the Fast DDS loopback profile)'),
        *[SetEnvironmentVariable(name, value, condition=loopback) for name, value in loopback_env({}).items()],
        UnsetEnvironmentVariable('ROS_STATIC_PEERS', condition=loopback),
    ])
