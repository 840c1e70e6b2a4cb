"""camera_sim_node: the overhead E/O camera of thesis 5.1 for the hardware-in-the-loop world.

Wiring (drawing and frame timing in :mod:`swarm_bridge.camera_render`):

  truth/agent_K/pose   geometry_msgs/PoseStamped: the boards' true poses that
                       hil_world_node publishes at its camera_rate_hz, one stamp per tick
  camera/image_raw     sensor_msgs/Image (bgr8) of the arena from above (covers, floor,
                       corner markers, lighting gradient, blur, noise), stamped with the
                       capture time and published ``camera_latency_s`` after it; reliable,
                       depth 1 (best effort lost 15-40 % of the 0.9 MB frames in bursts of
                       up to 1.7 s on this loaded 2-core machine): camera_tracker_node
                       (``image_reliable``) turns it into ``agent_K/pose``

A frame is captured when every robot's true pose of one tick has arrived, at that tick's
stamp, at most ``camera_rate_hz`` a second (:class:`~swarm_bridge.camera_render.SimCamera`).
The camera runs in a process of its own so that rendering its frames takes no time from
hil_world_node's radio medium. Parameters: PARAMETERS below, defaults equal to
config/hil.yaml's camera_* values.
"""

from __future__ import annotations

import os
import sys

from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.time import Time
from sensor_msgs.msg import Image

from swarm_agent.conversions import yaw_of
from swarm_bridge.camera_render import (
    CameraRenderer,
    Cover,
    sim_camera_config,
    SIM_CAMERA_PARAMETERS,
    SimCamera,
)
from swarm_bridge.image_msgs import image_to_msg
from swarm_common import qos
from swarm_common.fleet import load_cover_colors, load_fleet
from swarm_common.ros_support import run_node

PARAMETERS = {
    'fleet_file': ('', 'Fleet YAML: ids, cover colours and radii (default: config/fleet.yaml)'),
    **SIM_CAMERA_PARAMETERS,
    'publish_period': (0.005, 'Seconds between checks for frames whose latency has passed'),
}


class CameraSimNode(Node):
    """Renders the true poses as overhead images; see the module docstring."""

    def __init__(self, **kwargs) -> None:
        super().__init__('hil_camera', **kwargs)
        for name, (default, text) in PARAMETERS.items():
            self.declare_parameter(name, default, ParameterDescriptor(description=text))
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        if p['publish_period'] <= 0.0:
            raise ValueError(f'publish_period {p["publish_period"]}: must be > 0 s')
        fleet = p['fleet_file'] or None
        robots = load_fleet(fleet, hardware=True)
        colors = load_cover_colors(fleet)
        self._covers = {r.id: (colors[r.color], r.radius) for r in robots}
        self._camera = SimCamera(CameraRenderer(sim_camera_config(p)))
        self._poses: dict[int, tuple[int, float, float, float]] = {}
        self._captured_ns = -1
        self._image_pub = self.create_publisher(
            Image, 'camera/image_raw', QoSProfile(depth=1, reliability=1, durability=2))
        sensor = QoSProfile(**qos.SENSOR)
        for k in self._covers:
            self.create_subscription(PoseStamped, f'truth/agent_{k}/pose',
                                     lambda msg, k=k: self._on_truth(k, msg), sensor)
        self.create_timer(p['publish_period'], self._publish)
        self.get_logger().info(f'rendering {len(robots)} robots at {p["camera_rate_hz"]} '
                               f'frames/s, {p["camera_latency_s"]} s latency')

    def _on_truth(self, k: int, msg: PoseStamped) -> None:
        stamp = Time.from_msg(msg.header.stamp).nanoseconds
        self._poses[k] = (stamp, msg.pose.position.x, msg.pose.position.y,
                          yaw_of(msg.pose.orientation))
        if stamp <= self._captured_ns or len(self._poses) < len(self._covers) or any(
                s != stamp for s, *_ in self._poses.values()):
            return
        self._captured_ns = stamp
        self._camera.capture(stamp * 1e-9, [Cover(*self._covers[j], x, y, yaw)
                                            for j, (_, x, y, yaw) in self._poses.items()])

    def _publish(self) -> None:
        now = self.get_clock().now().nanoseconds * 1e-9
        for captured, image in self._camera.ready(now):
            stamp = Time(nanoseconds=int(captured * 1e9)).to_msg()
            self._image_pub.publish(image_to_msg(image, stamp, 'camera'))


def main(args: list[str] | None = None) -> None:
    """Run camera_sim_node until interrupted."""
    run_node(CameraSimNode, 'camera_sim_node', args)


if __name__ == '__main__':
    os.environ.setdefault('PYTHONUNBUFFERED', '1')
    sys.exit(main())
