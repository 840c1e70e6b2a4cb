"""composed_node: many agent nodes in one process (one DDS participant) for scale.

Reads a fleet file (``robots: [{id, type, beacon, x, y}, ...]``) and creates one
``AgentNode`` per robot (or per robot listed in ``agent_ids``, when the swarm is split
over several hosts), each named ``agent_K`` in the container's namespace (its topics
under ``agent_K/``, agent_node) with the same parameters a
separate ``agent_node`` process would get, all spun by one executor (the pattern of
ros2/examples ``executors/composed.py``). Measured on 2 cores: one participant
discovers 50 nodes in under a second where 50 processes need tens of seconds.

The container keeps its executor's wait set small, because a Python executor rebuilds
and polls it after every wait (py-spy on the 50-agent thesis scenario: 77 % of the
process in the executor, under 10 % in the agents' callbacks):

- With ``use_sim_time`` the agents do not each subscribe to ``/clock``: their clocks are
  attached to one time source of the container (50 agents at a 50 Hz clock would be
  2500 clock callbacks a second through one executor), and so is the clock of the timers
  that step them, so an agent never reads an older time than the tick it serves.
- One timer steps every agent's inner loop (``AgentNode.on_control``), one publishes
  every agent's state, one every agent's routes and one logs every agent's status line,
  instead of four timers per agent. With ``sensor_batch`` the world's batch steps them
  instead (below).
- The agents have no parameter or type-description services (seven services each) and
  their per-robot topics have no default QoS event handlers (``swarm_common.ros_support``).
  Their parameters are the container's (listed by ``ros2 param dump
  /agents_container``) plus the fleet file's.
- With ``sensor_batch`` (``launch_swarm.py --composed`` sets it, with sim_node's) the
  world sends one ``swarm/sensor_batch`` (swarm_msgs/SensorBatch) per step, which the
  container hands to its agents, and the agents' commands of a control step leave in one
  ``swarm/cmd_batch`` (swarm_msgs/ForceBatch); shape and goals come through the
  container too (beacons' GPS fixes included). The agents then subscribe to nothing and
  are not added to the executor at all (their publishers work without it): the
  container is the one node of its wait set. The world sends
  a batch at every step and with every repeat of a held clock, so the batch is the
  agents' clock (its stamp, with ``use_sim_time``) and its arrival their control tick:
  the sensors of a step reach the brains before the step that answers it, in one wait
  of the executor instead of one for /clock, one for the batch and one for a timer.
- The agents' radio frames leave in one batch per ``radio_tx_hz`` period, flushed in the
  control callback right after the step that produced them.

Each agent still publishes its own ``state`` and ``odom`` (``agent_K/state``,
``agent_K/odom``) at ``state_rate_hz``; the TF of their estimates (``map ->
agent_K/base_link``) leaves in one /tf message per state period for all of them. Every
name is relative but ``/tf`` and ``/clock`` (a swarm in a namespace remaps them,
swarm_bringup.launch_plan); radio frames go out on ``radio/tx``.

Subscribes ``swarm/kill`` (std_msgs/Int32MultiArray): agent ids whose nodes are
destroyed, to emulate robots dying mid-run (self-repair experiments).
"""

from __future__ import annotations

from array import array
import math
import sys

from geometry_msgs.msg import TransformStamped
import numpy as np
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.clock import ROSClock
from rclpy.event_handler import EventHandler
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rclpy.time import Time
from rclpy.time_source import TimeSource
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Int32MultiArray
from tf2_msgs.msg import TFMessage
import yaml

from swarm_agent.agent_node import (
    AgentNode,
    BRAIN_PARAMETERS,
    declare_brain_parameters,
    make_executor,
    RadioBatcher,
    set_brain_parameters,
)
from swarm_agent.brain import AgentBrain
from swarm_agent.brain_config import BrainConfigError
from swarm_agent.conversions import sensor_batch_from_msg, SensorInputs, stamp_seconds
from swarm_agent.frame_auth import ReplayStore
from swarm_agent.packet import PacketError
from swarm_agent.reception import receive, ReceiverSets
from swarm_agent.route_table import RouteStore
from swarm_common import qos
from swarm_common.ros_support import declare_list_parameter, run_node
from swarm_msgs.msg import ForceBatch, FormationShape, GoalArray, RadioPacketArray, SensorBatch

SHARED = {
    'method': ('bubble', 'Formation method of every agent'),
    'fleet_file': ('', 'Fleet YAML: robots with id, type, beacon, x, y'),
    'seed': (0, 'Base seed; agent K uses seed + K'),
    'control_rate_hz': (50.0, 'LQR inner loop rate of every agent'),
    'localization_period_s': (3.0, 'Trilateration period of every agent'),
    'placement_std_m': (0.3, "Uncertainty (m per axis) of every agent's deployment position"),
    'partition_locally': (False, 'Agents partition announced shapes themselves'),
    'radio_tx_hz': (20.0, "Rate of the one batch of every agent's radio frames"),
    'state_rate_hz': (2.0, "Rate of every agent's state topic"),
    'routes_rate_hz': (0.5, "Rate of every agent's routes topic"),
    'type_counts': ('', 'Swarm composition for local partitioning'),
    'sensor_batch': (False, "Take every agent's imu, ranges, proximity and radio deliveries "
                            "from the world's /swarm/sensor_batch (sim_node sensor_batch) and "
                            'shape and goals through the container, instead of per-robot '
                            'topics'),
}


def _has_callbacks(node: Node) -> bool:
    """Whether the executor has anything of ``node`` to wait for besides QoS event
    handlers (rclpy gives every node's /parameter_events publisher two, which only log
    an incompatible-QoS warning)."""
    if any(next(iter(entities), None) is not None for entities in (
            node.subscriptions, node.timers, node.services, node.clients, node.guards)):
        return True
    return any(not isinstance(w, EventHandler) for w in node.waitables)


class ComposedAgents(Node):
    """Owns the agent nodes of one process; see the module docstring."""

    def __init__(self, executor, **kwargs) -> None:
        super().__init__('agents_container', **kwargs)
        for name, (default, text) in SHARED.items():
            self.declare_parameter(name, default,
                                   ParameterDescriptor(description=text, read_only=True))
        # The brain's tunables, for every agent of the process; live ones apply to all.
        settings = declare_brain_parameters(self)
        only = declare_list_parameter(self, 'agent_ids', Parameter.Type.INTEGER_ARRAY,
                             'Ids of the fleet to run here (empty: all); the others run '
                             'elsewhere') or None
        p = {name: self.get_parameter(name).value for name in SHARED}
        use_sim_time = self.get_parameter('use_sim_time').value
        robots = _fleet_robots(p['fleet_file'])
        if only is not None:
            robots = [r for r in robots if int(r['id']) in set(only)]
        self.executor_ = executor
        self.agents: dict[int, AgentNode] = {}
        # The receivers of each set of addresses a frame reaches (cleared when one dies).
        self._heard = ReceiverSets(
            lambda r: node.brain if (node := self.agents.get(r)) is not None else None)
        # One clock for all: the container's time source drives every agent's clock (the
        # agents themselves run with use_sim_time false) and the clock of the container's
        # timers that step them. Not the container node's own clock: that one follows
        # its own /clock subscription, and an agent stepped by a timer on it could read a
        # time one message older than the timer's (measured: a parked agent then skipped
        # its keepalive command and the world held its clock for it for 10 s, wall).
        # With sensor_batch the world's batch is that clock (no /clock subscription) and
        # its arrival steps the agents (_on_batch): one wait of the executor per step.
        self._sim_time = None
        timer_clock = self.get_clock()
        if use_sim_time:
            self._sim_time = TimeSource() if p['sensor_batch'] else TimeSource(node=self)
            self._sim_time.ros_time_is_active = True
            timer_clock = ROSClock()
            self._sim_time.attach_clock(timer_clock)
        # One batch of every agent's radio frames per period (20 messages a second for
        # the whole swarm instead of one per frame per agent).
        for rate in ('radio_tx_hz', 'control_rate_hz', 'state_rate_hz', 'routes_rate_hz'):
            if not p[rate] > 0.0:
                raise BrainConfigError(f'parameter {rate} must be above 0 Hz, got {p[rate]}')
        self._control_period = 1.0 / p['control_rate_hz']
        self._next_control = 0.0   # time of the next batch-driven step (sensor_batch)
        self._radio = RadioBatcher(
            self.create_publisher(RadioPacketArray, 'radio/tx', QoSProfile(**qos.RADIO)),
            1.0 / p['radio_tx_hz'])
        # With sensor_batch the agents' commands of a step leave in one ForceBatch.
        self._commands: list[tuple[int, float, float, float]] = []
        self._cmd_batch = (self.create_publisher(ForceBatch, 'swarm/cmd_batch',
                                                 QoSProfile(**qos.COMMAND_BATCH))
                           if p['sensor_batch'] else None)
        # Every agent's TF of one state period in one message (reliable, as tf2 listens).
        self._transforms: list[TransformStamped] = []
        # Every agent's route table and replay windows: one call per frame heard.
        self._route_store, self._replay_store = RouteStore(), ReplayStore()
        self._tf = self.create_publisher(TFMessage, '/tf', QoSProfile(**qos.STATE))
        for robot in robots:
            agent_id = int(robot['id'])
            overrides = [
                Parameter('agent_id', value=agent_id),
                Parameter('agent_type', value=int(robot['type'])),
                Parameter('is_beacon', value=bool(robot.get('beacon', False))),
                Parameter('initial_x', value=float(robot['x'])),
                Parameter('initial_y', value=float(robot['y'])),
                Parameter('seed', value=int(p['seed']) + agent_id),
                Parameter('method', value=p['method']),
                Parameter('control_rate_hz', value=float(p['control_rate_hz'])),
                # In the batch every agent answers every step (a list entry each): the
                # world then holds each step until all have (strict lockstep).
                *([Parameter('keepalive_hz', value=float(p['control_rate_hz']))]
                  if p['sensor_batch'] else []),
                Parameter('localization_period_s', value=float(p['localization_period_s'])),
                Parameter('placement_std_m', value=float(p['placement_std_m'])),
                Parameter('partition_locally', value=bool(p['partition_locally'])),
                Parameter('type_counts', value=p['type_counts']),
                Parameter('state_rate_hz', value=float(p['state_rate_hz'])),
                Parameter('routes_rate_hz', value=float(p['routes_rate_hz'])),
                Parameter('start_type_description_service', value=False),
                # The container's clock drives the agent's (above); use_sim_time given on
                # the command line would reach this node too and subscribe it to /clock.
                Parameter('use_sim_time', value=False),
            ] + [Parameter(name, value=value) for name, value in settings.items()
                 # only what was set on the container: a params file's /** section
                 # reaches each agent node directly
                 if value != BRAIN_PARAMETERS[name].default]
            node = AgentNode(f'agent_{agent_id}', namespace=self.get_namespace(),
                             tx_sink=self._radio.extend, own_timers=False,
                             shared_inputs=bool(p['sensor_batch']),
                             command_sink=(self._command if p['sensor_batch'] else None),
                             tf_sink=self._transforms.append,
                             route_store=self._route_store,
                             replay_store=self._replay_store,
                             parameter_overrides=overrides, context=self.context,
                             start_parameter_services=False)
            if self._sim_time is not None:
                self._sim_time.attach_clock(node.get_clock())
            self.agents[agent_id] = node
            if _has_callbacks(node):
                executor.add_node(node)
        self._timer_clock = timer_clock
        if not p['sensor_batch']:
            self.create_timer(self._control_period, self._on_control, clock=timer_clock)
        self.create_timer(1.0 / p['state_rate_hz'], self._publish_states, clock=timer_clock)
        self.create_timer(1.0 / p['routes_rate_hz'], lambda: self._each('publish_routes'),
                          clock=timer_clock)
        status = next(iter(self.agents.values())).params['status_log_period_s'] \
            if self.agents else 0.0
        if status > 0:
            self.create_timer(status, lambda: self._each('log_status'), clock=timer_clock)
        self.create_subscription(Int32MultiArray, 'swarm/kill', self._on_kill, 10)
        if p['sensor_batch']:
            latched = QoSProfile(**qos.LATCHED)
            self.create_subscription(SensorBatch, 'swarm/sensor_batch', self._on_batch,
                                     QoSProfile(**qos.RADIO))
            self.create_subscription(FormationShape, 'swarm/shape',
                                     lambda m: self._each('on_shape', m), latched)
            self.create_subscription(GoalArray, 'swarm/goals',
                                     lambda m: self._each('on_goals', m), latched)
        self.add_on_set_parameters_callback(
            lambda params: set_brain_parameters([a.brain for a in self.agents.values()],
                                                params))
        self.get_logger().info(f'{len(self.agents)} agents composed in one process'
                               + (', inputs from swarm/sensor_batch' if p['sensor_batch']
                                  else ''))

    def _each(self, method: str, *args) -> None:
        """Call ``method`` of every agent node (the container's timers and topics)."""
        for node in list(self.agents.values()):
            getattr(node, method)(*args)

    def _publish_states(self) -> None:
        """Every agent's state and odom, then the TF of every estimate in one message."""
        self._each('publish_state')
        if self._transforms:
            self._tf.publish(TFMessage(transforms=list(self._transforms)))
            self._transforms.clear()

    def _command(self, agent_id: int, stamp: float, fx: float, fy: float) -> None:
        self._commands.append((agent_id, stamp, fx, fy))

    def _on_control(self, now: Time | None = None) -> None:
        """Step every agent's inner loop, then send the radio frames they produced.

        In the same callback (as a per-process agent does in its control loop): frames
        flushed by a timer of their own left a tick after the commands of their tick,
        and a world that steps as soon as every command is in delivered them a tick late,
        once per hop of a flood.
        """
        # Every agent's clock follows the container's time source (or the system clock,
        # without sim time): one reading serves all.
        if now is None:
            now = self._timer_clock.now()
        for node in list(self.agents.values()):
            node.on_control(now)
        self._radio.flush_if_due(now)
        if self._commands:
            msg = ForceBatch()
            msg.header.stamp = now.to_msg()
            ids, stamps, fx, fy = zip(*self._commands)
            # Arrays, which rosidl takes without checking each item.
            msg.ids = array('H', ids)
            msg.stamps, msg.fx, msg.fy = array('d', stamps), array('d', fx), array('d', fy)
            self._commands.clear()
            self._cmd_batch.publish(msg)

    def _on_batch(self, msg: SensorBatch) -> None:
        """The world's step: its time (with sim time), each agent's part of it, then,
        when a control period is due, every agent's inner loop (``_on_control``)."""
        if self._sim_time is not None:
            self._sim_time.clock_callback(Clock(clock=msg.header.stamp))
        stamp = stamp_seconds(msg.header.stamp)
        try:
            self._deliver(stamp, sensor_batch_from_msg(msg))
        except PacketError as exc:
            self.get_logger().error(f'dropped a corrupt /swarm/sensor_batch: {exc}',
                                    throttle_duration_sec=10.0)
        now = self._timer_clock.now()
        t = now.nanoseconds * 1e-9
        # Due as a timer of the control period on this clock would be (rcl skips missed
        # periods); half a microsecond of slack for sums of float steps.
        if t >= self._next_control - 5e-7:
            self._next_control = (math.floor(t / self._control_period + 5e-7) + 1) \
                * self._control_period
            self._on_control(now)

    def _deliver(self, stamp: float, inputs: SensorInputs) -> None:
        """Hand each agent of this process its part of a batch stamped ``stamp`` (s)."""
        agents = self.agents
        imu, ranges, proximity, rx, gps = inputs
        taking = [(agents[a], ax, ay) for a, ax, ay in imu if a in agents]
        if taking and stamp > 0.0:   # one Kalman prediction for all (AgentBrain.take_imu)
            AgentBrain.take_imu(stamp, [node.brain for node, _, _ in taking],
                                np.array([(ax, ay) for _, ax, ay in taking], dtype=float))
        else:
            for node, ax, ay in taking:
                node.on_imu_sample(stamp, ax, ay)
        for agent_id, x, y, std in gps:
            if agent_id in agents:
                agents[agent_id].on_gps_fix(x, y, std)
        for measured in ranges:
            if measured.receiver in agents:
                agents[measured.receiver].on_range_array(measured)
        for agent_id, (offsets, radii) in proximity.items():
            if agent_id in agents:
                agents[agent_id].on_proximity_scan(stamp, offsets, radii)
        if rx:
            # Each transmission to all its receivers here in one call (reception.receive,
            # as the headless evaluator); each receiver's frames stay in arrival order.
            now = None
            for agent_id in {r for _, _, receivers in rx for r in receivers}:
                if agent_id in agents:
                    now = agents[agent_id].radio_time(stamp)
            for _, packet, receivers in rx:
                heard = self._heard(receivers)
                if heard is not None:
                    receive(now, packet, heard)

    def _on_kill(self, msg: Int32MultiArray) -> None:
        for agent_id in msg.data:
            node = self.agents.pop(int(agent_id), None)
            self._heard.clear()
            if node is not None:
                self.executor_.remove_node(node)
                node.destroy_node()
                self.get_logger().warning(f'agent {agent_id} killed')

    def destroy_all(self) -> None:
        """Destroy every agent node."""
        for node in self.agents.values():
            node.destroy_node()
        self.agents.clear()


def _fleet_robots(path: str) -> list[dict]:
    """The fleet file's robots; FleetError names the file and what is wrong."""
    if not path:
        raise FleetError('parameter fleet_file is not set: give a fleet YAML with robots '
                         '(id, type, beacon, x, y), e.g. -p fleet_file:=fleet.yaml')
    try:
        with open(path, encoding='utf-8') as stream:
            robots = yaml.safe_load(stream)['robots']
        for robot in robots:
            int(robot['id']), int(robot['type']), float(robot['x']), float(robot['y'])
    except OSError as exc:
        raise FleetError(f'fleet_file {path}: {exc.strerror}') from None
    except (yaml.YAMLError, KeyError, TypeError, ValueError) as exc:
        raise FleetError(f'fleet_file {path} is not a fleet (robots: [{{id, type, beacon, x, '
                         f'y}}, ...]): {type(exc).__name__} {exc}') from None
    return robots


class FleetError(ValueError):
    """A fleet file that cannot be read; the message names it."""


def main(args=None) -> None:
    """Run a composed swarm (``ros2 run swarm_agent composed_node``)."""
    executors = []

    def make_container() -> ComposedAgents:
        executors.append(make_executor())   # the agents' nodes are added to it
        return ComposedAgents(executors[0])

    run_node(make_container, 'composed_node', args, executor=lambda: executors[0],
             stop=ComposedAgents.destroy_all)


if __name__ == '__main__':
    main(sys.argv)
