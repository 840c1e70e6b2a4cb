"""sim_node: the simulated world of the swarm (replaces the thesis's Gazebo, 4.1).

ROS wiring of the world model (``swarm_sim.world_model.World``, as the headless
evaluator runs it): parameters (generated from
``swarm_sim.sim_parameters.SimParameters``, the radio medium's ``medium.*`` included;
read-only but ``loss``, ``radio_range_m``, ``radio_wall_speed_mps``, ``rogue`` and
``real_time_factor``, which the on-set callback applies), commands and faults in,
readings out as messages (``swarm_sim.conversions``), ``/clock``. Paced by
``swarm_sim.pacing`` (``real_time_factor``, ``max_agent_lag_s`` behind the slowest
agent); as fast as possible, it steps once every agent has answered the current time (a
guard condition, after the callbacks of its wait), else at ``clock_rate_hz``.

Topics (K: a robot id; per-robot topics have no default QoS event handlers,
``swarm_common.ros_support``: with them 50 robots made a wait set of 750 entities)
  published  ``/clock``; ``agent_K/imu`` (sensor_msgs/Imu, map-frame acceleration);
             ``agent_K/gps`` (geometry_msgs/PoseWithCovarianceStamped, beacons only);
             ``agent_K/ranges`` (swarm_msgs/RangeArray, TOA ranges to beacon
             neighbours); ``agent_K/proximity`` (swarm_msgs/ProximityArray, neighbours
             within ``proximity_range_m``); ``agent_K/radio/rx`` (swarm_msgs/
             RadioPacketArray, the medium's deliveries since the last batch);
             ``swarm/sensor_batch`` (swarm_msgs/SensorBatch, with ``sensor_batch``: those
             five topics of every robot in one message at every step and with every
             held-clock repeat, empty when nothing was due: composed agents step on it);
             ``swarm/truth`` (swarm_msgs/SwarmTruth, metrics only) and ``/tf`` (the
             truth as ``map -> truth/agent_K/base_link``); ``swarm/markers``
             (visualization_msgs/MarkerArray, ``marker_rate_hz``, 0 turns it off);
             ``mission/radio/rx`` (swarm_msgs/RadioPacketArray, the route adverts the
             mission computer's radio heard, with ``mission_radio``: the mission node
             learns from them which agents are alive, swarm_sim.mission_mesh)
  subscribed ``agent_K/cmd_force`` (geometry_msgs/WrenchStamped, N, map frame) or, with
             ``sensor_batch``, ``swarm/cmd_batch`` (swarm_msgs/ForceBatch);
             ``radio/tx`` (swarm_msgs/RadioPacketArray, the agents' batches);
             ``agent_K/state``, ``swarm/goals``, ``swarm/shape`` (markers only)
  faults     ``swarm/kill``, ``swarm/radio_off``, ``swarm/radio_on`` (std_msgs/
             Int32MultiArray of robot ids), ``swarm/move_obstacle`` (std_msgs/
             Float64MultiArray ``[k, dx, dy]``), as ``World.inject`` applies them; run-time
             parameters ``loss``, ``radio_range_m``, ``radio_wall_speed_mps``, ``rogue`` (a
             transmitter without the key, ``swarm_sim.rogue``: its frames join the
             deliveries on ``agent_K/radio/rx``) (``World.apply_setting``; a bad value is
             refused with the reason).
"""

from __future__ import annotations

import math
import sys
import time

from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, Int32MultiArray
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from swarm_agent.conversions import (
    frames_or_log,
    frames_to_msg,
    sensor_batch_to_msg,
    stamp_seconds,
)
from swarm_common import qos
from swarm_common.conversions import goals_from_msg, shape_from_msg
from swarm_common.ros_parameters import declare
from swarm_common.ros_support import lean_publisher, lean_subscription, run_node
from swarm_msgs.msg import (
    AgentState,
    ForceBatch,
    FormationShape,
    GoalArray,
    RadioPacketArray,
    SensorBatch,
    SwarmTruth,
)
from swarm_sim import conversions as conv
from swarm_sim.markers import swarm_markers
from swarm_sim.medium import RUNTIME_SETTINGS
from swarm_sim.mission_mesh import RelayedListener
from swarm_sim.pacing import Pacer
from swarm_sim.run_record import RunRecord
from swarm_sim.sim_parameters import SIM_PARAMETERS, world_from_parameters
from swarm_sim.world_model import Readings

# Wall seconds between repeats of an unchanged /clock while the world waits for agents.
HELD_CLOCK_PERIOD_S = 0.25


class SimNode(Node):
    """The world; see the module docstring."""

    def __init__(self, **kwargs) -> None:
        super().__init__('sim', **kwargs)
        # Generated from SimParameters: described, ranged, read-only but the live ones.
        p = self.params = declare(self, SIM_PARAMETERS)
        self.fleet, self.types, self.world = world_from_parameters(p)
        self.ids = self.world.ids
        if p['radio_wall_speed_mps'] > 0:
            self._apply('radio_wall_speed_mps', p['radio_wall_speed_mps'])
        self.pacer = Pacer(len(self.fleet), self.world.dt, p['real_time_factor'],
                           p['max_agent_lag_s'], p['wait_for_agents_s'], p['agent_stall_s'],
                           time.monotonic())
        self._warned: set[int] = set()
        self._clock_wall = -math.inf  # wall time of the last /clock message
        self._observed = p['truth_subscribers'] <= 0
        self._record = RunRecord(p['record_dir'], self.ids) if p['record_dir'] else None
        sensor, radio, state, imu, command = (
            QoSProfile(**q) for q in (qos.SENSOR, qos.RADIO, qos.STATE, qos.IMU, qos.COMMAND))
        self.clock_pub = self.create_publisher(Clock, '/clock', 10)
        self.truth_pub = self.create_publisher(SwarmTruth, 'swarm/truth', state)
        self.tf_pub = self.create_publisher(TFMessage, '/tf', state)   # reliable, as tf2's
        self.marker_pub = self.create_publisher(MarkerArray, 'swarm/markers', state)
        # What the markers show beyond the world: modes, goals and the shape, heard only
        # when markers are on (a state subscription per robot costs callbacks).
        self._modes, self._goals, self._shape = {}, [], None
        if p['marker_rate_hz'] > 0:
            self._next_marker = 0.0
            latched = QoSProfile(**qos.LATCHED)
            self.create_subscription(GoalArray, 'swarm/goals', lambda m: setattr(
                self, '_goals', goals_from_msg(m)), latched)
            self.create_subscription(FormationShape, 'swarm/shape', self._on_shape, latched)
            for r in self.fleet:
                lean_subscription(self, AgentState, f'agent_{r.id}/state',
                                  lambda m: self._modes.__setitem__(m.id, m.mode), state)
        self.batch_pub = (self.create_publisher(SensorBatch, 'swarm/sensor_batch', radio)
                          if p['sensor_batch'] else None)
        self.pubs: dict[tuple[str, int], object] = {}   # (kind, robot id): publisher
        kinds = {'gps': sensor, 'imu': imu, 'ranges': sensor, 'rx': radio, 'proximity': sensor}
        kinds = {k: q for k, q in kinds.items() if not p['sensor_batch']
                 and (k != 'proximity' or self.world.proximity is not None)}
        for i, r in enumerate(self.fleet):
            for kind, profile in kinds.items():
                if kind != 'gps' or r.is_beacon:
                    msg_type, topic = conv.ROBOT_TOPICS[kind]
                    self.pubs[kind, r.id] = lean_publisher(self, msg_type,
                                                           f'agent_{r.id}/{topic}', profile)
            if not p['sensor_batch']:
                lean_subscription(self, WrenchStamped, f'agent_{r.id}/cmd_force',
                                  lambda m, i=i: self._command(
                                      [i], [[m.wrench.force.x, m.wrench.force.y]],
                                      [stamp_seconds(m.header.stamp)]), command)
        if p['sensor_batch']:
            # Composed agents answer in kind: every command of a step in one ForceBatch.
            self.create_subscription(ForceBatch, 'swarm/cmd_batch', self._on_force_batch,
                                     QoSProfile(**qos.COMMAND_BATCH))
        self._tx_sub = self.create_subscription(RadioPacketArray, 'radio/tx', self._on_tx, radio)
        listener = getattr(self.world.medium, 'listener', None)
        self._mission_radio = listener if isinstance(listener, RelayedListener) else None
        self.mission_rx_pub = (self.create_publisher(RadioPacketArray, 'mission/radio/rx', radio)
                               if self._mission_radio is not None else None)
        for fault in ('kill', 'radio_off', 'radio_on', 'move_obstacle'):
            self.create_subscription(
                Float64MultiArray if fault == 'move_obstacle' else Int32MultiArray,
                f'swarm/{fault}', lambda m, f=fault: self._on_fault(f, m.data), 10)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._step_now = self.create_guard_condition(self._on_tick)
        self.create_timer(1.0 / p['clock_rate_hz'], self._on_tick)
        self.get_logger().info(
            f'{len(self.fleet)} robots ({int(self.world.is_beacon.sum())} beacons), '
            f'{len(self.world.obstacles)} obstacles, backend {self.world.backend.name}, '
            f'{p["physics_rate_hz"]:.0f} Hz physics, real-time factor '
            f'{p["real_time_factor"] or "max"}')

    # -- inputs
    def _on_force_batch(self, msg: ForceBatch) -> None:
        rows, forces, stamps, errors = conv.force_batch_rows(msg, self.world.index)
        for error in errors:
            self.get_logger().error(f'swarm/cmd_batch: {error}', throttle_duration_sec=10.0)
        self._command(rows, forces, stamps)

    def _command(self, rows: list[int], forces, stamps) -> None:
        """Force commands (N, map frame) of robots ``rows``, stamped on their agents' clocks;
        then, once every agent has answered, a step (module docstring)."""
        if not rows:
            return
        refused, clamped = self.world.command(forces, rows)
        for i in sorted(set(refused + clamped) - self._warned):   # once per robot
            self._warned.add(i)
            self.get_logger().warning(f'robot {self.ids[i]}: ' + (
                'rejected a non-finite force command; holding the last valid one'
                if i in refused else f'force clamped to {self.params["max_force"]} N'))
        now = time.monotonic()
        for i, stamp in ((i, s) for i, s in zip(rows, stamps) if i not in refused):
            self.pacer.heard(i, stamp, now)
        # Through the guard condition, so the step runs after the callbacks of this wait: a
        # radio batch sent with the commands is on the air before the step delivers (else
        # a flood's hops are delivered a tick late each).
        if self._observed and self.pacer.all_answered(self.world.t, self.world.alive, now):
            self._step_now.trigger()

    def _on_tx(self, msg: RadioPacketArray) -> None:
        """This radio batch and up to a few per robot waiting behind it (rclpy takes one
        per wait: 50 agents' batches queued until frames went on the air 1.4 s late)."""
        self._transmit(msg)
        sub = self._tx_sub
        for _ in range(4 * len(self.fleet)):
            with sub.handle:
                taken = sub.handle.take_message(sub.msg_type, sub.raw)
            if taken is None:
                return
            self._transmit(taken[0])

    def _transmit(self, msg: RadioPacketArray) -> None:
        t = self.world.t   # a frame is on the air from its stamp (the agent's clock), not later
        for stamp, packet in frames_or_log(msg, self.get_logger(), 'radio/tx'):
            if packet.source in self.world.index:
                self.world.medium.transmit(stamp if 0.0 < stamp < t else t, packet)

    def _on_fault(self, fault: str, data) -> None:
        for line in self.world.inject(fault, data):
            self.get_logger().warning(line)

    def _apply(self, name: str, value: float) -> None:
        self.world.apply_setting(name, value)
        self.get_logger().info(f't={self.world.t:.1f} s: {name} set to {value}')

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        for param in params:   # every value checked before any is applied
            try:
                RUNTIME_SETTINGS.get(param.name, lambda value: value)(param.value)
            except (TypeError, ValueError) as exc:
                return SetParametersResult(successful=False, reason=f'{param.name}: {exc}')
        for param in params:
            if param.name in RUNTIME_SETTINGS:
                self._apply(param.name, float(param.value))
            elif param.name == 'real_time_factor':
                self.pacer.set_rtf(float(param.value), self.world.t, time.monotonic())
        return SetParametersResult(successful=True)

    # -- stepping
    def _on_tick(self) -> None:
        world, now = self.world, time.monotonic()
        if not self._observed:
            # Start-up: hold t = 0 until the run's observers (the launcher's monitor) are
            # matched or wait_for_agents_s is over, else a fast run starts unrecorded.
            self._observed = (self.truth_pub.get_subscription_count()
                              >= self.params['truth_subscribers']
                              or now - self.pacer.started >= self.params['wait_for_agents_s'])
        steps = self.pacer.steps_for_tick(world.t, world.alive, now) if self._observed else 0
        for _ in range(steps):
            world.step()
        if steps:
            self._publish(world.sense())
        elif now - self._clock_wall >= HELD_CLOCK_PERIOD_S:
            # Held for a slow agent: repeat the time now and then for late-starting nodes
            # (not at every tick: each /clock message wakes every agent process).
            self._publish_clock(world.t)
            if (held := self.pacer.holder(world.alive, now)) is not None:
                self.get_logger().warning(f't={world.t:.2f} s: held by robot {self.ids[held]}: '
                                          + self.pacer.describe(held, now),
                                          throttle_duration_sec=5.0)

    def _publish_clock(self, t: float, batch: SensorBatch | None = None) -> None:
        """/clock at ``t`` and, with ``sensor_batch``, the step's batch (an empty one when
        no reading was due or the world holds its time): composed agents step on it."""
        stamp = conv.stamp_of(t)
        self.clock_pub.publish(Clock(clock=stamp))
        if self.batch_pub is not None:
            self.batch_pub.publish(batch if batch is not None else sensor_batch_to_msg(stamp))
        self._clock_wall = time.monotonic()

    def _publish(self, readings: Readings) -> None:
        world, t, p = self.world, readings.t, self.params
        imu_std, prox_std = world.imu.noise_std, p['proximity_std']
        if self.batch_pub is None:
            self._publish_clock(t)
        else:
            self._publish_clock(t, conv.sensor_batch(readings, self.ids, imu_std, prox_std))
            readings.rx = readings.imu = readings.gps = readings.ranges = None
            readings.proximity = None
        for kind, agent, msg in conv.robot_messages(readings, self.ids, imu_std, prox_std):
            self.pubs[kind, agent].publish(msg)
        if self._mission_radio is not None and (heard := self._mission_radio.take()):
            self.mission_rx_pub.publish(frames_to_msg(heard, conv.stamp_of(t)))
        if readings.truth is not None:
            self.truth_pub.publish(conv.truth_msg(conv.stamp_of(t), self.fleet, readings.truth))
            self.tf_pub.publish(conv.truth_tf(conv.stamp_of(t), self.fleet, readings.truth))
            if self._record is not None:
                self._record.add(readings.truth)
        if p['marker_rate_hz'] > 0 and t + 1e-9 >= self._next_marker:
            self._next_marker = t + 1.0 / p['marker_rate_hz']
            self.marker_pub.publish(swarm_markers(
                conv.stamp_of(t), self.ids, [r.type for r in self.fleet], world.radii,
                world.backend.positions(), world.alive, modes=self._modes, goals=self._goals,
                region=self._shape.region if self._shape is not None else None,
                obstacles=world.obstacles, links=world.links_by_index()))

    def _on_shape(self, msg: FormationShape) -> None:
        try:
            self._shape = shape_from_msg(msg)
        except ValueError as exc:
            self.get_logger().warning(f'swarm/shape: {exc}; markers keep the last shape')

    def close(self) -> None:
        """Flush the run record and release the physics."""
        if self._record is not None:
            self._record.close(self.world)
        self.world.close()


def main(args=None) -> None:
    """Run the simulator (``ros2 run swarm_sim sim_node``): a bad parameter or file is
    refused in one line (``swarm_common.ros_support.run_node``)."""
    run_node(SimNode, 'sim_node', args, stop=SimNode.close)


if __name__ == '__main__':
    main(sys.argv)
