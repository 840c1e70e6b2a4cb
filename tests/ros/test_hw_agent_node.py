"""hw_agent_node: a robot the overhead camera has lost keeps its last estimate, LOST,
with an uncertainty that grows as far as it can have driven (issue: no camera or an
unreadable frame must not freeze a confident estimate)."""

from __future__ import annotations

import time

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from geometry_msgs.msg import PoseStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile  # noqa: E402

from swarm_agent.hw_agent_node import HwAgentNode  # noqa: E402
from swarm_common import qos  # noqa: E402
from swarm_msgs.msg import AgentState  # noqa: E402


def test_a_robot_without_camera_poses_is_lost_with_growing_uncertainty():
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    agent = HwAgentNode(node_name='agent_3', context=context, parameter_overrides=[
        Parameter('agent_id', value=3), Parameter('agent_type', value=1),
        Parameter('external_pose', value=True), Parameter('initial_x', value=0.5),
        Parameter('initial_y', value=0.5), Parameter('pose_timeout', value=0.5),
        Parameter('setpoint.v_max', value=0.035)])
    probe = rclpy.create_node('probe', context=context)
    executor.add_node(agent)
    executor.add_node(probe)
    states: list[AgentState] = []
    probe.create_subscription(AgentState, '/agent_3/state', states.append,
                              QoSProfile(**qos.STATE))
    pose_pub = probe.create_publisher(PoseStamped, '/agent_3/pose', QoSProfile(**qos.SENSOR))

    def spin_until(done, seconds: float, pose: tuple[float, float] | None = None) -> bool:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if pose is not None:
                msg = PoseStamped()
                msg.pose.position.x, msg.pose.position.y = pose
                pose_pub.publish(msg)
            executor.spin_once(timeout_sec=0.02)
            if done():
                return True
        return False

    def std(state: AgentState) -> float:
        return float(np.sqrt(state.covariance[0]))

    def seen_at(xy) -> bool:
        return bool(states) and states[-1].mode == AgentState.MODE_NORMAL and np.allclose(
            states[-1].position, xy, atol=1e-6)

    try:
        # Discovery can take seconds on a loaded machine: wait for the pose to arrive.
        assert spin_until(lambda: seen_at((0.8, 0.6)), 30.0, pose=(0.8, 0.6))
        assert std(states[-1]) == pytest.approx(0.01, abs=1e-6)
        last_pose = time.monotonic()
        # The camera loses the robot: LOST once no pose came for pose_timeout (0.5 s).
        assert spin_until(lambda: states[-1].mode == AgentState.MODE_LOST, 10.0)
        early = states[-1]
        spin_until(lambda: False, 1.5)
        late = states[-1]
        age = time.monotonic() - last_pose
        for state in (early, late):
            assert state.mode == AgentState.MODE_LOST
            assert np.allclose(state.position, (0.8, 0.6), atol=1e-6), 'kept, not guessed'
        # The deviation grows at 0.035 m/s from the last pose received: at least its
        # value at the timeout, at most its value now (0.5 s allowed for the last
        # best-effort poses lost on the way).
        assert np.hypot(0.01, 0.035 * 0.5) - 1e-6 <= std(early) < std(late)
        assert std(late) <= np.hypot(0.01, 0.035 * (age + 0.5)), (std(late), age)
        assert spin_until(lambda: seen_at((0.81, 0.6)), 10.0, pose=(0.81, 0.6))  # seen again
        assert std(states[-1]) == pytest.approx(0.01, abs=1e-6)
    finally:
        executor.shutdown()
        agent.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown(context=context)
