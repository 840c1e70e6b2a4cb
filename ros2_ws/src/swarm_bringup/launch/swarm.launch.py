"""The simulated swarm through ``ros2 launch``: the launch plan rendered by launch_ros.

  ros2 launch swarm_bringup swarm.launch.py agents:=8 beacons:=3 shape:=circle_314
  ros2 launch swarm_bringup swarm.launch.py mode:=per_robot \\
      fleet_file:=$(ros2 pkg prefix swarm_bringup)/share/swarm_bringup/config/fleet.yaml \\
      params_file:=$(ros2 pkg prefix swarm_bringup)/share/swarm_bringup/config/params.yaml
  # two swarms in one domain: every name under the namespace, /clock and /tf remapped
  ros2 launch swarm_bringup swarm.launch.py namespace:=/swarm_a
  ros2 launch swarm_bringup swarm.launch.py namespace:=/swarm_b shape:=thesis_shape_1

The processes are the ones ``scripts/launch_swarm.py`` starts, from the same plan
(swarm_bringup.launch_plan, arguments checked by swarm_bringup.launch_arguments): the
simulator, the mission node and the agents (composed or one process per robot). A fleet
is generated from agents, beacons, types and seed when no fleet_file is given. The
launch shuts down when the simulator exits; an agent process or the mission node that
exits on its own is respawned (1 s later, at most 3 times: launch_plan.RESPAWN_*).
``ros2 launch swarm_bringup swarm.launch.py --show-args`` lists the arguments. (Metrics
and figures of a run come with scripts/launch_swarm.py, whose monitor records it.)
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction, Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from swarm_bringup.launch_arguments import ARGUMENTS, plan_from_arguments
from swarm_bringup.launch_plan import node_kwargs


def _nodes(context):
    given = {name: LaunchConfiguration(name).perform(context) for name, _, _ in ARGUMENTS}
    plan, _ = plan_from_arguments(given)
    return [Node(**node_kwargs(spec),
                 on_exit=Shutdown(reason='the simulator exited') if spec.process == 'sim'
                 else None)
            for spec in plan]


def generate_launch_description():
    return LaunchDescription([
        *(DeclareLaunchArgument(name, default_value=default, description=text)
          for name, default, text in ARGUMENTS),
        OpaqueFunction(function=_nodes),
    ])
