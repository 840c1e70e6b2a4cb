"""Launch bridge_node with the package's parameters (full ROS 2 installs: ros2 launch)."""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    """bridge_node on the port given as port:=..., parameters from config/bridge.yaml."""
    config = os.path.join(get_package_share_directory('swarm_bridge'), 'config',
                          'bridge.yaml')
    return LaunchDescription([
        DeclareLaunchArgument('port', default_value='/dev/ttyUSB0'),
        Node(package='swarm_bridge', executable='bridge_node', name='bridge',
             parameters=[config, {'port': LaunchConfiguration('port')}], output='screen'),
    ])
