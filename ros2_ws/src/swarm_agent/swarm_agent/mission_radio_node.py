"""mission_radio_node: the mission computer's radio, a listening node of the swarm's mesh.

The thesis's mission computer reaches the robots through the same XBee mesh as they
reach each other (4.1). Its radio hears the route adverts of the agents around it; this
node runs them through the mission's ``MeshListener`` (``swarm_agent.mission_radio``: a
DSDV router of its own at ``MISSION_RADIO_ID``, every frame authenticated first under
``swarm_key_file``) and publishes, at ``rate_hz``, the agents it holds a route to. The
mission node's self-repair learns from that which agents are alive, as the headless
evaluator's mission does, with no topic of the agents' own.

Topics
  ``mission/radio/rx`` (swarm_msgs/RadioPacketArray)  subscribed: what the radio heard
                      (sim_node's mission radio, ``swarm_sim.mission_mesh``)
  ``mission/alive`` (std_msgs/Int32MultiArray)        published: agent ids with a route

The fleet comes from ``fleet_file`` (or ``type_counts``: ids 0.. in type order, as the
mission node reads them). A corrupt batch is dropped with one throttled error line; frames
that fail authentication are counted (``auth.stats``) and logged every ``rate_hz`` tick
that saw new ones.
"""

from __future__ import annotations

import sys

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from std_msgs.msg import Int32MultiArray

from swarm_agent.agent_factory import swarm_keyring
from swarm_agent.conversions import frames_or_log
from swarm_agent.frame_auth import FrameAuth
from swarm_agent.mission_radio import MeshListener
from swarm_common import qos
from swarm_common.fleet import load_fleet
from swarm_common.robot_types import agent_types_of, parse_type_counts
from swarm_common.ros_support import run_node
from swarm_msgs.msg import RadioPacketArray

PARAMETERS = {
    'fleet_file': ('', 'Fleet YAML (robots: id, type, ...): the agents listened for'),
    'type_counts': ('1:20,2:20,3:10', 'Composition when no fleet file: ids 0.. in type order'),
    'swarm_key_file': ('', "The swarm's radio key file (empty: the development key)"),
    'auth': (True, 'Authenticate the frames heard; false only with agents that do not'),
    'rate_hz': (2.0, 'How often the agents with a route are published, Hz'),
}


class MissionRadioNode(Node):
    """The mission computer's radio; see the module docstring."""

    def __init__(self, **kwargs) -> None:
        super().__init__('mission_radio', **kwargs)
        for name, (default, text) in PARAMETERS.items():
            self.declare_parameter(name, default,
                                   ParameterDescriptor(description=text, read_only=True))
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        if not 0.0 < p['rate_hz'] <= 100.0:
            raise ValueError(f"rate_hz {p['rate_hz']} is out of (0, 100]; e.g. -p rate_hz:=2.0")
        if p['fleet_file']:
            agents = [r.id for r in load_fleet(p['fleet_file'])]
        else:
            agents = list(agent_types_of(parse_type_counts(p['type_counts'])))
        keyring = swarm_keyring(p['swarm_key_file'] or None) if p['auth'] else None
        self.radio = MeshListener(agents, auth=FrameAuth(keyring) if keyring else None)
        self._rejected = 0
        self.alive_pub = self.create_publisher(Int32MultiArray, 'mission/alive',
                                               QoSProfile(**qos.STATE))
        self.create_subscription(RadioPacketArray, 'mission/radio/rx', self._on_rx,
                                 QoSProfile(**qos.RADIO))
        self.create_timer(1.0 / p['rate_hz'], self._on_timer)

    def _on_rx(self, msg: RadioPacketArray) -> None:
        for t, packet in frames_or_log(msg, self.get_logger(), 'mission/radio/rx'):
            self.radio.on_packet(t, packet)

    def _on_timer(self) -> None:
        self.alive_pub.publish(Int32MultiArray(data=self.radio.alive()))
        if self.radio.auth is not None:
            rejected = sum(self.radio.auth.stats.values())
            if rejected > self._rejected:
                self._rejected = rejected
                self.get_logger().warning(f'frames rejected by kind: {self.radio.auth.stats}',
                                          throttle_duration_sec=10.0)


def main(args=None) -> None:
    """Run the mission's radio (``ros2 run swarm_agent mission_radio_node``)."""
    run_node(MissionRadioNode, 'mission_radio_node', args)


if __name__ == '__main__':
    main(sys.argv)
