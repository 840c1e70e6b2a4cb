"""Helpers of the in-process ROS tests: a private rclpy context and spinning until."""

from __future__ import annotations

from collections.abc import Callable, Iterator
import contextlib
import time

import rclpy
from rclpy.executors import Executor, SingleThreadedExecutor


@contextlib.contextmanager
def ros_context(make_executor: Callable[..., Executor] = SingleThreadedExecutor,
                args: list[str] | None = None) -> Iterator[tuple[rclpy.Context, Executor]]:
    """A fresh rclpy context (command line ``args``, e.g. ``--ros-args -p name:=value``
    as ``ros2 run`` passes them to every node of the process) and an executor on it;
    shut down on exit."""
    context = rclpy.Context()
    rclpy.init(args=args, context=context)
    executor = make_executor(context=context)
    try:
        yield context, executor
    finally:
        executor.shutdown()
        rclpy.try_shutdown(context=context)


def spin_until(executor: Executor, condition: Callable[[], bool], timeout: float = 20.0,
               step: float = 0.01) -> bool:
    """Spin ``executor`` until ``condition()`` holds or ``timeout`` wall seconds pass."""
    deadline = time.monotonic() + timeout
    while not condition() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=step)
    return condition()


def beacon_agent(context: rclpy.Context, executor: Executor):
    """Beacon agent 5 (type 2) deployed at (-10, 0) and a ``probe`` node, both spun by
    ``executor``; the caller destroys them."""
    from rclpy.parameter import Parameter

    from swarm_agent.agent_node import AgentNode

    agent = AgentNode('agent_5', context=context, parameter_overrides=[
        Parameter('agent_id', value=5), Parameter('agent_type', value=2),
        Parameter('is_beacon', value=True), Parameter('initial_x', value=-10.0),
        Parameter('initial_y', value=0.0)])
    probe = rclpy.create_node('probe', context=context)
    executor.add_node(agent)
    executor.add_node(probe)
    return agent, probe


@contextlib.contextmanager
def sim_world(directory, robots, probe_name: str = 'probe', **params):
    """A point-mass SimNode over ``robots`` (RobotSpec) and a ``probe`` node, spun by one
    executor; the fleet file is written to ``directory``. placement_std_m 0: the robots
    stand exactly where the test puts them; ``params`` override the sim's parameters."""
    from rclpy.parameter import Parameter

    from swarm_common.fleet import save_fleet
    from swarm_sim.sim_node import SimNode

    fleet_file = directory / 'fleet.yaml'
    save_fleet(fleet_file, robots)
    settings = {'fleet_file': str(fleet_file), 'backend': 'pointmass',
                'real_time_factor': 0.0, 'max_agent_lag_s': 0.0, 'half_size': 20.0,
                'placement_std_m': 0.0, **params}
    with ros_context() as (context, executor):
        sim = SimNode(context=context, parameter_overrides=[
            Parameter(name, value=value) for name, value in settings.items()])
        probe = rclpy.create_node(probe_name, context=context)
        executor.add_node(sim)
        executor.add_node(probe)
        try:
            yield executor, sim, probe
        finally:
            sim.close()
            sim.destroy_node()
            probe.destroy_node()
