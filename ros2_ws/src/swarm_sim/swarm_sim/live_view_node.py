"""live_view_node: a running swarm served live to Foxglove over a WebSocket (issue 21).

Subscribes ``swarm/shape`` (swarm_msgs/FormationShape), ``swarm/goals``
(swarm_msgs/GoalArray), ``swarm/truth`` (swarm_msgs/SwarmTruth, simulation only), and
for each robot of the fleet ``agent_K/state`` (swarm_msgs/AgentState: type, beacon,
mode, estimate, assigned goal, settled) and ``agent_K/routes`` (swarm_msgs/RouteTable:
its one-hop neighbours are the radio links). At ``rate_hz`` (wall clock, so the view
moves while the simulation is paused or slow) it sends the scene and the status built
by ``swarm_sim.live_view`` on a Foxglove WebSocket server at ``host``:``port``
(``/swarm/scene`` foxglove.SceneUpdate, ``/swarm/status`` JSON counts). Open Foxglove,
connect to ``ws://localhost:8765`` and import ``config/foxglove_layout.json``.

The fleet is ``fleet_file`` (the run's fleet.yaml) or ``agent_ids``; coverage radii come
from the robot types (``robot_types_file``, Table 4.1 by default). A port that is taken
ends the node with one line naming it (``swarm_common.ros_support``).
"""

from __future__ import annotations

import threading
import time

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import QoSProfile

from swarm_common import qos
from swarm_common.conversions import goals_from_msg, shape_from_msg
from swarm_common.fleet import load_fleet
from swarm_common.robot_types import load_robot_types
from swarm_common.ros_support import lean_subscription, run_node
from swarm_common.shapes import ShapeError
from swarm_msgs.msg import AgentState, FormationShape, GoalArray, RouteTable, SwarmTruth
from swarm_sim.foxglove_view import LiveViewServer
from swarm_sim.live_view import links_from_routes, NO_GOAL, NOT_HEARD, RobotView, SwarmView

# name -> (default, description)
PARAMETERS = {
    'port': (8765, 'WebSocket port of the Foxglove server (0: any free port)'),
    'host': ('127.0.0.1', 'Address to listen on (0.0.0.0: every interface)'),
    'rate_hz': (2.0, 'Scene updates per second (wall clock)'),
    'fleet_file': ('', "The run's fleet YAML (robot ids, types, beacons)"),
    'agent_ids': ([0], 'Robot ids to watch when no fleet_file is given'),
    'robot_types_file': ('', 'Robot types YAML (empty: Table 4.1)'),
}


class LiveViewNode(Node):
    """Serves the live view; see the module docstring."""

    def __init__(self, **kwargs) -> None:
        super().__init__('live_view', **kwargs)
        for name, (default, text) in PARAMETERS.items():
            self.declare_parameter(name, default, ParameterDescriptor(description=text))
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        if not p['rate_hz'] > 0.0:
            raise ValueError(f"rate_hz must be positive, got {p['rate_hz']}")
        if not 0 <= p['port'] <= 65535:
            raise ValueError(f"port must be 0..65535, got {p['port']}")
        types = load_robot_types(p['robot_types_file'] or None)
        self.radius = {t: spec.coverage_radius for t, spec in types.items()}
        self.lock = threading.Lock()
        # id -> (type, beacon) from the fleet; states and truth refine it.
        if p['fleet_file']:
            self.fleet = {r.id: (r.type, r.is_beacon) for r in load_fleet(p['fleet_file'])}
        else:
            self.fleet = {int(a): (min(types), False) for a in p['agent_ids']}
        self.shape = None
        self.goals: list = []
        self.goal_version = 0
        self.states: dict[int, AgentState] = {}
        self.truth: SwarmTruth | None = None
        self.routes: dict[int, list[tuple[int, int]]] = {}
        self.server = LiveViewServer(port=p['port'], host=p['host'])
        state = QoSProfile(**qos.STATE)
        latched = QoSProfile(**qos.LATCHED)
        self.create_subscription(FormationShape, 'swarm/shape', self._on_shape, latched)
        self.create_subscription(GoalArray, 'swarm/goals', self._on_goals, latched)
        self.create_subscription(SwarmTruth, 'swarm/truth', self._on_truth, state)
        for agent in self.fleet:
            lean_subscription(self, AgentState, f'agent_{agent}/state', self._on_state, state)
            lean_subscription(self, RouteTable, f'agent_{agent}/routes', self._on_routes,
                              state)
        self.create_timer(1.0 / p['rate_hz'], self.publish,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f'live view of {len(self.fleet)} robots on ws://{p["host"]}:{self.server.port}')

    def _on_shape(self, msg: FormationShape) -> None:
        try:
            shape = shape_from_msg(msg)
        except ShapeError as exc:
            self.get_logger().warning(f'swarm/shape: {exc}; the view keeps the last shape')
            return
        with self.lock:
            self.shape = shape

    def _on_goals(self, msg: GoalArray) -> None:
        with self.lock:
            self.goals = goals_from_msg(msg)
            self.goal_version = int(msg.version)

    def _on_truth(self, msg: SwarmTruth) -> None:
        with self.lock:
            self.truth = msg

    def _on_state(self, msg: AgentState) -> None:
        with self.lock:
            self.states[int(msg.id)] = msg

    def _on_routes(self, msg: RouteTable) -> None:
        with self.lock:
            self.routes[int(msg.owner)] = [(int(r.destination), int(r.hop_count))
                                           for r in msg.routes]

    def view(self) -> SwarmView:
        """The swarm as last heard: fleet, states, truth, shape, goals and links."""
        with self.lock:
            truth = {int(a.id): a for a in self.truth.agents} if self.truth else {}
            robots = []
            for rid in sorted(set(self.fleet) | set(truth)):
                rtype, beacon = self.fleet.get(rid, (1, False))
                t, s = truth.get(rid), self.states.get(rid)
                if t is not None:
                    rtype, beacon = int(t.type), bool(t.is_beacon)
                if s is not None:
                    rtype, beacon = int(s.type), bool(s.is_beacon)
                robots.append(RobotView(
                    id=rid, type=rtype, radius=self.radius.get(rtype, min(self.radius.values())),
                    is_beacon=beacon,
                    estimate=tuple(s.position) if s is not None else None,
                    truth=tuple(t.position) if t is not None else None,
                    mode=int(s.mode) if s is not None else NOT_HEARD,
                    # An assignment to an older goal list would point at the wrong goal.
                    assigned_goal=(int(s.assigned_goal) if s is not None
                                   and s.goal_version == self.goal_version else NO_GOAL),
                    settled=bool(s.settled) if s is not None else False,
                    alive=bool(t.alive) if t is not None else True))
            return SwarmView(shape=self.shape, goals=list(self.goals), robots=robots,
                             links=links_from_routes(self.routes))

    def publish(self) -> None:
        """Send the current scene and status (wall-clock time stamps) to the clients
        that subscribe to them."""
        if self.server.watched():
            self.server.publish(self.view(), time.time_ns())

    def close(self) -> None:
        """Stop the WebSocket server."""
        self.server.stop()


def main(args=None) -> None:
    """Run the live view until Ctrl-C."""
    run_node(LiveViewNode, 'live_view_node', args, stop=LiveViewNode.close)


if __name__ == '__main__':
    main()
