"""hw_agent_node: swarm_agent's agent_node with the distances of the 2 x 2 m arena (ch. 5).

The agent brain's parking hysteresis and collision margins are sized for the 100 m
simulation with its 2 m LPS noise (BrainConfig: park within 0.3 m of the goal, resume
beyond 0.8 m; collision avoidance keeps 0.3 m beyond the summed coverage radii). In
the hardware arena every goal is closer than 0.8 m and the goals of Table 5.1's robots
are about 0.3 m apart, so with those values the robots never leave their start (parked)
or are pushed off their goals by their neighbours. A camera pose is good to about 1 cm,
so this node runs the unchanged AgentNode and only sets those distances (PARAMETERS,
defaults equal to config/hw_agent.yaml) on its brain before it starts. Everything else
(partition, consensus assignment, setpoint of thesis 3.2.4, mesh) is agent_node's.

Camera poses. The thesis's robots have no IMU and no LPS (5.1): the camera position is
their position. agent_node feeds it to the Kalman filter of 3.1.4 as a GPS fix, but with
no accelerometer the filter never predicts, its covariance only shrinks and the estimate
lags the robot more and more (measured: 0.25 m behind after 20 s, so robots overshoot
their goals). This node therefore sets the estimate from each camera pose: position as
measured, velocity as the camera displacement over ``velocity_window`` seconds. A robot
the camera has not seen for ``pose_timeout`` seconds keeps its last estimate, LOST, with
an uncertainty that grows as far as it can have driven since (``setpoint_v_max`` times
the time without a pose), so its state says how little its position is known.

Stopgap: once agent_node declares these parameters itself, launch agent_node with
config/hw_agent.yaml instead.
"""

from __future__ import annotations

from collections import deque
import sys

from geometry_msgs.msg import PoseStamped
import numpy as np
from rcl_interfaces.msg import ParameterDescriptor
import rclpy
from rclpy.executors import ExternalShutdownException

from swarm_agent.agent_node import AgentNode, make_executor
from swarm_agent.setpoint import SetpointParams

PARAMETERS = {
    'hold_radius': (0.02, 'Within this distance of its goal the robot parks, m'),
    'resume_radius': (0.06, 'A parked robot moves again beyond this distance, m'),
    'setpoint_gain': (0.4, 'Setpoint speed per metre of remaining path, 1/s (3.2.4)'),
    'setpoint_v_max': (0.035, 'Setpoint speed limit, m/s (the bridge max_speed)'),
    'avoid_rate': (1.0, 'A pair closes its gap at most this fast per metre of gap, 1/s'),
    'avoid_buffer': (0.0, 'Gap kept free beyond the summed coverage radii, m'),
    'yield_margin': (0.03, 'A parked robot steps aside for one closer than this beyond '
                           'the buffer, m (goals are about 0.34 m apart)'),
    'arrive_radius': (0.005, 'Closer than this to the goal the setpoint is zero, m'),
    'velocity_window': (0.5, 'Camera displacement over this many seconds is the velocity'),
    'pose_timeout': (0.5, 'Without a camera pose for this long the robot is LOST, s'),
}


class HwAgentNode(AgentNode):
    """AgentNode whose brain uses the arena's distances; see the module docstring."""

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        for name, (default, text) in PARAMETERS.items():
            self.declare_parameter(name, default, ParameterDescriptor(description=text))
        p = {name: float(self.get_parameter(name).value) for name in PARAMETERS}
        if not 0.0 < p['hold_radius'] < p['resume_radius']:
            raise ValueError(f'hold_radius {p["hold_radius"]} must be positive and below '
                             f'resume_radius {p["resume_radius"]}')
        config = self.brain.config
        config.hold_radius = p['hold_radius']
        config.resume_radius = p['resume_radius']
        config.setpoint = SetpointParams(
            gain=p['setpoint_gain'], v_max=p['setpoint_v_max'], avoid_rate=p['avoid_rate'],
            avoid_buffer=p['avoid_buffer'], yield_margin=p['yield_margin'],
            arrive_radius=p['arrive_radius'])
        self._window = p['velocity_window']
        self._pose_timeout = p['pose_timeout']
        self._v_max = p['setpoint_v_max']
        self._poses: deque[tuple[float, float, float]] = deque()
        self._stale = False
        self.create_timer(0.1, self._check_pose_age)
        self.get_logger().info(f'arena distances: park {p["hold_radius"]} m, resume '
                               f'{p["resume_radius"]} m, v_max {p["setpoint_v_max"]} m/s')

    def _on_pose(self, msg: PoseStamped) -> None:
        """Camera pose: the estimate is the measurement (see the module docstring)."""
        t = self._now()
        x, y = msg.pose.position.x, msg.pose.position.y
        if not (np.isfinite(x) and np.isfinite(y)):
            return
        self._poses.append((t, x, y))
        while len(self._poses) > 2 and t - self._poses[1][0] >= self._window:
            self._poses.popleft()
        t0, x0, y0 = self._poses[0]
        velocity = (np.array([x - x0, y - y0]) / (t - t0)) if t - t0 > 1e-3 else np.zeros(2)
        std = self.params['external_pose_std']
        self.brain.localizer.set_state((x, y), velocity, std, 2 * std / self._window)
        if self._stale:
            self._stale = False
            self.get_logger().info('camera pose back')

    def _check_pose_age(self) -> None:
        """Hold the last estimate with a growing uncertainty while no pose comes."""
        if not self._poses:
            return
        age = self._now() - self._poses[-1][0]
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
    """Run one hardware agent (``ros2 run swarm_bridge hw_agent_node``)."""
    rclpy.init(args=args)
    node = HwAgentNode()
    try:
        rclpy.spin(node, executor=make_executor())
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        try:
            node.stop()
        except Exception:  # noqa: BLE001 - the context may already be gone
            pass
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main(sys.argv)
