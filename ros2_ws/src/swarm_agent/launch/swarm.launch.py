"""The whole simulated swarm for users with a full ROS 2 install.

  ros2 launch swarm_agent swarm.launch.py fleet_file:=/path/fleet.yaml method:=bubble \
      shape:=circle_314

Starts the same graph as scripts/launch_swarm.py --composed: sim_node, mission_node and
every robot of the fleet file in one composed_node process. (Per-robot processes and
the metrics/figures come with scripts/launch_swarm.py.)
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    agent_cfg = os.path.join(get_package_share_directory('swarm_agent'), 'config', 'agent.yaml')
    mission_cfg = os.path.join(get_package_share_directory('swarm_mission'), 'config',
                               'mission.yaml')
    fleet = LaunchConfiguration('fleet_file')
    method = LaunchConfiguration('method')
    shape = LaunchConfiguration('shape')
    return LaunchDescription([
        DeclareLaunchArgument('fleet_file', description='fleet YAML (robots: id, type, ...)'),
        DeclareLaunchArgument('method', default_value='bubble'),
        DeclareLaunchArgument('shape', default_value='circle_314'),
        Node(package='swarm_sim', executable='sim_node', name='sim',
             parameters=[{'fleet_file': fleet, 'shape': shape}], output='screen'),
        Node(package='swarm_mission', executable='mission_node', name='mission',
             parameters=[mission_cfg, {'shape': shape, 'method': method,
                                       'use_sim_time': True}], output='screen'),
        Node(package='swarm_agent', executable='composed_node', name='agents_container',
             parameters=[agent_cfg, {'fleet_file': fleet, 'method': method,
                                     'use_sim_time': True}], output='screen'),
    ])
