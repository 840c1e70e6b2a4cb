"""agent_node in-process: it speaks DSDV on /radio/tx, takes goals and proximity scans,
and reports state."""

from __future__ import annotations

import time

import pytest

rclpy = pytest.importorskip('rclpy')

from geometry_msgs.msg import PoseWithCovarianceStamped, WrenchStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile  # noqa: E402
from spin import beacon_agent  # noqa: E402

from swarm_agent.agent_node import AgentNode  # noqa: E402
from swarm_agent.brain_config import BrainConfigError  # noqa: E402
from swarm_agent.conversions import frames_from_msg  # noqa: E402
from swarm_common import qos  # noqa: E402
from swarm_common.conversions import goals_to_msg, shape_to_msg  # noqa: E402
from swarm_common.goals import Goal  # noqa: E402
from swarm_common.shapes import load_shape  # noqa: E402
from swarm_msgs.msg import (  # noqa: E402
    AgentState,
    FormationShape,
    GoalArray,
    RadioPacketArray,
    RouteTable,
)


def test_beacon_agent_drives_to_its_goal_and_reports(tmp_path):
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    agent, probe = beacon_agent(context, executor)
    got: dict[str, list] = {'tx': [], 'state': [], 'force': [], 'routes': []}
    probe.create_subscription(RadioPacketArray, '/radio/tx', got['tx'].append,
                              QoSProfile(**qos.RADIO))
    probe.create_subscription(AgentState, '/agent_5/state', got['state'].append,
                              QoSProfile(**qos.STATE))
    probe.create_subscription(RouteTable, '/agent_5/routes', got['routes'].append,
                              QoSProfile(**qos.STATE))
    probe.create_subscription(WrenchStamped, '/agent_5/cmd_force', got['force'].append,
                              QoSProfile(**qos.COMMAND))
    shape_pub = probe.create_publisher(FormationShape, '/swarm/shape', QoSProfile(**qos.LATCHED))
    goals_pub = probe.create_publisher(GoalArray, '/swarm/goals', QoSProfile(**qos.LATCHED))
    gps_pub = probe.create_publisher(PoseWithCovarianceStamped, '/agent_5/gps',
                                     QoSProfile(**qos.SENSOR))
    try:
        shape_pub.publish(shape_to_msg(load_shape('circle_314'), 1))
        goals_pub.publish(goals_to_msg([Goal(0, 2, 3.0, 0.0, 0.3)], 1, 1, 'bubble'))
        deadline = time.monotonic() + 20.0

        def pushing_east() -> bool:
            return any(f.wrench.force.x > 0.0 for f in got['force'])

        # Spin until the goal is taken and the inner loop has acted on it (the setpoint
        # changes at the 2 Hz outer loop, so a slow machine needs more than one tick).
        while time.monotonic() < deadline and not (
                got['state'] and got['state'][-1].assigned_goal == 0 and got['routes']
                and pushing_east()):
            fix = PoseWithCovarianceStamped()
            fix.pose.pose.position.x = -10.0
            fix.pose.covariance[0] = fix.pose.covariance[7] = 0.01
            gps_pub.publish(fix)
            executor.spin_once(timeout_sec=0.05)
        frames = [f for batch in got['tx'] for _, f in frames_from_msg(batch)]
        assert frames, 'no radio traffic (heartbeats) on /radio/tx'
        assert all(f.source == 5 for f in frames)
        # batched at radio_tx_hz (20 Hz): fewer messages than frames once routing runs
        assert len(got['tx']) <= len(frames)
        state = got['state'][-1]
        assert state.id == 5 and state.type == 2 and state.is_beacon
        assert not state.localized, 'a beacon fixes by GPS, never from its own ranges'
        assert state.assigned_goal == 0, 'a lone agent must take the only goal of its type'
        assert state.rows_used == 1
        # The goal is to the east (+x): the LQR force must push east.
        assert pushing_east(), 'no eastward force towards the goal at x = 3 m'
    finally:
        executor.shutdown()
        agent.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown(context=context)


@pytest.mark.parametrize('rate', ['radio_tx_hz', 'control_rate_hz'])
def test_a_rate_of_zero_is_refused_with_its_name(rate):
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        with pytest.raises(BrainConfigError, match=f'{rate} must be above 0 Hz'):
            AgentNode('agent_1', context=context,
                      parameter_overrides=[Parameter(rate, value=0.0)])
    finally:
        rclpy.try_shutdown(context=context)


def test_proximity_scans_reach_the_brain_and_a_malformed_one_is_dropped():
    from builtin_interfaces.msg import Time

    from swarm_agent.conversions import proximity_to_msg
    from swarm_msgs.msg import ProximityArray

    context = rclpy.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    agent = AgentNode('agent_3', context=context,
                      parameter_overrides=[Parameter('agent_id', value=3)])
    probe = rclpy.create_node('probe', context=context)
    executor.add_node(agent)
    executor.add_node(probe)
    pub = probe.create_publisher(ProximityArray, '/agent_3/proximity', QoSProfile(**qos.SENSOR))
    try:
        deadline = time.monotonic() + 20.0
        while agent.brain._proximity is None and time.monotonic() < deadline:
            pub.publish(proximity_to_msg(Time(sec=1), 3, [[1.0, -0.5]], [0.45], 0.02))
            executor.spin_once(timeout_sec=0.05)
        assert agent.brain._proximity is not None, 'no scan reached the brain'
        offsets, radii = agent.brain._proximity
        assert offsets.tolist() == [[1.0, -0.5]] and radii.tolist() == [0.45]
        # Stamped on the agent's clock, as ranges are.
        assert abs(agent.brain._proximity_at - agent._now()) < 5.0

        lines = []

        class Logger:
            def error(self, text, **kwargs):
                lines.append((text, kwargs))

        agent.get_logger = Logger   # the node's logger, for this one call
        at = agent.brain._proximity_at
        agent.on_proximity_array(ProximityArray(receiver=3, x=[1.0], y=[2.0], radius=[]))
        del agent.get_logger
        assert agent.brain._proximity_at == at and agent.brain._proximity is not None
        ((text, kwargs),) = lines
        assert 'proximity' in text and '1 x, 1 y and 0 radius' in text
        assert kwargs.get('throttle_duration_sec', 0) > 0
    finally:
        executor.shutdown()
        agent.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown(context=context)
