"""bridge_node in-process drives an emulated robot over a pty: wheels match eqs.
5.1-5.3 for a cmd_vel, and the robot stops once the agent stops publishing."""

from __future__ import annotations

import math
import time

import pytest

rclpy = pytest.importorskip('rclpy')

from geometry_msgs.msg import PoseStamped, Twist  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from swarm_bridge import protocol  # noqa: E402
from swarm_bridge.bridge_node import BridgeNode, SENSOR_QOS, STATE_QOS  # noqa: E402
from swarm_bridge.emulator import EmulatedRadio, PtyEmulator  # noqa: E402
from swarm_common.fleet import load_fleet  # noqa: E402


def test_bridge_node_drives_an_emulated_robot_and_stops_it():
    robot = load_fleet()[3]
    emu = PtyEmulator(EmulatedRadio.for_fleet([robot.address]))
    board = emu.radio.boards[robot.address]
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    node = BridgeNode(context=context, parameter_overrides=[
        Parameter('port', value=emu.port), Parameter('agents', value=str(robot.id))])
    probe = rclpy.create_node('probe', context=context)
    executor.add_node(node)
    executor.add_node(probe)
    wheels: list[JointState] = []
    k = robot.id
    probe.create_subscription(JointState, f'/agent_{k}/wheel_states', wheels.append,
                              QoSProfile(**STATE_QOS))
    cmd_pub = probe.create_publisher(Twist, f'/agent_{k}/cmd_vel', QoSProfile(**SENSOR_QOS))
    pose_pub = probe.create_publisher(PoseStamped, f'/agent_{k}/pose', QoSProfile(**SENSOR_QOS))
    yaw = math.radians(-60.0)
    pose = PoseStamped()
    pose.pose.orientation.z, pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    cmd = Twist()
    cmd.linear.x, cmd.linear.y = 0.02, -0.01
    # cmd_vel is in the robot's body frame (REP 103): sent as is, whatever the heading
    speed, alpha = protocol.body_to_polar(0.02, -0.01)
    expected = protocol.mix_fixed(*protocol.quantize(speed, alpha))[0]
    try:
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline and not (
                tuple(board.rates) == expected and wheels and any(wheels[-1].velocity)):
            pose_pub.publish(pose)
            cmd_pub.publish(cmd)
            executor.spin_once(timeout_sec=0.01)
            emu.pump(time.monotonic())
        assert tuple(board.rates) == expected, 'the robot never got the command'
        for got, want in zip(board.wheel_speeds(), protocol.wheel_speeds(speed, alpha)):
            assert abs(got - want) < 2e-4
        assert wheels and list(wheels[-1].name) == list(protocol.WHEEL_NAMES)
        # the agent falls silent: the bridge's watchdog (or the board's) stops the robot
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline and any(board.rates):
            pose_pub.publish(pose)
            executor.spin_once(timeout_sec=0.01)
            emu.pump(time.monotonic())
        assert board.rates == [0, 0, 0]
        assert node.bridge.counters['watchdog_stops'] >= 1
    finally:
        executor.shutdown()
        node.shutdown()
        node.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown(context=context)
        emu.close()


def test_a_missing_port_is_logged_and_the_node_keeps_running():
    context = rclpy.Context()
    rclpy.init(context=context)
    node = BridgeNode(context=context, parameter_overrides=[
        Parameter('port', value='/dev/does-not-exist-swarm'), Parameter('agents', value='0')])
    try:
        assert node.serial is None and node.bridge.counters['port_errors'] == 1
        node._reopen()
        node._on_poll()
        assert node.bridge.counters['port_errors'] == 2
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)
