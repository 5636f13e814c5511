"""RViz2 with the simulator's view (config/rviz/mta.rviz), for a running node or a bag played back.

    ros2 launch mta_sim_ros rviz.launch.py [namespace:=unit1]

The config's topics are relative (``markers``, ``hitch_poses``, ``odom``, ``robot_description``),
so RViz in ``namespace`` shows that node's train; the frames carry the namespace (``unit1/odom``,
``unit1/base_link``), so RViz gets a copy of the config whose fixed frame and view target are the
namespace's (``fixed_frame`` and ``target_frame`` override them; the config itself is never
written). Time is the simulator's /clock (``use_sim_time``), which ``mta replay`` and ``ros2 bag
play`` of the node's bags publish too. Without rviz2 installed the launch fails in one line and
starts nothing (launch_support.py). ``loopback:=true`` (the default) keeps DDS on this host, as
everything of the package (loopback.launch.py). ``sim.launch.py rviz:=true`` includes this file.
"""
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription, OpaqueFunction
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

from launch import LaunchDescription
from mta_sim_ros.node.launch_support import require_packages, rviz_config, shutdown_on_failure


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument(
            'config',
            default_value=PathJoinSubstitution([FindPackageShare('mta_sim_ros'), 'config', 'rviz', 'mta.rviz']),
            description='the RViz config'),
        DeclareLaunchArgument('namespace', default_value='', description="RViz's namespace (the node's)"),
        DeclareLaunchArgument('fixed_frame', default_value='',
                              description="RViz's fixed frame; '' = <namespace>/odom"),
        DeclareLaunchArgument('target_frame', default_value='',
                              description="the frame the view follows; '' = <namespace>/base_link"),
        DeclareLaunchArgument('use_sim_time', default_value='true', choices=['true', 'false'],
                              description='follow /clock (the simulator, a bag played back)'),
        IncludeLaunchDescription(PythonLaunchDescriptionSource(
            PathJoinSubstitution([FindPackageShare('mta_sim_ros'), 'launch', 'loopback.launch.py']))),
        OpaqueFunction(function=launch_setup),
    ])


def launch_setup(context):
    def arg(name):
        return LaunchConfiguration(name).perform(context)

    require_packages({'rviz2': 'RViz'}, 'rviz.launch.py')
    namespace = arg('namespace').strip('/')
    prefix = namespace + '/' if namespace else ''
    fixed = arg('fixed_frame') or prefix + 'odom'
    config = rviz_config(arg('config'), fixed, arg('target_frame') or prefix + 'base_link')
    return [Node(package='rviz2', executable='rviz2', name='rviz2', namespace=namespace, output='screen',
                 on_exit=shutdown_on_failure, arguments=['-d', config, '-f', fixed],
                 parameters=[{'use_sim_time': arg('use_sim_time') == 'true'}])]
