"""Standard interfaces on the ROS graph (REP 103/105): an agent's ``odom``
(nav_msgs/Odometry) and its TF ``map -> agent_K/base_link`` carry its estimate and
covariance, per robot in composed mode too; a camera heading turns ``cmd_vel`` into the
robot's body frame; the simulator's truth is on /tf as ``truth/agent_K/base_link``."""

from __future__ import annotations

import math

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')
pytest.importorskip('tf2_msgs')

from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Twist  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile  # noqa: E402
from spin import ros_context, sim_world, spin_until  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

from swarm_agent.agent_node import AgentNode, make_executor  # noqa: E402
from swarm_agent.brain_config import BrainConfigError  # noqa: E402
from swarm_agent.composed_node import ComposedAgents  # noqa: E402
from swarm_agent.conversions import yaw_of, yaw_quaternion  # noqa: E402
from swarm_agent.hw_agent_node import HwAgentNode  # noqa: E402
from swarm_common import qos  # noqa: E402
from swarm_common.conversions import goals_to_msg, shape_to_msg  # noqa: E402
from swarm_common.fleet import RobotSpec, save_fleet  # noqa: E402
from swarm_common.goals import Goal  # noqa: E402
from swarm_common.shapes import load_shape  # noqa: E402
from swarm_msgs.msg import AgentState, FormationShape, GoalArray  # noqa: E402

STATE = QoSProfile(**qos.STATE)


def _stamp(msg) -> tuple[int, int]:
    return msg.header.stamp.sec, msg.header.stamp.nanosec


def _frames(tf_messages) -> dict[str, object]:
    """The latest transform of each child frame heard on /tf."""
    return {t.child_frame_id: t for m in tf_messages for t in m.transforms}


def test_agent_odom_and_tf_carry_its_estimate_and_covariance():
    with ros_context() as (context, executor):
        agent = AgentNode('agent_5', context=context, parameter_overrides=[
            Parameter('agent_id', value=5), Parameter('agent_type', value=2),
            Parameter('is_beacon', value=True), Parameter('initial_x', value=-10.0),
            Parameter('initial_y', value=0.0), Parameter('state_rate_hz', value=10.0)])
        probe = rclpy.create_node('probe', context=context)
        executor.add_node(agent)
        executor.add_node(probe)
        states, odoms, tfs = [], [], []
        probe.create_subscription(AgentState, '/agent_5/state', states.append, STATE)
        probe.create_subscription(Odometry, '/agent_5/odom', odoms.append, STATE)
        probe.create_subscription(TFMessage, '/tf', tfs.append, QoSProfile(depth=100))
        gps = probe.create_publisher(PoseWithCovarianceStamped, '/agent_5/gps',
                                     QoSProfile(**qos.SENSOR))
        fix = PoseWithCovarianceStamped()
        fix.pose.pose.position.x, fix.pose.pose.position.y = -9.0, 0.5
        fix.pose.covariance[0] = fix.pose.covariance[7] = 0.04

        def fixed() -> bool:   # a state after the fix moved the estimate, odom and TF of it
            gps.publish(fix)
            return (any(s.position[0] > -9.9 for s in states) and len(odoms) >= 3
                    and 'agent_5/base_link' in _frames(tfs))

        try:
            assert spin_until(executor, fixed, 30.0, step=0.05), (len(states), len(odoms))
            by_stamp = {_stamp(s): s for s in states}
            tf_by_stamp = {_stamp(t): t for m in tfs for t in m.transforms}
            pairs = [(o, by_stamp[_stamp(o)], tf_by_stamp.get(_stamp(o))) for o in odoms
                     if _stamp(o) in by_stamp]
            assert pairs, 'odom and state of one snapshot share a stamp'
            assert any(tf is not None for *_, tf in pairs), 'and the TF of it too'
            for odom, state, tf in pairs:
                assert (odom.header.frame_id, odom.child_frame_id) == ('map',
                                                                       'agent_5/base_link')
                pose = odom.pose.pose
                assert (pose.position.x, pose.position.y) == tuple(state.position)
                assert (pose.orientation.z, pose.orientation.w) == (0.0, 1.0)  # map-aligned
                assert (odom.twist.twist.linear.x, odom.twist.twist.linear.y) == tuple(
                    state.velocity)
                p = np.array(state.covariance).reshape(4, 4)
                c = np.array(odom.pose.covariance).reshape(6, 6)
                assert np.array_equal(c[:2, :2], p[:2, :2]) and c[0, 0] > 0.0
                tw = np.array(odom.twist.covariance).reshape(6, 6)
                assert np.array_equal(tw[:2, :2], p[2:4, 2:4])
                if tf is not None:
                    assert tf.header.frame_id == 'map'
                    assert (tf.transform.translation.x, tf.transform.translation.y) == tuple(
                        state.position)
        finally:
            agent.destroy_node()
            probe.destroy_node()


def test_camera_heading_puts_cmd_vel_and_odom_in_the_robots_body_frame():
    """A hardware robot facing north (camera yaw +90 deg) whose goal lies east: its
    setpoint points east, which is the robot's right (-y in the body frame)."""
    with ros_context(make_executor) as (context, executor):
        agent = HwAgentNode(node_name='agent_3', context=context,
                            parameter_overrides=[
                                Parameter('agent_id', value=3), Parameter('agent_type', value=2),
                                Parameter('external_pose', value=True),
                                Parameter('state_rate_hz', value=10.0)])
        probe = rclpy.create_node('probe', context=context)
        executor.add_node(agent)
        executor.add_node(probe)
        cmds, odoms = [], []
        probe.create_subscription(Twist, '/agent_3/cmd_vel', cmds.append,
                                  QoSProfile(**qos.SENSOR))
        probe.create_subscription(Odometry, '/agent_3/odom', odoms.append, STATE)
        latched = QoSProfile(**qos.LATCHED)
        probe.create_publisher(FormationShape, '/swarm/shape', latched).publish(
            shape_to_msg(load_shape('circle_314'), 1))
        probe.create_publisher(GoalArray, '/swarm/goals', latched).publish(
            goals_to_msg([Goal(0, 2, 3.0, 0.0, 0.3)], 1, 1, 'bubble'))
        poses = probe.create_publisher(PoseStamped, '/agent_3/pose', QoSProfile(**qos.SENSOR))
        camera = PoseStamped()
        camera.pose.orientation = yaw_quaternion(math.pi / 2)

        def driving() -> bool:
            poses.publish(camera)
            return any(math.hypot(c.linear.x, c.linear.y) > 0.01 for c in cmds) and any(
                abs(yaw_of(o.pose.pose.orientation) - math.pi / 2) < 1e-9 for o in odoms)

        try:
            assert spin_until(executor, driving, 30.0, step=0.02), (cmds[-3:], len(odoms))
            cmd = next(c for c in reversed(cmds) if math.hypot(c.linear.x, c.linear.y) > 0.01)
            assert cmd.linear.y < 0.0 and abs(cmd.linear.x) < 0.05 * abs(cmd.linear.y), cmd
            odom = odoms[-1]
            assert odom.pose.covariance[35] == pytest.approx(0.05 ** 2)   # camera heading
        finally:
            agent.destroy_node()
            probe.destroy_node()


@pytest.mark.parametrize('value', [-0.1, math.nan])
def test_a_bad_heading_std_is_refused_with_its_name(value):
    with ros_context() as (context, _):
        with pytest.raises(BrainConfigError, match='external_heading_std must be a finite'):
            AgentNode('agent_1', context=context,
                      parameter_overrides=[Parameter('external_heading_std', value=value)])


@pytest.mark.parametrize('sensor_batch', [False, True])
def test_composed_agents_each_publish_odom_and_tf(tmp_path, sensor_batch):
    robots = [RobotSpec(0, 1, True, 0.0, 0.0), RobotSpec(1, 2, False, 4.0, -1.0),
              RobotSpec(2, 3, False, -3.0, 2.5)]
    fleet_file = tmp_path / 'fleet.yaml'
    save_fleet(fleet_file, robots)
    with ros_context(make_executor) as (context, executor):
        container = ComposedAgents(executor, context=context, parameter_overrides=[
            Parameter('fleet_file', value=str(fleet_file)),
            Parameter('sensor_batch', value=sensor_batch),
            Parameter('state_rate_hz', value=10.0)])
        executor.add_node(container)
        probe = rclpy.create_node('probe', context=context)
        executor.add_node(probe)
        odoms: dict[int, list[Odometry]] = {r.id: [] for r in robots}
        states: dict[int, list[AgentState]] = {r.id: [] for r in robots}
        tfs: list[TFMessage] = []
        for r in robots:
            probe.create_subscription(Odometry, f'/agent_{r.id}/odom', odoms[r.id].append,
                                      STATE)
            probe.create_subscription(AgentState, f'/agent_{r.id}/state',
                                      states[r.id].append, STATE)
        probe.create_subscription(TFMessage, '/tf', tfs.append, QoSProfile(depth=100))
        names = {f'agent_{r.id}/base_link' for r in robots}
        try:
            assert spin_until(executor, lambda: all(odoms.values()) and all(states.values())
                              and names <= set(_frames(tfs)), 30.0, step=0.05)
            frames = _frames(tfs)
            # one /tf message per state period for the whole process
            assert any(names <= {t.child_frame_id for t in m.transforms} for m in tfs)
            for r in robots:
                odom = odoms[r.id][-1]
                assert odom.child_frame_id == f'agent_{r.id}/base_link'
                # no sensor input here: the estimate is the deployment position
                assert (odom.pose.pose.position.x, odom.pose.pose.position.y) == (r.x, r.y)
                assert odom.pose.covariance[0] == states[r.id][-1].covariance[0] > 0.0
                t = frames[f'agent_{r.id}/base_link'].transform.translation
                assert (t.x, t.y) == (r.x, r.y)
        finally:
            container.destroy_all()
            container.destroy_node()
            probe.destroy_node()


def _world(tmp_path, robots):
    return sim_world(tmp_path, robots, 'tf_probe')


def test_sim_publishes_the_truth_as_tf_under_its_own_prefix(tmp_path):
    robots = [RobotSpec(0, 1, True, 0.0, 0.0), RobotSpec(1, 1, True, 6.0, 0.0),
              RobotSpec(2, 1, False, 12.0, 0.0)]
    with _world(tmp_path, robots) as (executor, sim, probe):
        tfs: list[TFMessage] = []
        probe.create_subscription(TFMessage, '/tf', tfs.append, QoSProfile(depth=100))
        names = {f'truth/agent_{r.id}/base_link' for r in robots}
        assert spin_until(executor, lambda: names <= set(_frames(tfs)), 30.0, step=0.05)
        frames = _frames(tfs)
        assert set(frames) == names      # truth only: no agents run here
        for r in robots:
            tf = frames[f'truth/agent_{r.id}/base_link']
            assert tf.header.frame_id == 'map'
            # placed exactly (placement_std_m 0), no force commanded: standing still
            t = tf.transform.translation
            assert (t.x, t.y) == pytest.approx((r.x, r.y), abs=1e-9)
