"""RViz2 with the simulator's view (config/rviz/mta.rviz), for a running node or a bag played back.

    ros2 launch mta_sim_ros rviz.launch.py [namespace:=unit1 fixed_frame:=unit1/odom]

The config's topics are relative (``markers``, ``hitch_poses``, ``odom``, ``robot_description``),
so RViz in ``namespace`` shows that node's train; ``fixed_frame`` overrides the config's ``odom``
(the frames carry the namespace: ``unit1/odom``). Time is the simulator's /clock (``use_sim_time``),
which ``mta replay`` and ``ros2 bag play`` of the node's bags publish too. ``loopback:=true`` (the
default) keeps DDS on this host, as everything of the package (loopback.launch.py).
``sim.launch.py rviz:=true`` includes this file.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument(
            'config',
            default_value=PathJoinSubstitution([FindPackageShare('mta_sim_ros'), 'config', 'rviz', 'mta.rviz']),
            description='the RViz config'),
        DeclareLaunchArgument('namespace', default_value='', description="RViz's namespace (the node's)"),
        DeclareLaunchArgument('fixed_frame', default_value='odom', description="RViz's fixed frame"),
        DeclareLaunchArgument('use_sim_time', default_value='true', choices=['true', 'false'],
                              description='follow /clock (the simulator, a bag played back)'),
        IncludeLaunchDescription(PythonLaunchDescriptionSource(
            PathJoinSubstitution([FindPackageShare('mta_sim_ros'), 'launch', 'loopback.launch.py']))),
        Node(package='rviz2', executable='rviz2', name='rviz2', namespace=LaunchConfiguration('namespace'),
             output='screen',
             arguments=['-d', LaunchConfiguration('config'), '-f', LaunchConfiguration('fixed_frame')],
             parameters=[{'use_sim_time': LaunchConfiguration('use_sim_time')}]),
    ])
