"""The rclpy-free QoS table matches rclpy's enums and builds valid profiles."""

import time

import pytest

rclpy = pytest.importorskip('rclpy')
rclpy_qos = pytest.importorskip('rclpy.qos')

from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402

from swarm_common import qos  # noqa: E402
from swarm_common.ros_support import lean_publisher, lean_subscription  # noqa: E402


def test_integers_match_rclpy_enums():
    assert qos.KEEP_LAST == rclpy_qos.QoSHistoryPolicy.KEEP_LAST.value
    assert qos.RELIABLE == rclpy_qos.QoSReliabilityPolicy.RELIABLE.value
    assert qos.BEST_EFFORT == rclpy_qos.QoSReliabilityPolicy.BEST_EFFORT.value
    assert qos.TRANSIENT_LOCAL == rclpy_qos.QoSDurabilityPolicy.TRANSIENT_LOCAL.value
    assert qos.VOLATILE == rclpy_qos.QoSDurabilityPolicy.VOLATILE.value


@pytest.mark.parametrize('name', ['LATCHED', 'SENSOR', 'COMMAND', 'IMU', 'RADIO', 'STATE'])
def test_profiles_build(name):
    profile = rclpy_qos.QoSProfile(**getattr(qos, name))
    assert profile.depth >= 1


@pytest.mark.parametrize('profile, delivered', [('COMMAND', True), ('SENSOR', False)])
def test_force_command_reaches_a_late_subscriber(profile, delivered):
    """A command sent before the simulator matched the agent still arrives with COMMAND.

    The simulator holds its clock until it has every agent's first command, and an
    agent's timers only fire when the clock moves: a lost first command was a deadlock
    for the start-up window. SENSOR (volatile) shows the loss that COMMAND prevents.
    """
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    agent = rclpy.create_node('agent', context=context)
    sim = rclpy.create_node('sim', context=context)
    executor.add_node(agent)
    executor.add_node(sim)
    got: list[WrenchStamped] = []
    try:
        qos_profile = rclpy_qos.QoSProfile(**getattr(qos, profile))
        publisher = lean_publisher(agent, WrenchStamped, '/agent_3/cmd_force', qos_profile)
        assert publisher.event_handlers == []  # no default QoS event waitables
        command = WrenchStamped()
        command.wrench.force.x = 7.0
        publisher.publish(command)
        executor.spin_once(timeout_sec=0.2)
        subscription = lean_subscription(sim, WrenchStamped, '/agent_3/cmd_force',
                                         got.append, qos_profile)
        assert subscription.event_handlers == []
        deadline = time.monotonic() + (5.0 if delivered else 2.0)
        while not got and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
    finally:
        executor.shutdown()
        agent.destroy_node()
        sim.destroy_node()
        rclpy.try_shutdown(context=context)
    assert [m.wrench.force.x for m in got] == ([7.0] if delivered else [])
