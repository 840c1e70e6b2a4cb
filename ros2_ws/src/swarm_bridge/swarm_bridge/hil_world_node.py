"""hil_world_node: the hardware of thesis ch. 5 without hardware (hardware in the loop).

Stands for everything outside the software under test:

- the robots and their coordinator XBee: an :class:`~swarm_bridge.emulator.EmulatedRadio`
  of firmware twins on a pseudo-terminal (bridge_node's ``port``; the node links the pty
  to ``port_link`` so a launcher knows it before starting the bridge). Each board
  integrates its own half-steps into a pose (forward kinematics of eqs. 5.1-5.3);
- the overhead E/O camera of thesis 5.1, at ``camera_rate_hz``: the boards' true poses
  go to ``truth/agent_K/pose`` (geometry_msgs/PoseStamped, map frame, yaw
  counter-clockwise; one stamp per tick; no agent reads them). With ``camera: truth``
  the world also publishes them as the camera's ``agent_K/pose``, optionally with
  Gaussian noise (``camera_noise_m``, seeded). With ``camera: image`` it publishes no
  ``agent_K/pose``: camera_sim_node, a process of its own, renders the true poses into
  ``camera/image_raw`` and camera_tracker_node turns the images into ``agent_K/pose``;
- the XBee mesh between the agents (Fig. 5.1): a frame on ``radio/tx`` goes through
  the simulator's radio medium (``swarm_bridge.hil_mesh``: range, line of sight,
  per-receiver loss, airtime and latency, ``radio_*`` parameters whose defaults are
  ``swarm_sim.medium.MediumConfig``'s) between the boards' poses, and what arrives is
  delivered on ``agent_K/radio/rx`` of its destination, or of every robot that heard
  it when broadcast.

Initial poses come from ``initial_poses`` (flat list x0,y0,yaw0,x1,... in fleet order,
yaw in degrees counter-clockwise). Parameters: PARAMETERS below, defaults equal to
config/hil.yaml. Runs on the wall clock, as real robots do.
"""

from __future__ import annotations

import os
import pathlib
import sys
import time

from geometry_msgs.msg import PoseStamped
import numpy as np
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import QoSProfile

from swarm_agent.conversions import frames_or_log, frames_to_msg, pose_stamped
from swarm_bridge.emulator import EmulatedRadio, PtyEmulator
from swarm_bridge.hil_mesh import HilMesh
from swarm_common import qos
from swarm_common.fleet import initial_poses, load_coordinator, load_fleet
from swarm_common.ros_support import run_node
from swarm_msgs.msg import RadioPacketArray
from swarm_sim.medium import MediumConfig

MEDIUM = MediumConfig()

PARAMETERS = {
    'fleet_file': ('', 'Fleet YAML (default: the package config/fleet.yaml)'),
    'port_link': ('', 'Symlink created to the pty for bridge_node (empty: none)'),
    'initial_poses': ([0.0], 'x,y,yaw_deg per robot in fleet order (default: a row)'),
    'camera_rate_hz': (10.0, 'Rate of the true poses (and of the camera poses of truth)'),
    'camera_noise_m': (0.0, 'Standard deviation of the camera position noise, m'),
    'camera_seed': (0, 'Seed of the camera noise'),
    'camera': ('truth', "truth: publish the boards' poses on /agent_K/pose; image: none "
                        '(camera_sim_node renders them for camera_tracker_node)'),
    'pump_period': (0.005, 'Seconds between serial transfers and board time steps'),
    'relay_radio': (True, 'Carry /radio/tx frames to the agents through the radio medium'),
    'radio_loss': (MEDIUM.loss, 'Per-receiver frame loss probability of the mesh'),
    'radio_range_m': (MEDIUM.range_m, 'Radio range of the mesh, m'),
    'radio_latency_s': (MEDIUM.latency_s, 'Propagation and processing delay of a frame, s'),
    'radio_seed': (0, 'Seed of the frame losses'),
}


class HilWorldNode(Node):
    """Emulated robots, their true poses and the mesh radio; see the module docstring."""

    def __init__(self, **kwargs) -> None:
        super().__init__('hil_world', **kwargs)
        for name, (default, text) in PARAMETERS.items():
            self.declare_parameter(name, default, ParameterDescriptor(description=text))
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        self.params = p
        self.robots = load_fleet(p['fleet_file'] or None, hardware=True)
        self._mesh = None
        if p['relay_radio']:
            try:
                self._mesh = HilMesh([r.id for r in self.robots], MediumConfig(
                    range_m=p['radio_range_m'], loss=p['radio_loss'],
                    latency_s=p['radio_latency_s']), p['radio_seed'])
            except ValueError as exc:
                raise ValueError(f'{exc}: set radio_loss, radio_range_m and radio_latency_s '
                                 'in config/hil.yaml or with --ros-args -p') from None
        # The boards obey only the coordinator their firmware was built for (PROTOCOL.md).
        self.emulator = PtyEmulator(EmulatedRadio.for_fleet(
            [r.address for r in self.robots], load_coordinator(p['fleet_file'] or None)))
        self.boards = {r.id: self.emulator.radio.boards[r.address] for r in self.robots}
        poses = initial_poses([float(v) for v in p['initial_poses']], self.robots)
        for robot, pose in zip(self.robots, poses):
            self.boards[robot.id].place(*pose)
        self._link = pathlib.Path(p['port_link']) if p['port_link'] else None
        if self._link is not None:
            self._link.unlink(missing_ok=True)
            self._link.symlink_to(self.emulator.port)
        self._rng = np.random.default_rng(p['camera_seed'])
        sensor, radio = QoSProfile(**qos.SENSOR), QoSProfile(**qos.RADIO)
        if p['camera'] not in ('truth', 'image'):
            raise ValueError(f'camera {p["camera"]!r}: use truth or image')
        self._pose_pubs = {}
        if p['camera'] == 'truth':
            self._pose_pubs = {k: self.create_publisher(PoseStamped, f'agent_{k}/pose',
                                                        sensor)
                               for k in self.boards}
        self._truth_pubs = {k: self.create_publisher(PoseStamped, f'truth/agent_{k}/pose',
                                                     sensor)
                            for k in self.boards}
        self._rx_pubs = {k: self.create_publisher(RadioPacketArray, f'agent_{k}/radio/rx',
                                                  radio)
                         for k in self.boards}
        if self._mesh is not None:
            self._move_mesh()
            self.create_subscription(RadioPacketArray, 'radio/tx', self._on_tx, radio)
        self.create_timer(p['pump_period'], self._pump)
        self.create_timer(1.0 / p['camera_rate_hz'], self._camera)
        self.get_logger().info(f'{len(self.robots)} emulated robots on {self.emulator.port}'
                               + (f' (linked at {self._link})' if self._link else ''))

    def _pump(self) -> None:
        now = time.monotonic()
        self.emulator.pump(now)
        if self._mesh is not None:
            self._deliver(now)

    def _camera(self) -> None:
        now = self.get_clock().now()
        stamp = now.to_msg()
        noise = self.params['camera_noise_m']
        for k, board in self.boards.items():
            x, y, yaw = board.pose()
            self._truth_pubs[k].publish(pose_stamped(x, y, yaw, stamp))
            if not self._pose_pubs:
                continue
            if noise > 0.0:
                x, y = np.array([x, y]) + self._rng.normal(0.0, noise, 2)
            self._pose_pubs[k].publish(pose_stamped(x, y, yaw, stamp))
        if self._mesh is not None:
            self._move_mesh()

    def _move_mesh(self) -> None:
        """The mesh's links between the boards' true poses (at the camera rate)."""
        self._mesh.move({k: board.pose()[:2] for k, board in self.boards.items()})

    def _on_tx(self, msg: RadioPacketArray) -> None:
        now = time.monotonic()
        for _, packet in frames_or_log(msg, self.get_logger(), 'radio/tx'):
            self._mesh.send(now, packet)

    def _deliver(self, now: float) -> None:
        due = self._mesh.due(now)
        if not due:
            return
        stamp = self.get_clock().now()
        seconds, stamp = stamp.nanoseconds * 1e-9, stamp.to_msg()
        for packet, receivers in due:
            frame = [(seconds, packet)]   # stamped on arrival, as sim_node does
            for k in receivers:
                # A real link delivers frame by frame: batches of one.
                self._rx_pubs[k].publish(frames_to_msg(frame, stamp))

    def close(self) -> None:
        """Remove the pty link and close the pty."""
        if self._link is not None and self._link.is_symlink():
            self._link.unlink(missing_ok=True)
        self.emulator.close()


def main(args: list[str] | None = None) -> None:
    """Run hil_world_node until interrupted."""
    run_node(HilWorldNode, 'hil_world_node', args, stop=HilWorldNode.close)


if __name__ == '__main__':
    os.environ.setdefault('PYTHONUNBUFFERED', '1')
    sys.exit(main())
