"""The standard interfaces' conversions (REP 103/105): an agent's estimate as
nav_msgs/Odometry and TF, its setpoint as a body-frame cmd_vel, the simulator's truth
as TF under its own prefix, and the tf2_msgs stand-in equal to upstream's."""

from __future__ import annotations

import json
import math
import pathlib

import numpy as np
import pytest

pytest.importorskip('nav_msgs')
pytest.importorskip('tf2_msgs')

from swarm_agent.brain import Snapshot  # noqa: E402
from swarm_agent.conversions import (  # noqa: E402
    Heading,
    map_to_body,
    setpoint_to_twist,
    snapshot_to_odometry,
    snapshot_to_transform,
    yaw_of,
    yaw_quaternion,
)
from swarm_bridge import protocol  # noqa: E402

# Upstream Jazzy tf2_msgs/msg/TFMessage (ros2/geometry2): the RIHS01 hash every ROS 2
# tool checks against; a stand-in with another definition would not be read by them.
UPSTREAM_TFMESSAGE_HASH = \
    'RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087'


def _snapshot(position=(1.0, -2.0), velocity=(0.3, 0.1), covariance=None) -> Snapshot:
    if covariance is None:
        # Position and velocity blocks with a cross term each, and position-velocity
        # correlation, as a Kalman filter's P of [x, y, vx, vy] (thesis 3.1.4).
        covariance = np.array([[4.0, 0.5, 0.2, 0.0], [0.5, 1.0, 0.0, 0.1],
                               [0.2, 0.0, 0.09, 0.01], [0.0, 0.1, 0.01, 0.04]])
    return Snapshot(agent_id=7, agent_type=2, is_beacon=False, mode=0,
                    position=np.array(position), velocity=np.array(velocity),
                    covariance=covariance, goal_id=-1, goal_version=0, assignment_round=0,
                    assignment_digest=0, rows_used=0, settled=False)


def _cov(values) -> np.ndarray:
    return np.array(values, dtype=float).reshape(6, 6)


def test_map_aligned_odometry_is_the_estimate_and_its_covariance():
    snap = _snapshot()
    odom = snapshot_to_odometry(snap)
    assert (odom.header.frame_id, odom.child_frame_id) == ('map', 'agent_7/base_link')
    p = odom.pose.pose
    assert (p.position.x, p.position.y, p.position.z) == (1.0, -2.0, 0.0)
    assert (p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w) == (
        0.0, 0.0, 0.0, 1.0)
    pose_cov, twist_cov = _cov(odom.pose.covariance), _cov(odom.twist.covariance)
    assert np.array_equal(pose_cov[:2, :2], snap.covariance[:2, :2])
    # Body axes = map axes: the twist is the map-frame velocity, its covariance P[2:4, 2:4].
    assert (odom.twist.twist.linear.x, odom.twist.twist.linear.y) == (0.3, 0.1)
    assert np.allclose(twist_cov[:2, :2], snap.covariance[2:4, 2:4], atol=1e-15)
    # Planar, heading by definition: everything else is exactly zero.
    pose_cov[:2, :2] = 0.0
    twist_cov[:2, :2] = 0.0
    assert not pose_cov.any() and not twist_cov.any()


def test_a_measured_heading_rotates_the_twist_and_its_covariance_into_the_body():
    # Facing north (yaw +90 deg, REP 103): moving east is moving to the robot's right.
    snap = _snapshot(velocity=(0.3, 0.0), covariance=np.diag([4.0, 1.0, 0.09, 0.01]))
    heading = Heading(yaw=math.pi / 2, yaw_std=0.05, rate=0.2, rate_std=0.1)
    odom = snapshot_to_odometry(snap, heading=heading)
    q = odom.pose.pose.orientation
    assert (q.z, q.w) == pytest.approx((math.sqrt(0.5), math.sqrt(0.5)))
    v = odom.twist.twist
    assert (v.linear.x, v.linear.y, v.angular.z) == pytest.approx((0.0, -0.3, 0.2), abs=1e-12)
    pose_cov, twist_cov = _cov(odom.pose.covariance), _cov(odom.twist.covariance)
    assert pose_cov[0, 0] == 4.0 and pose_cov[1, 1] == 1.0      # the pose stays in map
    assert pose_cov[5, 5] == pytest.approx(0.05 ** 2)
    # body x is map y (variance 0.01), body y is map -x (variance 0.09)
    assert np.allclose(twist_cov[:2, :2], np.diag([0.01, 0.09]), atol=1e-15)
    assert twist_cov[5, 5] == pytest.approx(0.1 ** 2)


def test_transform_places_the_body_frame_at_the_estimate():
    tf = snapshot_to_transform(_snapshot(), heading=Heading(yaw=-0.7))
    assert (tf.header.frame_id, tf.child_frame_id) == ('map', 'agent_7/base_link')
    t = tf.transform.translation
    assert (t.x, t.y, t.z) == (1.0, -2.0, 0.0)
    assert yaw_of(tf.transform.rotation) == pytest.approx(-0.7)


@pytest.mark.parametrize('yaw', [0.0, 0.4, math.pi / 2, -2.5, math.pi])
def test_body_frame_setpoint_rotated_back_is_the_map_setpoint(yaw):
    twist = setpoint_to_twist((0.02, -0.03), Heading(yaw=yaw))
    c, s = math.cos(yaw), math.sin(yaw)
    vx, vy = twist.linear.x, twist.linear.y
    assert (c * vx - s * vy, s * vx + c * vy) == pytest.approx((0.02, -0.03), abs=1e-15)
    assert twist.angular.z == 0.0
    assert yaw_of(yaw_quaternion(yaw)) == pytest.approx(math.remainder(yaw, math.tau))


def test_map_aligned_setpoint_is_the_map_setpoint_exactly():
    twist = setpoint_to_twist((-0.25, 0.125))
    assert (twist.linear.x, twist.linear.y) == (-0.25, 0.125)


@pytest.mark.parametrize('yaw', [0.0, 0.5236, -2.0])
def test_the_bridge_sends_the_body_frame_setpoint_as_is(yaw):
    # What the board gets from a body-frame cmd_vel is what the map-frame setpoint of the
    # same motion gave when the bridge rotated it by the camera yaw itself.
    body = map_to_body(0.02, -0.01, yaw)
    assert protocol.body_command(*body, 0.035, 3) == protocol.command_for(
        0.02, -0.01, yaw, 0.035, 3)


def test_tf2_msgs_stand_in_has_upstreams_type_hash():
    from ament_index_python.packages import get_package_share_directory

    share = pathlib.Path(get_package_share_directory('tf2_msgs'))
    description = json.loads((share / 'msg' / 'TFMessage.json').read_text())
    hashes = {h['type_name']: h['hash_string'] for h in description['type_hashes']}
    assert hashes['tf2_msgs/msg/TFMessage'] == UPSTREAM_TFMESSAGE_HASH
