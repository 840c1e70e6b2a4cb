"""The simulator's ground truth as TF: under its own prefix, beside the estimates."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip('tf2_msgs')

from swarm_agent.conversions import yaw_of  # noqa: E402
from swarm_common.fleet import RobotSpec  # noqa: E402
from swarm_sim.conversions import stamp_of, truth_tf  # noqa: E402
from swarm_sim.world_model import TruthSample  # noqa: E402


def test_truth_frames_carry_the_prefix_true_pose_and_only_living_robots():
    fleet = [RobotSpec(0, 1, True, 0.0, 0.0), RobotSpec(4, 2, False, 0.0, 0.0),
             RobotSpec(9, 3, False, 0.0, 0.0)]
    truth = TruthSample(t=12.5, positions=np.array([[1.0, 2.0], [-3.0, 0.5], [7.0, 7.0]]),
                        velocities=np.zeros((3, 2)), yaws=np.array([0.0, 1.2, -3.0]),
                        alive=np.array([True, True, False]), min_separation=1.0)
    msg = truth_tf(stamp_of(12.5), fleet, truth)
    assert [t.child_frame_id for t in msg.transforms] == [
        'truth/agent_0/base_link', 'truth/agent_4/base_link']   # robot 9 is dead
    for tf, i in zip(msg.transforms, (0, 1)):
        assert tf.header.frame_id == 'map'
        assert (tf.header.stamp.sec, tf.header.stamp.nanosec) == (12, 500_000_000)
        t = tf.transform.translation
        assert (t.x, t.y, t.z) == (*truth.positions[i], 0.0)
        assert yaw_of(tf.transform.rotation) == pytest.approx(truth.yaws[i])
        q = tf.transform.rotation
        assert math.hypot(q.x, q.y, q.z, q.w) == pytest.approx(1.0)
