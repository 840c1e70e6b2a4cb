"""Launch the mission node: ros2 launch swarm_mission mission.launch.py shape:=circle_314."""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    config = os.path.join(get_package_share_directory('swarm_mission'), 'config',
                          'mission.yaml')
    return LaunchDescription([
        DeclareLaunchArgument('shape', default_value='circle_314'),
        DeclareLaunchArgument('method', default_value='bubble'),
        Node(package='swarm_mission', executable='mission_node', name='mission',
             parameters=[config, {'shape': LaunchConfiguration('shape'),
                                  'method': LaunchConfiguration('method'),
                                  'use_sim_time': True}], output='screen'),
    ])
