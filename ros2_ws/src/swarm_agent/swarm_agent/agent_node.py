"""agent_node: one robot's brain on ROS 2 (a thin adapter around ``AgentBrain``).

Topics (relative names; the robot's own are under ``agent_K/``, K = ``agent_id``, e.g.
``agent_7/state``: the node runs in its swarm's namespace, ``/`` or e.g. ``/swarm_a``,
beside the swarm's other nodes, and the launch plan names it ``agent_K``. ``/tf`` is
absolute, as tf2 expects; a swarm in a namespace remaps it and ``/clock`` into the
namespace, swarm_bringup.launch_plan)

Subscribed
  ``imu`` (sensor_msgs/Imu)                    accelerometer, map frame -> Kalman prediction
  ``gps`` (geometry_msgs/PoseWithCovarianceStamped)  absolute fix, beacons only
  ``ranges`` (swarm_msgs/RangeArray)           TOA ranges to beacon neighbours
  ``proximity`` (swarm_msgs/ProximityArray)    neighbours' offsets and radii, measured
                                               (collision avoidance)
  ``radio/rx`` (swarm_msgs/RadioPacketArray)   what this robot's radio heard (batches)
  ``pose`` (geometry_msgs/PoseStamped)         external (camera) pose, hardware mode only
  ``swarm/shape`` (swarm_msgs/FormationShape)  desired shape (transient local)
  ``swarm/goals`` (swarm_msgs/GoalArray)       goal states (transient local)

Published
  ``radio/tx`` (swarm_msgs/RadioPacketArray)   what this robot's radio sends (batches at
                                               ``radio_tx_hz``, as the medium delivers)
  ``cmd_force`` (geometry_msgs/WrenchStamped)  LQR force command, map frame (simulation)
  ``cmd_vel`` (geometry_msgs/Twist)            velocity setpoint, body frame ``agent_K/
                                               base_link`` (REP 103; hardware)
  ``state`` (swarm_msgs/AgentState)            estimate, mode, assignment
  ``odom`` (nav_msgs/Odometry)                 estimate with its covariance: pose in
                                               ``map``, twist in ``agent_K/base_link``
  ``/tf`` (tf2_msgs/TFMessage)                 ``map -> agent_K/base_link`` (the estimate)
  ``routes`` (swarm_msgs/RouteTable)           DSDV route table

``state``, ``odom`` and ``/tf`` go out together at ``state_rate_hz``. The body frame's
heading (``swarm_agent.conversions``, REP 103/105): in simulation the brain estimates
none and the frame keeps the map axes (yaw 0: the body-frame twist and ``cmd_vel`` equal
the map-frame velocity and setpoint); with ``external_pose`` (hardware) it is the
camera's yaw, and ``cmd_vel`` is the setpoint rotated into the robot's frame.

Radio frames are authenticated (``swarm_agent.frame_auth``, docs/security.md) under the
keys of ``swarm_key_file`` (empty: the development key shipped in config/, with a
warning); a key file that cannot be used stops the node with one line naming it.
``auth:=false`` turns authentication off, only to compare with and without.

The agent never subscribes to ``/swarm/truth``. With ``partition_locally`` the agent
computes the partition of the announced shape itself (the thesis's future work: no
central server); the mission node then only announces shapes.
"""

from __future__ import annotations

from collections.abc import Callable
import copy
import math
import os
import sys

from geometry_msgs.msg import (
    PoseStamped,
    PoseWithCovarianceStamped,
    TransformStamped,
    Twist,
    WrenchStamped,
)
from nav_msgs.msg import Odometry
import numpy as np
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.clock import ClockType
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.time import Time
from sensor_msgs.msg import Imu
from tf2_msgs.msg import TFMessage

from swarm_agent.agent_factory import DEFAULT_KEY_FILE, make_brain, swarm_keyring, type_counts_from
from swarm_agent.brain_config import BrainConfig, BrainConfigError
from swarm_agent.conversions import (
    frames_or_log,
    frames_to_msg,
    Heading,
    MAP_ALIGNED,
    proximity_from_msg,
    routes_to_msg,
    SensorMessageError,
    setpoint_to_twist,
    snapshot_to_odometry,
    snapshot_to_state,
    snapshot_to_transform,
    stamp_seconds,
    yaw_of,
)
from swarm_agent.frame_auth import ReplayStore
from swarm_agent.packet import Packet
from swarm_agent.route_table import RouteStore
from swarm_common import qos
from swarm_common.conversions import goals_from_msg, shape_from_msg
from swarm_common.jit import warm
from swarm_common.parameters import ParameterError, set_live, spec_table
from swarm_common.ros_parameters import declare
from swarm_common.ros_support import lean_publisher, lean_subscription, run_node
from swarm_common.shapes import ShapeError
from swarm_mission.partition import partition, PartitionError
from swarm_msgs.msg import (
    AgentState,
    FormationShape,
    GoalArray,
    ProximityArray,
    RadioPacketArray,
    RangeArray,
    RouteTable,
)

PARAMETERS = {
    'agent_id': (0, 'Agent id, 0..65534; also its radio address'),
    'agent_type': (1, 'Robot type of thesis Table 4.1 (1, 2 or 3)'),
    'is_beacon': (False, 'Beacon robots have absolute positioning (GPS)'),
    'method': ('bubble', 'Formation method: bubble, fractal or forces'),
    'initial_x': (0.0, 'Deployment position x in metres (initial estimate)'),
    'initial_y': (0.0, 'Deployment position y in metres (initial estimate)'),
    'placement_std_m': (0.3, 'Standard deviation (m per axis) of the deployment position: '
                             "the initial estimate's uncertainty until the first fix"),
    'seed': (0, "Seed of this agent's random generator"),
    'control_rate_hz': (50.0, 'Rate of the LQR inner loop and of cmd_force'),
    'keepalive_hz': (10.0, 'Rate at which an unchanged cmd_force is repeated'),
    'radio_tx_hz': (20.0, 'Rate at which the frames sent since the last batch go out'),
    'localization_period_s': (3.0, 'Period of trilateration updates (thesis 4.2: 3 s)'),
    'state_rate_hz': (2.0, 'Rate of the state introspection topic'),
    'routes_rate_hz': (0.5, 'Rate of the routes topic (DSDV table: about N entries)'),
    'status_log_period_s': (30.0, 'Period of the one-line status log (sim seconds); 0: off'),
    'external_pose': (False, 'Hardware: use the camera pose topic instead of the LPS'),
    'external_pose_std': (0.01, 'Standard deviation of the camera pose in metres'),
    'external_heading_std': (0.05, 'Standard deviation of the camera heading in radians '
                                   '(the tracker is within 3 degrees rms)'),
    'partition_locally': (False, 'Partition announced shapes on the agent itself'),
    'type_counts': ('', 'Swarm composition for local partitioning, e.g. 1:20,2:20,3:10'),
    'partition_seed': (0, 'Seed of the local partition (same on every agent)'),
    'formation_margin_m': (0.6, 'Band (m) inside the contour a local partition leaves free '
                                "for localization error (as the mission's); 0 on hardware"),
    'robot_types_file': ('', 'Robot type table YAML (default: the package config)'),
    'swarm_key_file': ('', 'Swarm key file of the authenticated radio frames (empty: the '
                           'development key in config/, simulation only; docs/security.md)'),
    'auth': (True, 'Authenticate radio frames; false only to compare with and without'),
}
_warned_keys: set[str] = set()   # one key warning per process (composed: 50 agents)


# The brain's tunables, generated from its configuration dataclasses (one source of
# truth, swarm_common.parameters): ``hold_radius``, ``localization.gate``, ...
BRAIN_PARAMETERS = spec_table(BrainConfig)


def declare_brain_parameters(node: Node) -> dict:
    """Declare every generated brain parameter on ``node`` (description, range,
    read-only: swarm_common.ros_parameters); their values by name."""
    return declare(node, BRAIN_PARAMETERS)


def set_brain_parameters(brains, params) -> SetParametersResult:
    """Apply run-time changes of generated parameters to running brains (an on-set
    parameters callback): all or nothing, with the reason of a refusal."""
    changes = [(p.name, p.value) for p in params if p.name in BRAIN_PARAMETERS]
    try:
        for name, value in changes:   # check every change on a copy first
            for brain in brains:
                set_live(copy.deepcopy(brain.config), name, value)
        for name, value in changes:
            for brain in brains:
                set_live(brain.config, name, value)
    except ParameterError as exc:
        return SetParametersResult(successful=False, reason=str(exc))
    return SetParametersResult(successful=True)


# A first control step later than this in sim time is a (re)start mid-run (s).
LATE_START_S = 2.0
RATES_HZ = ('control_rate_hz', 'keepalive_hz', 'radio_tx_hz', 'state_rate_hz',
            'routes_rate_hz')


Frames = list[tuple[float, Packet]]  # (transmission time in seconds, frame)


class RadioBatcher:
    """Radio frames sent since the last batch, published as one RadioPacketArray on
    /radio/tx at most every ``period`` seconds of the node's clock.

    Flushed from the control loop that produced the frames (an agent's, or composed_node's
    for all its agents), not from a timer of its own: one timer less to wake the process
    for, and the frames of a step leave with that step's commands.
    """

    def __init__(self, publisher, period: float) -> None:
        self.pending: Frames = []
        self._publisher = publisher
        self._period = period
        self._due = -math.inf

    def extend(self, frames: Frames) -> None:
        """Queue ``(stamp, packet)`` frames for the next batch."""
        self.pending.extend(frames)

    def flush_if_due(self, now: Time) -> None:
        """Publish the queued frames if a period has passed since the last batch."""
        t = now.nanoseconds * 1e-9
        if t < self._due:
            return
        self._due = t + self._period
        if self.pending:
            batch = frames_to_msg(self.pending, now.to_msg())
            self.pending.clear()
            self._publisher.publish(batch)


class AgentNode(Node):
    """ROS wiring of one AgentBrain; see the module docstring."""

    def __init__(self, node_name: str = 'agent', namespace: str | None = None,
                 tx_sink: Callable[[Frames], None] | None = None,
                 own_timers: bool = True, shared_inputs: bool = False,
                 command_sink: Callable[[int, float, float, float], None] | None = None,
                 tf_sink: Callable[[TransformStamped], None] | None = None,
                 route_store: RouteStore | None = None,
                 replay_store: ReplayStore | None = None, **kwargs) -> None:
        """``tx_sink`` takes the radio frames instead of this node's own batching
        publisher (composed_node: one batch of every agent's frames per period).
        Without ``own_timers`` the node creates no control and introspection timers:
        its owner calls ``on_control``, ``publish_state`` and ``publish_routes`` at the
        node's ``control_rate_hz``, ``state_rate_hz`` and ``routes_rate_hz``
        (composed_node: one timer of each drives every agent of the process). With
        ``shared_inputs`` it subscribes to none of imu, gps, ranges, proximity, radio/rx,
        shape and goals: its owner hands them over (``on_imu_sample``, ``on_gps_fix``,
        ``on_range_array``,
        ``on_proximity_scan``, ``on_radio_frames``, ``on_shape``, ``on_goals``;
        composed_node with the world's /swarm/sensor_batch). ``command_sink(agent id,
        stamp s, fx, fy)`` takes the force commands instead of the cmd_force topic
        (composed_node: one ForceBatch per step), ``tf_sink`` the transform of the
        estimate instead of this node's /tf publisher (composed_node: one TFMessage of
        every agent per state period). ``route_store`` and ``replay_store`` hold the route
        tables and replay windows of the process's brains (composed_node: one of each for
        all; ``swarm_agent.route_table``, ``frame_auth.ReplayStore``)."""
        super().__init__(node_name, namespace=namespace, **kwargs)
        # The node's own parameters are read once, at start: read-only.
        for name, (default, text) in PARAMETERS.items():
            self.declare_parameter(name, default,
                                   ParameterDescriptor(description=text, read_only=True))
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        settings = declare_brain_parameters(self)
        for rate in RATES_HZ:
            if not p[rate] > 0.0:
                raise BrainConfigError(
                    f'parameter {rate} must be above 0 Hz, got {p[rate]}: set it in '
                    f'config/agent.yaml or with --ros-args -p {rate}:=<Hz>')
        if not (math.isfinite(p['formation_margin_m']) and p['formation_margin_m'] >= 0.0):
            raise BrainConfigError(
                f'parameter formation_margin_m must be a finite number >= 0 m, got '
                f'{p["formation_margin_m"]}: set it in config/agent.yaml or with --ros-args '
                '-p formation_margin_m:=0.6')
        if not (math.isfinite(p['external_heading_std']) and p['external_heading_std'] >= 0.0):
            raise BrainConfigError(
                f'parameter external_heading_std must be a finite number >= 0 rad, got '
                f'{p["external_heading_std"]}: e.g. --ros-args -p external_heading_std:=0.05')
        self.params = p
        keyring = swarm_keyring(p['swarm_key_file'] or None) if p['auth'] else None
        self.brain = make_brain(
            agent_id=p['agent_id'], agent_type=p['agent_type'], is_beacon=p['is_beacon'],
            method=p['method'], initial_position=(p['initial_x'], p['initial_y']),
            seed=p['seed'], localization_period_s=p['localization_period_s'],
            robot_types_file=p['robot_types_file'] or None,
            external_pose=p['external_pose'], initial_position_std=p['placement_std_m'],
            settings=settings, keyring=keyring, auth=p['auth'], route_store=route_store,
            replay_store=replay_store)
        self.add_on_set_parameters_callback(
            lambda params: set_brain_parameters([self.brain], params))
        self._type_counts = p['type_counts']
        self._last_setpoint: tuple[float, float] | None = None
        # The body frame's heading (module docstring): map-aligned until a camera pose.
        self.heading: Heading = MAP_ALIGNED
        self._radio_lag_max = 0.0  # s: worst delay from the medium to this callback
        self._stepped = False      # the control loop has run once (_late_start)
        self._last_force: tuple[float, float] | None = None
        self._last_force_t = -1e9
        self._keepalive_s = 1.0 / p['keepalive_hz']

        latched, sensor, radio, state = (
            QoSProfile(**profile) for profile in (qos.LATCHED, qos.SENSOR, qos.RADIO, qos.STATE))
        # Frames go out in batches, like the medium's deliveries: one DDS message per
        # frame would be 466 messages a second for 50 agents, more than the simulator's
        # executor takes (one message per subscription per wait): measured, half of
        # the frames are then lost in DDS and the assignment consensus breaks
        # (agreement 0.18 on the 50-agent demo).
        self._command_sink = command_sink
        me = f'agent_{p["agent_id"]}/'   # this robot's topics (module docstring)
        self._radio = (RadioBatcher(lean_publisher(self, RadioPacketArray, 'radio/tx', radio),
                                    1.0 / p['radio_tx_hz'])
                       if tx_sink is None else None)
        self._tx_sink = self._radio.extend if tx_sink is None else tx_sink
        # Per-robot topics without rclpy's default QoS event handlers: see
        # ``lean_publisher`` (they made most of a composed process's wait set).
        self._cmd_force = (lean_publisher(self, WrenchStamped, me + 'cmd_force',
                                          QoSProfile(**qos.COMMAND))
                           if command_sink is None else None)
        self._cmd_vel = lean_publisher(self, Twist, me + 'cmd_vel', sensor)
        self._state = lean_publisher(self, AgentState, me + 'state', state)
        self._odom = lean_publisher(self, Odometry, me + 'odom', state)
        # Reliable and volatile, as tf2's listeners subscribe; /tf is one topic for the
        # whole tree (absolute, as tf2 tools expect; the frames carry the robot's name).
        self._tf = lean_publisher(self, TFMessage, '/tf', state) if tf_sink is None else None
        self._tf_sink = tf_sink or (
            lambda transform: self._tf.publish(TFMessage(transforms=[transform])))
        self._routes = lean_publisher(self, RouteTable, me + 'routes', state)

        if p['is_beacon'] and not shared_inputs:
            lean_subscription(self, PoseWithCovarianceStamped, me + 'gps', self._on_gps, sensor)
        if p['external_pose']:
            lean_subscription(self, PoseStamped, me + 'pose', self._on_pose, sensor)
        if not shared_inputs:
            lean_subscription(self, Imu, me + 'imu', self._on_imu, QoSProfile(**qos.IMU))
            lean_subscription(self, RangeArray, me + 'ranges', self.on_range_array, sensor)
            lean_subscription(self, ProximityArray, me + 'proximity', self.on_proximity_array,
                              sensor)
            lean_subscription(self, RadioPacketArray, me + 'radio/rx', self._on_radio, radio)
            lean_subscription(self, FormationShape, 'swarm/shape', self.on_shape, latched)
            lean_subscription(self, GoalArray, 'swarm/goals', self.on_goals, latched)

        # Every kernel compiled (or loaded from numba's cache) before the first step: compiled
        # at its first call instead, each took its robot's control loop away for up to
        # seconds mid-run, and five agents compiling at once (numba's cache cold) left the
        # emulated world of the hardware-in-the-loop demo without CPU for 3-6 s. A no-op
        # once warm (composed_node, the launcher's forked agents).
        warm()
        if own_timers:
            self.create_timer(1.0 / p['control_rate_hz'], self.on_control)
            self.create_timer(1.0 / p['state_rate_hz'], self.publish_state)
            self.create_timer(1.0 / p['routes_rate_hz'], self.publish_routes)
            if p['status_log_period_s'] > 0:
                self.create_timer(p['status_log_period_s'], self.log_status)
        # Once the node has started: a node that refuses its input prints one line only.
        self._warn_key(keyring)
        self.get_logger().info(
            f'agent {p["agent_id"]} type {p["agent_type"]} beacon={p["is_beacon"]} '
            f'method={p["method"]} ready')

    def _warn_key(self, keyring) -> None:
        """Say, once per process, when frames are not protected by a secret key."""
        if keyring is None:
            text = ('radio frames are NOT authenticated (auth:=false): any transmitter can '
                    'steer this swarm')
        elif keyring.development:
            text = (f'radio frames are authenticated with the published development key '
                    f'{DEFAULT_KEY_FILE}: set swarm_key_file to a secret key for a '
                    'deployment (docs/security.md)')
        else:
            return
        if text not in _warned_keys:
            _warned_keys.add(text)
            self.get_logger().warning(text)

    # -- time
    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    # -- inputs
    def _on_imu(self, msg: Imu) -> None:
        # Integrate over the sample's own time stamps: the mean acceleration of an
        # interval times the interval. Arrival times jitter by tens of milliseconds under
        # load, and a ~1 m/s^2 manoeuvre times that jitter random-walks the velocity
        # estimate by centimetres per second at every sample (measured: estimates
        # hundreds of metres off after a minute when integrating over arrival times).
        a = msg.linear_acceleration
        self.on_imu_sample(stamp_seconds(msg.header.stamp), a.x, a.y)

    def on_imu_sample(self, stamp: float, ax: float, ay: float) -> None:
        """One IMU sample: map-frame mean acceleration (m/s^2) stamped ``stamp`` (s)."""
        self.brain.on_imu(stamp if stamp > 0.0 else self._now(), np.array([ax, ay]))

    def _on_gps(self, msg: PoseWithCovarianceStamped) -> None:
        pos = msg.pose.pose.position
        self.on_gps_fix(pos.x, pos.y, float(np.sqrt(max(msg.pose.covariance[0], 1e-12))))

    def on_gps_fix(self, x: float, y: float, std: float) -> None:
        """A beacon's absolute fix (m, map frame; ``std`` m per axis), taken now."""
        self.brain.on_gps(self._now(), np.array([x, y]), std)

    def _on_pose(self, msg: PoseStamped) -> None:
        pos = msg.pose.position
        self.brain.on_gps(self._now(), np.array([pos.x, pos.y]),
                          self.params['external_pose_std'])
        self.set_heading(yaw_of(msg.pose.orientation))

    def set_heading(self, yaw: float, rate: float = 0.0, rate_std: float = 0.0) -> None:
        """The robot's measured heading (rad, CCW from map x) and its rate (rad/s): the
        body frame of ``cmd_vel``, ``odom`` and the TF from now on (hardware)."""
        if math.isfinite(yaw):
            self.heading = Heading(yaw, self.params['external_heading_std'],
                                   rate if math.isfinite(rate) else 0.0, rate_std)

    def on_range_array(self, msg: RangeArray) -> None:
        """TOA ranges to beacon neighbours (swarm_msgs/RangeArray)."""
        self.brain.on_ranges(self._now(),
                             [(r.beacon_id, r.range, r.stddev) for r in msg.ranges])

    def on_proximity_array(self, msg: ProximityArray) -> None:
        """Proximity scan: neighbours' offsets and radii (swarm_msgs/ProximityArray); a
        malformed one is dropped with a throttled error line."""
        try:
            offsets, radii = proximity_from_msg(msg)
        except SensorMessageError as exc:
            self.get_logger().error(f'dropped a malformed scan on proximity: {exc}',
                                    throttle_duration_sec=10.0)
            return
        self.on_proximity_scan(0.0, offsets, radii)

    def on_proximity_scan(self, stamp: float, offsets: np.ndarray, radii: np.ndarray) -> None:
        """Neighbours' offsets (k, 2) and radii (k,) seen at ``stamp`` (s; 0: now)."""
        self.brain.on_proximity(stamp if stamp > 0.0 else self._now(), offsets, radii)

    def _on_radio(self, msg: RadioPacketArray) -> None:
        self.on_radio_frames(stamp_seconds(msg.header.stamp),
                             frames_or_log(msg, self.get_logger(), 'radio/rx'))

    def on_radio_frames(self, stamp: float, frames: Frames) -> None:
        """Frames the radio heard, delivered in a batch stamped ``stamp`` (s)."""
        now = self.radio_time(stamp)
        for _, packet in frames:
            self.brain.on_packet(now, packet)

    def radio_time(self, stamp: float) -> float:
        """Now (s), for frames in a batch stamped ``stamp``; notes how late it came."""
        now = self._now()
        if stamp > 0.0:
            self._radio_lag_max = max(self._radio_lag_max, now - stamp)
        return now

    def on_shape(self, msg: FormationShape) -> None:
        """A new desired shape (swarm_msgs/FormationShape)."""
        try:
            shape = shape_from_msg(msg)
        except ShapeError as exc:
            self.get_logger().error(f'ignoring shape version {msg.version}: {exc}')
            return
        self.brain.set_shape(shape, msg.version)
        if self.params['partition_locally'] and self.params['method'] != 'forces':
            self._partition_locally(shape, msg.version)

    def _partition_locally(self, shape, version: int) -> None:
        try:
            result = partition(shape, type_counts_from(self._type_counts),
                               self.brain.config.type_radii, self.params['method'],
                               seed=self.params['partition_seed'],
                               previous=self.brain.goals or None,
                               margin=self.params['formation_margin_m'])
        except (PartitionError, ShapeError, ValueError) as exc:
            self.get_logger().error(f'local partition of shape {version} failed: {exc}')
            return
        self.brain.set_goals(result.goals, version)

    def on_goals(self, msg: GoalArray) -> None:
        """Goal states from the mission (ignored when partitioning locally)."""
        if not self.params['partition_locally']:
            self.brain.set_goals(goals_from_msg(msg), msg.version)

    def _late_start(self, t: float) -> None:
        """First step at sim time ``t``: an agent (re)started mid-run (a respawn) widens
        its deployment prior to the distance the robot can have driven since t = 0, and
        its velocity prior to the robot's top speed (``Localizer.restarted``)."""
        clock = self.get_clock()
        if not (clock.clock_type == ClockType.ROS_TIME and clock.ros_time_is_active):
            return    # wall time (hardware): no run time to go by
        loc = self.brain.localizer
        if t > LATE_START_S and loc.config.max_speed * t > loc.worst_std:
            loc.restarted(t)
            self.get_logger().info(
                f'started at sim time {t:.1f} s: prior widened to {loc.worst_std:.1f} m and '
                f'{loc.config.max_speed:.1f} m/s (the robot may have driven since)')

    # -- outputs
    def on_control(self, now: Time | None = None) -> None:
        """One inner-loop step: brain, radio frames, cmd_force and cmd_vel; ``now`` is
        this node's clock's time (composed_node reads it once for all its agents)."""
        if now is None:
            now = self.get_clock().now()
        t = now.nanoseconds * 1e-9
        if not self._stepped:
            self._stepped = True
            self._late_start(t)
        # A parked agent with nothing due skips the step (AgentBrain.rest): its force
        # stays zero, no frame goes out and its setpoint is unchanged.
        out = None if self.brain.rest(t) else self.brain.step(t)
        if out is not None and out.packets:
            self._tx_sink([(t, packet) for packet in out.packets])
        if self._radio is not None:
            self._radio.flush_if_due(now)
        # An unchanged force (a parked robot: zero) is repeated at keepalive_hz only: the
        # simulator holds the last command and paces its clock to the stamps it gets.
        force = (0.0, 0.0) if out is None else (float(out.force[0]), float(out.force[1]))
        # (Half a microsecond of slack: sim times are sums of float steps, and a keepalive
        # due at exactly one period must not wait for the next, the world may be holding
        # its clock for it.)
        if force != self._last_force or t - self._last_force_t >= self._keepalive_s - 5e-7:
            self._last_force, self._last_force_t = force, t
            if self._command_sink is not None:
                self._command_sink(self.params['agent_id'], t, *force)
            else:
                wrench = WrenchStamped()
                wrench.header.stamp = now.to_msg()
                wrench.header.frame_id = 'map'
                wrench.wrench.force.x, wrench.wrench.force.y = force
                self._cmd_force.publish(wrench)
        if out is None:
            return
        # The setpoint changes at the outer-loop rate only, its body-frame form also when
        # the heading changes (hardware): publish it when it changes.
        twist = setpoint_to_twist(out.velocity_setpoint, self.heading)
        setpoint = (twist.linear.x, twist.linear.y)
        if setpoint != self._last_setpoint:
            self._last_setpoint = setpoint
            self._cmd_vel.publish(twist)

    def publish_state(self) -> None:
        """Publish ``state`` (estimate, mode, assignment), ``odom`` and the TF of the
        estimate, all of one snapshot and one stamp."""
        snap, stamp = self.brain.snapshot(), self.get_clock().now().to_msg()
        self._state.publish(snapshot_to_state(snap, stamp))
        self._odom.publish(snapshot_to_odometry(snap, stamp, self.heading))
        self._tf_sink(snapshot_to_transform(snap, stamp, self.heading))

    def publish_routes(self) -> None:
        """Publish ``routes`` (the DSDV table)."""
        self._routes.publish(routes_to_msg(self.brain.config.agent_id,
                                           self.brain.router.routes(),
                                           self.get_clock().now().to_msg()))

    def log_status(self) -> None:
        self.get_logger().info(f'{self.brain.status_line()}; radio lag max '
                               f'{self._radio_lag_max:.2f} s')
        self._radio_lag_max = 0.0

    def stop(self) -> None:
        """Command zero force and velocity (on shutdown)."""
        self._cmd_force.publish(WrenchStamped())
        self._cmd_vel.publish(Twist())


def make_executor(context=None):
    """The executor chosen by SWARM_EXECUTOR (``single``, default, or ``events``).

    benchmarks/bench_executor.py: 50 composed nodes at 50 Hz wall-clock timers cost 1.0
    core with the SingleThreadedExecutor and 0.44 core with the EventsExecutor, but in
    rclpy 7.1 the EventsExecutor's timers did not fire on /clock with use_sim_time
    (agents froze in scripts/launch_swarm.py), so sim-time swarms use SingleThreaded.
    """
    if os.environ.get('SWARM_EXECUTOR', 'single') == 'events':
        try:
            from rclpy.experimental import EventsExecutor
            return EventsExecutor(context=context)
        except ImportError:
            pass
    return SingleThreadedExecutor(context=context)


def main(args=None) -> None:
    """Run one agent node (``ros2 run swarm_agent agent_node``)."""
    run_node(AgentNode, 'agent_node', args, executor=make_executor, stop=AgentNode.stop)


if __name__ == '__main__':
    main(sys.argv)
