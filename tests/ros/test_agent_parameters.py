"""The brain's tunables are ROS parameters of agent_node (generated from its
configuration dataclasses): declared with descriptions and ranges, live ones applied at
run time with a visible effect, read-only and out-of-range ones refused, and a node
given a bad parameter prints one line and exits 2."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time

import pytest

rclpy = pytest.importorskip('rclpy')

from geometry_msgs.msg import PoseWithCovarianceStamped, Twist  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile  # noqa: E402
from spin import beacon_agent  # noqa: E402

from swarm_common import qos  # noqa: E402
from swarm_common.conversions import goals_to_msg, shape_to_msg  # noqa: E402
from swarm_common.goals import Goal  # noqa: E402
from swarm_common.shapes import load_shape  # noqa: E402
from swarm_msgs.msg import FormationShape, GoalArray  # noqa: E402


@pytest.fixture
def beacon():
    """A beacon agent 13 m west of its only goal, fixed by GPS, with a probe node."""
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    agent, probe = beacon_agent(context, executor)
    speeds: list[float] = []
    probe.create_subscription(Twist, '/agent_5/cmd_vel',
                              lambda m: speeds.append(math.hypot(m.linear.x, m.linear.y)),
                              QoSProfile(**qos.SENSOR))
    latched = QoSProfile(**qos.LATCHED)
    probe.create_publisher(FormationShape, '/swarm/shape', latched).publish(
        shape_to_msg(load_shape('circle_314'), 1))
    probe.create_publisher(GoalArray, '/swarm/goals', latched).publish(
        goals_to_msg([Goal(0, 2, 3.0, 0.0, 0.3)], 1, 1, 'bubble'))
    gps = probe.create_publisher(PoseWithCovarianceStamped, '/agent_5/gps',
                                 QoSProfile(**qos.SENSOR))

    def spin_until(done, seconds: float = 20.0) -> bool:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            fix = PoseWithCovarianceStamped()
            fix.pose.pose.position.x = -10.0
            fix.pose.covariance[0] = fix.pose.covariance[7] = 0.01
            gps.publish(fix)
            executor.spin_once(timeout_sec=0.05)
            if done():
                return True
        return False

    yield agent, speeds, spin_until
    executor.shutdown()
    agent.destroy_node()
    probe.destroy_node()
    rclpy.try_shutdown(context=context)


def test_generated_parameters_are_declared_with_range_and_mutability(beacon):
    agent, _, _ = beacon
    gate = agent.describe_parameter('localization.gate')
    assert gate.description and not gate.read_only
    assert gate.floating_point_range[0].from_value == 1.0
    assert gate.floating_point_range[0].to_value == 1000.0
    ttl = agent.describe_parameter('dsdv.default_ttl')
    assert ttl.read_only, 'the router is built at start: its timers cannot change live'
    assert (ttl.integer_range[0].from_value, ttl.integer_range[0].to_value) == (1, 255)
    assert agent.get_parameter('setpoint.v_max').value == 0.5   # the dataclass default
    assert agent.describe_parameter('agent_id').read_only


def test_a_live_parameter_changes_the_running_brain(beacon):
    agent, speeds, spin_until = beacon
    # 13 m from the goal the setpoint saturates at v_max (3.2.4): 0.5 m/s by default.
    assert spin_until(lambda: speeds and speeds[-1] > 0.45), 'no saturated setpoint'
    assert max(speeds) <= 0.5 + 1e-9
    result = agent.set_parameters([Parameter('setpoint.v_max', value=0.2)])[0]
    assert result.successful, result.reason
    assert agent.brain.config.setpoint.v_max == 0.2
    before = len(speeds)
    assert spin_until(lambda: len(speeds) > before and abs(speeds[-1] - 0.2) < 1e-6), \
        f'the setpoint did not follow the new v_max: {speeds[before:]}'


def test_read_only_and_out_of_range_changes_are_refused(beacon):
    agent, _, _ = beacon
    ttl = agent.set_parameters([Parameter('dsdv.default_ttl', value=8)])[0]
    assert not ttl.successful and 'read-only' in ttl.reason
    gate = agent.set_parameters([Parameter('localization.gate', value=5000.0)])[0]
    assert not gate.successful
    assert agent.brain.config.localization.gate == 13.8
    # A change that breaks a cross-field rule of the config is refused whole.
    hold = agent.set_parameters([Parameter('hold_radius', value=2.0)])[0]
    assert not hold.successful and 'resume_radius' in hold.reason
    assert agent.brain.config.hold_radius == 0.3


def _start(module: str, *args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    return subprocess.run([sys.executable, '-m', module, '--ros-args', *args],
                          capture_output=True, text=True, timeout=60, env=env)


@pytest.mark.parametrize('module,args,names', [
    ('swarm_agent.agent_node', ['-p', 'agent_type:=7'], 'type 7'),
    ('swarm_agent.agent_node', ['-p', 'localization.gate:=5000.0'], 'localization.gate'),
    ('swarm_agent.agent_node', ['-p', 'method:=foo'], 'foo'),
    ('swarm_agent.composed_node', ['-p', 'fleet_file:=/nonexistent/fleet.yaml'],
     '/nonexistent/fleet.yaml'),
])
def test_a_bad_parameter_is_one_line_and_exit_2(module, args, names):
    proc = _start(module, *args)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert 'Traceback' not in proc.stderr + proc.stdout
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and names in lines[0], proc.stderr
