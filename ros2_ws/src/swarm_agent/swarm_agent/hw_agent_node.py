"""hw_agent_node: swarm_agent's agent_node on a real robot seen by the overhead camera (ch. 5).

The brain and its parameters are agent_node's; swarm_bridge's config/hw_agent.yaml sets
the distances of the 2 x 2 m arena on them (park within 2 cm of the goal, resume beyond
6 cm, 3.5 cm/s: the brain's defaults are sized for the 100 m simulation with its 2 m LPS
noise, and with them the robots would never leave their start). This node adds what a
robot without an IMU or LPS needs from the camera.

Camera poses. The thesis's robots have no IMU and no LPS (5.1): the camera position is
their position. agent_node feeds it to the Kalman filter of 3.1.4 as a GPS fix, but with
no accelerometer the filter never predicts, its covariance only shrinks and the estimate
lags the robot more and more (measured: 0.25 m behind after 20 s, so robots overshoot
their goals). This node therefore sets the estimate from each camera pose
(:class:`~swarm_agent.camera_pose.CameraPoseWindow`): velocity as the camera
displacement over ``velocity_window`` seconds of capture stamps, position as measured
predicted forward over the pose's age (its stamp is the frame's capture time; the
camera's latency is up to ``max_pose_age`` seconds, an older or unset stamp is taken as
the arrival time). A robot the camera has not seen for ``pose_timeout`` seconds keeps
its last estimate, LOST, with an uncertainty that grows as far as it can have driven
(``setpoint.v_max`` times the time without a pose), so its state says how little its
position is known.

Heading. The camera also measures each robot's yaw: it is the agent's heading
(``AgentNode.set_heading``), the body frame of its ``cmd_vel``, ``odom`` and TF (REP
103/105), with its rate over the same window, predicted over the pose's age as the
position is. A robot turns while it drives (the omni wheels' travel does not sum to zero,
eqs. 5.1-5.3), so ``cmd_vel`` goes out again whenever the setpoint seen from the new
heading changes; the bridge sends it to the board as is.
"""

from __future__ import annotations

import sys

from geometry_msgs.msg import PoseStamped
import numpy as np
from rcl_interfaces.msg import ParameterDescriptor

from swarm_agent.agent_node import AgentNode, make_executor
from swarm_agent.camera_pose import CameraPoseWindow
from swarm_agent.conversions import stamp_seconds, yaw_of
from swarm_common.ros_support import run_node

PARAMETERS = {
    'velocity_window': (0.5, 'Camera displacement over this many seconds is the velocity'),
    'pose_timeout': (0.5, 'Without a camera pose for this long the robot is LOST, s'),
    'max_pose_age': (0.3, 'Camera latency compensated at most (capture stamp to arrival), '
                          's; an older stamp counts as the arrival time'),
}


class HwAgentNode(AgentNode):
    """AgentNode whose estimate comes from camera poses; see the module docstring."""

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        for name, (default, text) in PARAMETERS.items():
            self.declare_parameter(name, default,
                                   ParameterDescriptor(description=text, read_only=True))
        p = {name: float(self.get_parameter(name).value) for name in PARAMETERS}
        for name, value in p.items():
            if not (np.isfinite(value) and value > 0.0):
                raise ValueError(f'parameter {name} must be a positive number of seconds, '
                                 f'got {value}: e.g. -p {name}:={PARAMETERS[name][0]}')
        self._window = p['velocity_window']
        self._pose_timeout = p['pose_timeout']
        self._poses = CameraPoseWindow(self._window, p['max_pose_age'])
        self._stale = False
        self.create_timer(0.1, self._check_pose_age)
        config = self.brain.config
        self.get_logger().info(f'arena distances: park {config.hold_radius} m, resume '
                               f'{config.resume_radius} m, v_max {config.setpoint.v_max} m/s')

    @property
    def _v_max(self) -> float:
        """How fast the robot can drive away from its last pose (setpoint.v_max)."""
        return self.brain.config.setpoint.v_max

    def _on_pose(self, msg: PoseStamped) -> None:
        """Camera pose: the estimate is the measurement predicted to now (module docstring)."""
        t = self._now()
        if not self._poses.add(stamp_seconds(msg.header.stamp), t, msg.pose.position.x,
                               msg.pose.position.y, yaw_of(msg.pose.orientation)):
            return
        est = self._poses.estimate(t)
        std = self.params['external_pose_std']
        self.brain.localizer.set_state(est.position, est.velocity, std, 2 * std / self._window)
        self.set_heading(est.yaw, est.rate,
                         2 * self.params['external_heading_std'] / self._window)
        if self._stale:
            self._stale = False
            self.get_logger().info('camera pose back')

    def _check_pose_age(self) -> None:
        """Hold the last estimate with a growing uncertainty while no pose comes."""
        last = self._poses.last_stamp
        if last is None:
            return
        age = self._now() - last
        if age < self._pose_timeout:
            return
        if not self._stale:
            self._stale = True
            self.get_logger().warning(
                f'no camera pose for {age:.1f} s: holding the last estimate, LOST, its '
                f'uncertainty growing at {self._v_max} m/s until the camera sees the robot')
        std = float(np.hypot(self.params['external_pose_std'], self._v_max * age))
        self.brain.localizer.hold(std, self._v_max)


def main(args: list[str] | None = None) -> None:
    """Run one hardware agent (``ros2 run swarm_agent hw_agent_node``)."""
    run_node(HwAgentNode, 'hw_agent_node', args, executor=make_executor,
             stop=HwAgentNode.stop)


if __name__ == '__main__':
    main(sys.argv)
