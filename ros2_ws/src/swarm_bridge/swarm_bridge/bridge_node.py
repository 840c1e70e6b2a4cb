"""bridge_node: swarm agents to PIC16F690 omni-wheel robots over an XBee (thesis ch. 5).

Wiring (logic in bridge.Bridge, codec in xbee, messages and eqs. 5.1-5.3 in protocol):

  /agent_K/cmd_vel      geometry_msgs/Twist (body frame)  -> CmdVel (eqs. 5.1-5.3), as is
  /agent_K/pose         geometry_msgs/PoseStamped (camera) -> watchdog: no pose, no motion
  /agent_K/wheel_states sensor_msgs/JointState             <- board status (wheel m/s)
  /diagnostics          diagnostic_msgs/DiagnosticArray    <- per-robot status and counters
                        (foreign_frames: frames a board dropped, not from the coordinator;
                        link: unknown_address / unknown_senders, frames dropped from
                        XBees not in the fleet)

The serial port is opened with pyserial (``port`` may be a device or a pyserial URL). A
port that fails or vanishes is closed, logged once with the cause and reopened every
``reopen_period``; the node keeps running. Parameters: PARAMETERS below, defaults equal
to config/bridge.yaml.
"""

from __future__ import annotations

import math
import sys

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, Twist
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from sensor_msgs.msg import JointState
import serial

from swarm_bridge import protocol
from swarm_bridge.bridge import Bridge, BridgeParams
from swarm_common.fleet import FleetError, load_coordinator, load_fleet
from swarm_common.ros_support import run_node

PARAMETERS = {
    'port': ('/dev/ttyUSB0', 'Serial port of the coordinator XBee (device or pyserial URL)'),
    'baud': (protocol.BAUD, 'Baud rate of the coordinator XBee (firmware SWP_BAUD)'),
    'fleet_file': ('', 'Fleet YAML mapping agent ids to XBee addresses (default: package)'),
    'agents': ('', 'Comma-separated agent ids to bridge (default: the whole fleet)'),
    'max_speed': (0.035, 'Robot speed limit, m/s (<= fastest wheel speed: no clipping)'),
    'cmd_timeout': (1.5, 'Seconds without cmd_vel before the robot is sent STOP (agents '
                         'publish on change, every 0.5 s at most)'),
    'pose_timeout': (1.0, 'Seconds without a camera pose before the robot is sent STOP'),
    'resend_period': (0.1, 'Seconds between repeated commands (board watchdog: 0.5 s)'),
    'board_timeout': (1.0, 'Seconds without status or ack before a board counts as silent'),
    'poll_period': (0.01, 'Seconds between serial reads and command updates'),
    'reopen_period': (1.0, 'Seconds between attempts to reopen a failed port'),
    'status_period': (1.0, 'Seconds between diagnostics messages'),
}
SENSOR_QOS = {'depth': 5, 'reliability': 2, 'durability': 2, 'history': 1}
STATE_QOS = {'depth': 10, 'reliability': 1, 'durability': 2, 'history': 1}


def yaw_of(q) -> float:
    """Yaw (rad, counter-clockwise) of a geometry_msgs quaternion."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


class BridgeNode(Node):
    """ROS wiring of a Bridge and its serial port; see the module docstring."""

    def __init__(self, node_name: str = 'bridge', **kwargs) -> None:
        super().__init__(node_name, **kwargs)
        for name, (default, text) in PARAMETERS.items():
            self.declare_parameter(name, default, ParameterDescriptor(description=text))
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        self.params = p
        robots = load_fleet(p['fleet_file'] or None, hardware=True)
        if p['agents']:
            wanted = {int(a) for a in str(p['agents']).split(',') if a.strip()}
            missing = wanted - {r.id for r in robots}
            if missing:
                raise ValueError(f'agents {sorted(missing)} are not in the fleet file; '
                                 'add them there or drop them from the agents parameter')
            robots = [r for r in robots if r.id in wanted]
        self.bridge = Bridge(robots, BridgeParams(
            max_speed=p['max_speed'], cmd_timeout=p['cmd_timeout'],
            pose_timeout=p['pose_timeout'], resend_period=p['resend_period'],
            board_timeout=p['board_timeout']))
        self.serial: serial.SerialBase | None = None
        self._wheel_pubs = {}
        sensor, state = QoSProfile(**SENSOR_QOS), QoSProfile(**STATE_QOS)
        for robot in robots:
            k = robot.id
            self.create_subscription(Twist, f'agent_{k}/cmd_vel',
                                     lambda m, k=k: self._on_cmd_vel(k, m), sensor)
            self.create_subscription(PoseStamped, f'agent_{k}/pose',
                                     lambda m, k=k: self._on_pose(k, m), sensor)
            self._wheel_pubs[k] = self.create_publisher(JointState, f'agent_{k}/wheel_states',
                                                        state)
        self._diag = self.create_publisher(DiagnosticArray, '/diagnostics', state)
        self._open()
        self.create_timer(p['poll_period'], self._on_poll)
        self.create_timer(p['reopen_period'], self._reopen)
        self.create_timer(p['status_period'], self._publish_diagnostics)
        try:
            coordinator = f'{load_coordinator(p["fleet_file"] or None):016X}'
        except FleetError as exc:
            self.get_logger().warning(f'{exc}: the robots obey only the XBee their firmware '
                                      'was built for (firmware/PROTOCOL.md)')
        else:
            self.get_logger().info(f'the robots obey only XBee {coordinator} (fleet file '
                                   f'coordinator): it must be the one on {p["port"]}')
        self.get_logger().info(f'bridging agents {[r.id for r in robots]} '
                               f'on {p["port"]} at {p["baud"]} baud')

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    # -- inputs ------------------------------------------------------------------------
    def _on_cmd_vel(self, agent: int, msg: Twist) -> None:
        self.bridge.on_setpoint(agent, msg.linear.x, msg.linear.y, self._now())

    def _on_pose(self, agent: int, msg: PoseStamped) -> None:
        pos = msg.pose.position
        self.bridge.on_pose(agent, pos.x, pos.y, yaw_of(msg.pose.orientation), self._now())

    # -- serial port -------------------------------------------------------------------
    def _open(self) -> None:
        try:
            self.serial = serial.serial_for_url(self.params['port'], self.params['baud'],
                                                timeout=0, write_timeout=0.5)
        except (serial.SerialException, OSError, ValueError) as exc:
            self.serial = None
            self.bridge.report_port_problem(f'cannot open {self.params["port"]}: {exc}')
        else:
            self.bridge.report_port_ok(self.params['port'])
        self._log_events()

    def _reopen(self) -> None:
        if self.serial is None:
            self._open()

    def _fail(self, exc: Exception) -> None:
        self.bridge.report_port_problem(f'{self.params["port"]}: {exc}')
        try:
            self.serial.close()
        except Exception:  # noqa: BLE001 - the port is gone already
            pass
        self.serial = None

    def _on_poll(self) -> None:
        now = self._now()
        if self.serial is not None:
            try:
                waiting = self.serial.in_waiting
                data = self.serial.read(waiting) if waiting else b''
            except (serial.SerialException, OSError) as exc:
                self._fail(exc)
            else:
                for agent in self.bridge.on_bytes(data, now):
                    self._publish_wheels(agent)
        out = self.bridge.poll(now)
        if out and self.serial is not None:
            try:
                self.serial.write(out)
            except (serial.SerialException, OSError) as exc:
                self._fail(exc)
        self._log_events()

    def _log_events(self) -> None:
        # One call site per severity: rclpy refuses to change a call site's severity
        # ('Logger severity cannot be changed between calls'), which crashed the node.
        for event in self.bridge.take_events():
            if event.level == 'warn':
                self.get_logger().warning(event.text)
            else:
                self.get_logger().info(event.text)

    # -- outputs -----------------------------------------------------------------------
    def _publish_wheels(self, agent: int) -> None:
        status = self.bridge.links[agent].status
        msg = JointState()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = f'agent_{agent}/base_link'
        msg.name = list(protocol.WHEEL_NAMES)
        msg.velocity = [float(v) for v in status.wheel_speeds()]
        self._wheel_pubs[agent].publish(msg)

    def _publish_diagnostics(self) -> None:
        array = DiagnosticArray()
        array.header.stamp = self.get_clock().now().to_msg()
        for agent, link in self.bridge.links.items():
            st = DiagnosticStatus()
            st.name = f'swarm_bridge: agent_{agent}'
            st.hardware_id = link.robot.address_hex
            status = link.status
            if link.silent or status is None:
                st.level, st.message = DiagnosticStatus.ERROR, 'board silent'
            elif status.faults & ~protocol.FAULT_RESET:
                st.level, st.message = DiagnosticStatus.WARN, ','.join(status.fault_names())
            else:
                st.level, st.message = DiagnosticStatus.OK, 'ok'
            values = dict(link.counters)
            if status is not None:
                values.update(cmd_age_ms=status.cmd_age_ms, faults=status.faults,
                              bad_frames=status.bad_frames, foreign=status.foreign,
                              rates=status.rates)
            st.values = [KeyValue(key=k, value=str(v)) for k, v in sorted(values.items())]
            array.status.append(st)
        st = DiagnosticStatus(name='swarm_bridge: link', level=DiagnosticStatus.OK,
                              message='port open' if self.serial else 'port closed')
        if self.serial is None:
            st.level = DiagnosticStatus.ERROR
        st.values = [KeyValue(key=k, value=str(v))
                     for k, v in sorted(self.bridge.all_counters().items())]
        array.status.append(st)
        self._diag.publish(array)

    def shutdown(self) -> None:
        """Stop every robot and close the port."""
        if self.serial is not None:
            try:
                self.serial.write(self.bridge.stop_all())
                self.serial.close()
            except (serial.SerialException, OSError):
                pass
            self.serial = None


def main(args: list[str] | None = None) -> None:
    """Run bridge_node until interrupted."""
    run_node(BridgeNode, 'bridge_node', args, stop=BridgeNode.shutdown)


if __name__ == '__main__':
    sys.exit(main())
