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

from swarm_bridge.hw_agent_node import HwAgentNode  # noqa: E402
from swarm_mission import qos  # noqa: E402
from swarm_msgs.msg import AgentState  # noqa: E402


def test_a_robot_without_camera_poses_is_lost_with_growing_uncertainty():
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    agent = HwAgentNode(namespace='/agent_3', context=context, parameter_overrides=[
        Parameter('agent_id', value=3), Parameter('agent_type', value=1),
        Parameter('external_pose', value=True), Parameter('initial_x', value=0.5),
        Parameter('initial_y', value=0.5), Parameter('pose_timeout', value=0.5),
        Parameter('setpoint_v_max', value=0.035)])
    probe = rclpy.create_node('probe', context=context)
    executor.add_node(agent)
    executor.add_node(probe)
    states: list[AgentState] = []
    probe.create_subscription(AgentState, '/agent_3/state', states.append,
                              QoSProfile(**qos.STATE))
    pose_pub = probe.create_publisher(PoseStamped, '/agent_3/pose', QoSProfile(**qos.SENSOR))

    def spin(seconds: float, pose: tuple[float, float] | None = None) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if pose is not None:
                msg = PoseStamped()
                msg.pose.position.x, msg.pose.position.y = pose
                pose_pub.publish(msg)
            executor.spin_once(timeout_sec=0.02)

    def std(state: AgentState) -> float:
        return float(np.sqrt(state.covariance[0]))

    try:
        spin(1.5, pose=(0.8, 0.6))
        seen = states[-1]
        assert seen.mode == AgentState.MODE_NORMAL
        assert np.allclose(seen.position, (0.8, 0.6), atol=1e-6)
        assert std(seen) == pytest.approx(0.01, abs=1e-6)
        spin(1.5)                       # the camera loses the robot
        early = states[-1]
        spin(1.5)
        late = states[-1]
        for state in (early, late):
            assert state.mode == AgentState.MODE_LOST
            assert np.allclose(state.position, (0.8, 0.6), atol=1e-6), 'kept, not guessed'
        # 0.035 m/s for 1-3 s without a pose: 3.5-10.5 cm, and growing.
        assert 0.03 < std(early) < std(late) < 0.12, (std(early), std(late))
        spin(1.0, pose=(0.81, 0.6))     # seen again
        back = states[-1]
        assert back.mode == AgentState.MODE_NORMAL and std(back) == pytest.approx(0.01, abs=1e-6)
    finally:
        executor.shutdown()
        agent.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown(context=context)
