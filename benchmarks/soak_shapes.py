"""Shape changes at wall-clock times for the soak benchmark (benchmarks/soak.py).

A client of the mission node's ``swarm/set_shape`` service (swarm_msgs/srv/SetShape)
in the swarm's ROS domain, with the sim clock (``use_sim_time``) to stamp each change
on the run's record clock. The sequence option of the launcher changes shapes at sim
times; a soak is timed in wall time, and on a loaded machine the two drift apart.
"""

from __future__ import annotations

import os
import threading
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

from swarm_common.conversions import shape_to_msg
from swarm_common.shapes import load_shape
from swarm_msgs.srv import SetShape


class ShapeChanger:
    """Sets shapes through ``swarm/set_shape`` in ROS domain ``domain`` (localhost)."""

    def __init__(self, domain: int) -> None:
        os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('soak_shapes', context=self.context,
                                      parameter_overrides=[
                                          Parameter('use_sim_time', value=True)])
        self.client = self.node.create_client(SetShape, 'swarm/set_shape')
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._spin = threading.Thread(target=self.executor.spin, daemon=True)
        self._spin.start()

    def sim_time(self) -> float:
        return self.node.get_clock().now().nanoseconds / 1e9

    def change(self, name: str, timeout_s: float = 300.0) -> dict:
        """Set shape ``name``; the mission node's answer and the sim time it was sent."""
        entry = {'shape': name, 'sim': self.sim_time(), 'ok': False, 'version': None,
                 'message': 'the mission node did not answer'}
        if not self.client.wait_for_service(timeout_sec=timeout_s):
            return entry
        request = SetShape.Request(shape=shape_to_msg(load_shape(name), 0))
        future = self.client.call_async(request)
        deadline = time.monotonic() + timeout_s
        while not future.done() and time.monotonic() < deadline:
            time.sleep(0.1)
        if future.done() and future.result() is not None:
            answer = future.result()
            entry.update(ok=bool(answer.success), version=int(answer.version),
                         message=answer.message)
        return entry

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
