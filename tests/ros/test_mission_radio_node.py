"""mission_radio_node: the route adverts the mission's radio hears make the agents it
publishes on mission/alive; frames without the swarm key make none."""

from __future__ import annotations

import pytest

rclpy = pytest.importorskip('rclpy')

from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile  # noqa: E402
from spin import ros_context, spin_until  # noqa: E402
from std_msgs.msg import Int32MultiArray  # noqa: E402

from swarm_agent.agent_factory import swarm_keyring  # noqa: E402
from swarm_agent.conversions import frames_to_msg  # noqa: E402
from swarm_agent.dsdv import DsdvRouter  # noqa: E402
from swarm_agent.frame_auth import FrameAuth  # noqa: E402
from swarm_agent.mission_radio_node import MissionRadioNode  # noqa: E402
from swarm_common import qos  # noqa: E402
from swarm_msgs.msg import RadioPacketArray  # noqa: E402


def _adverts_of_agent_3(sealed: bool) -> list:
    """Agent 3's frames after it heard agent 4: its full dump has routes to 3 and 4."""
    three, four = DsdvRouter(3), DsdvRouter(4)
    for packet in four.tick(0.0):
        three.on_packet(0.0, packet)
    frames = three.tick(2.0)
    if sealed:
        auth = FrameAuth(swarm_keyring())
        frames = [auth.seal(p) for p in frames]
    return [(2.0, p) for p in frames]


@pytest.mark.parametrize('sealed', [True, False])
def test_the_radio_publishes_the_agents_it_holds_routes_to(sealed):
    with ros_context() as (context, executor):
        node = MissionRadioNode(context=context, parameter_overrides=[
            Parameter('type_counts', value='1:3,2:3'), Parameter('rate_hz', value=20.0)])
        probe = rclpy.create_node('probe', context=context)
        alive: list[list[int]] = []
        probe.create_subscription(Int32MultiArray, '/mission/alive',
                                  lambda m: alive.append(list(m.data)),
                                  QoSProfile(**qos.STATE))
        rx = probe.create_publisher(RadioPacketArray, '/mission/radio/rx',
                                    QoSProfile(**qos.RADIO))
        executor.add_node(node)
        executor.add_node(probe)
        try:
            assert spin_until(executor, lambda: bool(alive), timeout=20.0)
            assert alive[-1] == []
            assert spin_until(executor, lambda: rx.get_subscription_count() > 0, 10.0)
            rx.publish(frames_to_msg(_adverts_of_agent_3(sealed)))
            if sealed:
                assert spin_until(executor, lambda: alive[-1] == [3, 4], timeout=20.0)
            else:
                assert spin_until(executor, lambda: node.radio.auth.stats, timeout=20.0)
                count = len(alive)
                assert spin_until(executor, lambda: len(alive) > count + 2, timeout=20.0)
                assert alive[-1] == [] and sum(node.radio.auth.stats.values()) >= 1
        finally:
            node.destroy_node()
            probe.destroy_node()
