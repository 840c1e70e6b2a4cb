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
