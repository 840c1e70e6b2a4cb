"""Launch one agent: ros2 launch swarm_agent agent.launch.py agent_id:=3 agent_type:=2."""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PythonExpression
from launch_ros.actions import Node


def generate_launch_description():
    config = os.path.join(get_package_share_directory('swarm_agent'), 'config', 'agent.yaml')
    args = {name: LaunchConfiguration(name) for name in (
        'agent_id', 'agent_type', 'is_beacon', 'method', 'initial_x', 'initial_y')}
    return LaunchDescription([
        DeclareLaunchArgument('agent_id', default_value='0'),
        DeclareLaunchArgument('agent_type', default_value='1'),
        DeclareLaunchArgument('is_beacon', default_value='false'),
        DeclareLaunchArgument('method', default_value='bubble'),
        DeclareLaunchArgument('initial_x', default_value='0.0'),
        DeclareLaunchArgument('initial_y', default_value='0.0'),
        Node(package='swarm_agent', executable='agent_node', name='agent',
             namespace=PythonExpression(["'agent_' + '", args['agent_id'], "'"]),
             parameters=[config, {**args, 'use_sim_time': True}], output='screen'),
    ])
