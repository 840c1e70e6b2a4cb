"""Helpers of the in-process ROS tests: a private rclpy context and spinning until."""

from __future__ import annotations

from collections.abc import Callable, Iterator
import contextlib
import time

import rclpy
from rclpy.executors import Executor, SingleThreadedExecutor


@contextlib.contextmanager
def ros_context(make_executor: Callable[..., Executor] = SingleThreadedExecutor,
                ) -> Iterator[tuple[rclpy.Context, Executor]]:
    """A fresh rclpy context and an executor on it; shut down on exit."""
    context = rclpy.Context()
    rclpy.init(context=context)
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
