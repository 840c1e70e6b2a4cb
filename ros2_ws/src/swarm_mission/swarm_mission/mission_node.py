"""mission_node: announces the formation shape and its typed goal states.

Topics and services
  ``swarm/shape`` (swarm_msgs/FormationShape, latched)   published: current shape
  ``swarm/goals`` (swarm_msgs/GoalArray, latched)        published: current goals
  ``swarm/shape_in`` (swarm_msgs/FormationShape)         subscribed: set a shape by topic
  ``swarm/set_shape`` (swarm_msgs/srv/SetShape)          service: set a shape, with reply
  ``mission/alive`` (std_msgs/Int32MultiArray)          subscribed: the agents the
                                                          mission's radio holds routes to
  ``agent_K/state`` (swarm_msgs/AgentState)              subscribed with liveness:=states

The shape comes from the ``shape`` parameter (built-in name or .json/.svg/.png file),
the topic or the service; ``sequence_file`` switches shapes at given sim times and
``morph`` changes the shape smoothly (move, rotate, grow). ``remesh`` chooses whether bubble
packing moves the goals of a changed shape (incremental) or partitions it anew. With
``decentralized`` the node only announces shapes: every agent partitions for itself.

Self-repair needs to know which agents are alive. As the thesis's mission computer, the
node learns it over the radio (``liveness`` radio, the default): its radio's node,
``swarm_agent``'s ``mission_radio_node``, hears the route adverts of the agents around it
and publishes on ``mission/alive`` the agents it holds a route to. ``liveness`` states
reads the agents' AgentState topics instead (a ROS graph a real mission computer may not
see).
With ``state_file`` the node keeps its shape, goals, versions, sequence position and lost
agents in that file at every change; restarted with the same ``run_id`` it publishes them
again under the same versions instead of starting from its parameters
(``swarm_mission.mission_state``).
"""

from __future__ import annotations

import sys

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from std_msgs.msg import Int32MultiArray
import yaml

from swarm_common import qos
from swarm_common.conversions import goals_to_msg, shape_from_msg, shape_to_msg
from swarm_common.robot_types import (
    agent_types_of,
    load_robot_types,
    parse_type_counts,
    RobotTypeError,
)
from swarm_common.ros_support import run_node
from swarm_common.shapes import load_shape, ShapeError
from swarm_mission import mission_state
from swarm_mission.mission import load_sequence, Mission, MissionConfig, parse_morph
from swarm_mission.mission_state import MissionStateError
from swarm_mission.partition import PartitionError
from swarm_msgs.msg import AgentState, FormationShape, GoalArray
from swarm_msgs.srv import SetShape

PARAMETERS = {
    'shape': ('circle_314', 'Initial shape: built-in name or path to .json/.svg/.png'),
    'shape_scale': (1.0, 'Scale applied to SVG/PNG shapes'),
    'sequence_file': ('', 'Optional YAML/JSON shape sequence [{time, shape}, ...]'),
    'morph': ('', 'Optional smooth change of the shape, KIND:AMOUNT@START+DURATION[/STEPS]: '
                  'move (m along x, or DX,DY), rotate (degrees) or grow (by 1 + '
                  'AMOUNT), e.g. move:15@200+60; not with sequence_file'),
    'method': ('bubble', 'Partition method: bubble, fractal or forces (no partition)'),
    'fleet_file': ('', 'Fleet YAML (robots: id, type, beacon, ...): the swarm composition '
                       'and its position beacons, for whom beacon goals are chosen'),
    'type_counts': ('1:20,2:20,3:10', 'Composition when no fleet file: ids 0.. in type order'),
    'seed': (0, 'Partition seed (deterministic partitions)'),
    'decentralized': (False, 'Only announce shapes; agents partition themselves'),
    'agent_timeout_s': (6.0, 'Silence after which an agent is declared lost'),
    'repair': (True, 'Re-partition for the survivors when agents are lost'),
    'formation_margin_m': (0.6, 'Partition the shape shrunk by this band (m) so robots '
                                'parked off their goals under localization error stay '
                                'inside; 0: the shape as is'),
    'radio_range_m': (25.0, 'Radio range (m) the beacon goals are chosen for, thesis 4.1 '
                            '(the radio_range_m of sim_node)'),
    'remesh': ('incremental', 'Bubble packing on a changed shape: incremental (goals '
                              'move, keeping their ids) or scratch (new goals, re-assigned)'),
    'robot_types_file': ('', "Robot type table YAML (coverage radii; default: the "
                             "package's thesis Table 4.1); the agents' robot_types_file"),
    'state_file': ('', 'File the node keeps its shape, goals and versions in, and resumes '
                       'from when restarted (swarm_mission.mission_state); empty: none'),
    'run_id': ('', 'Id of this run: a state_file saved under another run id is not resumed '
                   '(the launch plan gives every run its own)'),
    'liveness': ('radio', 'How the node learns which agents are alive: radio (the route '
                          'adverts its radio hears, on mission/alive) or states (the '
                          "agents' AgentState topics)"),
}
LIVENESS = ('radio', 'states')


def _fleet(path: str) -> tuple[dict[int, int], set[int]]:
    """Agent types and beacon ids of a fleet file; ShapeError names the file."""
    try:
        with open(path, encoding='utf-8') as stream:
            robots = yaml.safe_load(stream)['robots']
        return ({int(r['id']): int(r['type']) for r in robots},
                {int(r['id']) for r in robots if r.get('beacon', False)})
    except OSError as exc:
        raise ShapeError(f'fleet_file {path}: {exc.strerror}') from None
    except (yaml.YAMLError, KeyError, TypeError, ValueError) as exc:
        raise ShapeError(f'fleet_file {path} is not a fleet (robots: [{{id, type, beacon, '
                         f'x, y}}, ...]): {type(exc).__name__} {exc}') from None


class MissionNode(Node):
    """ROS wiring of the Mission planner; see the module docstring."""

    def __init__(self, **kwargs) -> None:
        super().__init__('mission', **kwargs)
        # Read once, at start (shapes change through the topic and the service).
        for name, (default, text) in PARAMETERS.items():
            self.declare_parameter(name, default,
                                   ParameterDescriptor(description=text, read_only=True))
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        self.params = p
        types = load_robot_types(p['robot_types_file'] or None)
        if p['fleet_file']:
            agent_types, beacons = _fleet(p['fleet_file'])
        else:
            beacons = None
            agent_types = agent_types_of(parse_type_counts(p['type_counts']))
        for t in set(agent_types.values()):
            if t not in types:
                raise RobotTypeError(f'agent_types holds unknown robot type {t}; '
                                     f'known: {sorted(types)}')
        self.mission = Mission(
            MissionConfig(method=p['method'], seed=p['seed'],
                          agent_timeout_s=p['agent_timeout_s'], repair=p['repair'],
                          formation_margin=p['formation_margin_m'], remesh=p['remesh'],
                          radio_range_m=p['radio_range_m']),
            agent_types=agent_types,
            radii={t: r.coverage_radius for t, r in types.items()}, beacons=beacons)
        if p['sequence_file'] and p['morph']:
            raise ShapeError('set the mission parameter sequence_file or morph, not both')
        base = None if p['sequence_file'] else load_shape(p['shape'], scale=p['shape_scale'])
        if p['sequence_file']:
            self._sequence = load_sequence(p['sequence_file'], scale=p['shape_scale'])
        else:
            self._sequence = parse_morph(p['morph'], base) if p['morph'] else []
        self._next_step = 0
        self._start: float | None = None

        latched = QoSProfile(**qos.LATCHED)
        self._shape_pub = self.create_publisher(FormationShape, 'swarm/shape', latched)
        self._goals_pub = self.create_publisher(GoalArray, 'swarm/goals', latched)
        self.create_subscription(FormationShape, 'swarm/shape_in', self._on_shape_in,
                                 QoSProfile(**qos.STATE))
        self.create_service(SetShape, 'swarm/set_shape', self._on_set_shape)
        if p['liveness'] not in LIVENESS:
            raise ValueError(f"liveness {p['liveness']!r} is not one of {', '.join(LIVENESS)}; "
                             'set -p liveness:=radio (or states)')
        if p['liveness'] == 'radio':
            self.create_subscription(Int32MultiArray, 'mission/alive', self._on_alive,
                                     QoSProfile(**qos.STATE))
        else:
            for agent in self.mission.agent_types:
                self.create_subscription(AgentState, f'agent_{agent}/state', self._on_state,
                                         QoSProfile(**qos.STATE))
        self.create_timer(0.5, self._on_timer)
        self._saved: tuple | None = None
        if not self._resume() and base is not None:
            self._apply(base)

    def _resume(self) -> bool:
        """Publish the state saved by this run's previous node, if any (module docstring)."""
        path = self.params['state_file']
        if not path:
            return False
        try:
            state = mission_state.load(path, self.params['run_id'])
        except MissionStateError as exc:
            self.get_logger().error(f'{exc}; starting from the parameters')
            return False
        if state is None:
            return False
        mission_state.resume(self.mission, state, self._now())
        self._next_step, self._start = state.next_step, state.sequence_start
        self._saved = self._save_key()
        if state.shape is not None:
            self._shape_pub.publish(shape_to_msg(state.shape, state.shape_version,
                                                 self.get_clock().now().to_msg()))
            if not self.params['decentralized']:
                self._publish_goals()
        self.get_logger().info(f'{self.mission.events[-1]} (from {path})')
        return True

    def _save_key(self) -> tuple:
        m = self.mission
        return (m.shape_version, m.goal_version, self._next_step, self._start,
                tuple(sorted(m.lost)))

    def _save(self) -> None:
        """Keep the state in ``state_file`` when it changed (one error line if it cannot)."""
        key = self._save_key()
        if not self.params['state_file'] or key == self._saved:
            return
        self._saved = key
        try:
            mission_state.save(self.params['state_file'], mission_state.capture(
                self.mission, self.params['run_id'], self._next_step, self._start))
        except OSError as exc:
            self.get_logger().error(f'cannot write the mission state file '
                                    f'{self.params["state_file"]}: {exc.strerror}; a '
                                    'restarted mission node will start from its parameters')

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _running_now(self) -> float | None:
        """The clock's time (s), None while a node on simulated time has heard no /clock
        yet (its clock reads 0). Liveness stamped then would read as the whole run's
        silence once the clock jumps to the simulator's time: a respawned node that hears
        mission/alive before /clock would declare every agent lost, hear them again and
        re-partition instead of keeping the goals it resumed."""
        now = self._now()
        return now if now > 0.0 else None

    def _apply(self, shape) -> tuple[bool, str]:
        """Version, partition and publish a shape; return (success, message)."""
        if self.params['decentralized']:
            self.mission.shape = shape
            self.mission.shape_version += 1
            ok = True
        else:
            try:
                ok = self.mission.set_shape(shape)
            except (PartitionError, ShapeError) as exc:
                self.get_logger().error(f'cannot partition shape {shape.name!r}: {exc}')
                return False, str(exc)
        stamp = self.get_clock().now().to_msg()
        self._shape_pub.publish(shape_to_msg(shape, self.mission.shape_version, stamp))
        if not self.params['decentralized']:
            self._publish_goals()
        message = self.mission.events[-1] if self.mission.events else 'shape announced'
        self.get_logger().info(message)
        self._save()
        return ok, message

    def _publish_goals(self) -> None:
        stamp = self.get_clock().now().to_msg()
        self._goals_pub.publish(goals_to_msg(self.mission.goals, self.mission.goal_version,
                                             self.mission.shape_version,
                                             self.params['method'], stamp))

    def _on_shape_in(self, msg: FormationShape) -> None:
        try:
            self._apply(shape_from_msg(msg))
        except ShapeError as exc:
            self.get_logger().error(f'rejected shape from /swarm/shape_in: {exc}')

    def _on_set_shape(self, request: SetShape.Request, response: SetShape.Response):
        try:
            ok, message = self._apply(shape_from_msg(request.shape))
        except ShapeError as exc:
            ok, message = False, f'rejected shape: {exc}'
        response.success = ok
        response.message = message
        response.version = self.mission.shape_version
        return response

    def _on_state(self, msg: AgentState) -> None:
        now = self._running_now()
        if now is not None:
            self.mission.agent_seen(int(msg.id), now)

    def _on_alive(self, msg: Int32MultiArray) -> None:
        now = self._running_now()
        if now is None:
            return
        for agent in msg.data:
            self.mission.agent_seen(int(agent), now)

    def _on_timer(self) -> None:
        now = self._running_now()
        if now is None:
            return
        if self._start is None:
            self._start = now
        while (self._next_step < len(self._sequence)
               and now - self._start >= self._sequence[self._next_step].time):
            self._apply(self._sequence[self._next_step].shape)
            self._next_step += 1
        goal_version = self.mission.goal_version
        self.mission.check_liveness(now)
        if self.mission.goal_version != goal_version and not self.params['decentralized']:
            self.get_logger().warning(self.mission.events[-1])
            self._publish_goals()
        self._save()


def main(args=None) -> None:
    """Run the mission node (``ros2 run swarm_mission mission_node``)."""
    run_node(MissionNode, 'mission_node', args)


if __name__ == '__main__':
    main(sys.argv)
