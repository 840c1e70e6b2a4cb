"""sim_node: the simulated world of the swarm (replaces the thesis's Gazebo, 4.1).

Owns the clock and steps the physics at ``physics_rate_hz``, paced to
``real_time_factor`` (0: as fast as possible) and never more than ``max_agent_lag_s``
of sim time ahead of the slowest living agent (the stamp of its last force command):
a closed loop whose controllers fall behind the plant is not the system under test.
It waits up to ``wait_for_agents_s`` (wall) for every robot's first command (and for
``truth_subscribers`` observers), and an agent silent for ``agent_stall_s`` (wall) is
no longer waited for. Running as fast as possible, it steps as soon as every agent has
answered the current time (through a guard condition, after the callbacks of its
wait), else at ``clock_rate_hz``; a hold of a wall second names the agent it waits for.

Robots come from the fleet file, obstacles from the shape spec
(``swarm_mission.shapes.load_shape``), physics from a backend: ``pybullet``
(``swarm_sim.world``, rough terrain, rigid bodies) when available, else the ``pointmass``
model shared with the headless evaluator.

Topics
  published  ``/clock`` (rosgraph_msgs/Clock)
             ``/agent_K/imu`` (sensor_msgs/Imu, map-frame acceleration with bias + noise)
             ``/agent_K/gps`` (geometry_msgs/PoseWithCovarianceStamped, beacons only)
             ``/agent_K/ranges`` (swarm_msgs/RangeArray, TOA ranges to beacon neighbours)
             ``/agent_K/proximity`` (swarm_msgs/ProximityArray, the neighbours within
             ``proximity_range_m``: offsets and coverage radii, ``proximity_rate_hz``)
             ``/agent_K/radio/rx`` (swarm_msgs/RadioPacketArray, what the medium
             delivered to the robot since the last batch, ``radio_rate_hz``)
             ``/swarm/sensor_batch`` (swarm_msgs/SensorBatch: with ``sensor_batch``,
             every robot's imu, ranges, proximity and radio deliveries of a step in one
             message, in place of the four per-robot topics above; for composed agents)
             ``/swarm/truth`` (swarm_msgs/SwarmTruth, for metrics only)
             ``/swarm/markers`` (visualization_msgs/MarkerArray for RViz, built by
             ``swarm_sim.markers``: robots by type and mode, goals, shape, obstacles,
             radio links; ``marker_rate_hz``, 0 turns it off)
  subscribed ``/agent_K/cmd_force`` (geometry_msgs/WrenchStamped, N, map frame)
             ``/swarm/cmd_batch`` (swarm_msgs/ForceBatch: with ``sensor_batch``, the
             commands of many agents in place of their cmd_force topics)
             ``/radio/tx`` (swarm_msgs/RadioPacketArray, batches from the agents)
             ``/swarm/kill`` (std_msgs/Int32MultiArray: robots to remove, a fault)
             ``/agent_K/state``, ``/swarm/goals``, ``/swarm/shape`` (for the markers
             only, and only while they are on)
             ``/swarm/radio_off``, ``/swarm/radio_on`` (std_msgs/Int32MultiArray: robots
             whose radio dies or comes back; the robot stays in the world)
             ``/swarm/move_obstacle`` (std_msgs/Float64MultiArray ``[k, dx, dy]``:
             translate obstacle k of the shape spec by (dx, dy) m, bodies and radio
             shadow alike; the agents are not told)

Faults: ``/swarm/kill`` removes robots, ``/swarm/radio_off`` silences radios,
``/swarm/move_obstacle`` moves an obstacle (unknown robots or obstacles, non-finite or
malformed commands are ignored with a log line naming them); three parameters change
the radio medium at run time (``swarm_sim.medium.RUNTIME_SETTINGS``; a bad value is
refused with the reason): ``loss`` (packet loss), ``radio_range_m`` (range cut) and
``radio_wall_speed_mps`` (> 0 starts a radio-opaque wall sweeping across the workspace
from x = -half_size at that speed, from the sim time it is set; it cuts links, not
bodies; 0 removes it).
Malformed force commands (NaN, huge) are rejected with one log line per robot.
"""

from __future__ import annotations

import json
import math
import pathlib
import sys
import time

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseWithCovarianceStamped, WrenchStamped
import numpy as np
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu
from shapely import affinity
from std_msgs.msg import Float64MultiArray, Int32MultiArray
from visualization_msgs.msg import MarkerArray

from swarm_agent.agent_node import lean_publisher, lean_subscription
from swarm_agent.conversions import (
    frames_or_log,
    frames_to_msg,
    proximity_to_msg,
    sensor_batch_to_msg,
    stamp_seconds,
)
from swarm_agent.packet import Packet
from swarm_mission import qos
from swarm_mission.conversions import goals_from_msg, shape_from_msg
from swarm_mission.robot_types import load_robot_types
from swarm_mission.shapes import load_shape, ShapeError
from swarm_msgs.msg import (
    AgentState,
    AgentTruth,
    ForceBatch,
    FormationShape,
    GoalArray,
    ProximityArray,
    RadioPacketArray,
    RangeArray,
    RangeMeasurement,
    SensorBatch,
    SwarmTruth,
)
from swarm_sim.fleet import FleetError, load_fleet, place_fleet, PLACEMENT_STD_M
from swarm_sim.markers import swarm_markers
from swarm_sim.medium import MediumConfig, RadioMedium, RUNTIME_SETTINGS, SweepingWall
from swarm_sim.metrics import SeparationTracker
from swarm_sim.sensors import GpsModel, ImuModel, ProximityModel

PARAMETERS = {
    'fleet_file': ('', 'Fleet YAML: robots with id, type, beacon, x, y, yaw'),
    'placement_std_m': (PLACEMENT_STD_M, 'Robots spawn this far (m per axis, Gaussian, '
                                         'seeded) from their fleet positions, the '
                                         "agents' deployment prior"),
    'shape': ('', 'Shape spec whose obstacles populate the world (built-in or file)'),
    'backend': ('auto', 'Physics: pybullet, pointmass, or auto (pybullet if available)'),
    'physics_rate_hz': (100.0, 'Physics steps per simulated second'),
    'real_time_factor': (1.0, 'Target sim/wall speed ratio; 0 runs as fast as possible'),
    'clock_rate_hz': (50.0, 'Wall-clock rate of /clock updates and stepping batches'),
    'imu_rate_hz': (10.0, 'IMU samples per simulated second'),
    'gps_rate_hz': (1.0, 'Beacon GPS fixes per simulated second'),
    'gps_std': (2.0, 'GPS noise per axis (m), thesis 4.2'),
    'range_rate_hz': (1.0, 'TOA ranging rate per simulated second'),
    'radio_rate_hz': (20.0, 'Radio delivery batches per simulated second, per robot'),
    'proximity_rate_hz': (10.0, 'Proximity scans per simulated second; 0: no sensor'),
    'proximity_range_m': (3.0, 'Proximity sensor range (m): neighbours within it are seen'),
    'proximity_std': (0.02, 'Proximity offset noise per axis (m)'),
    'sensor_batch': (False, 'Publish imu, ranges, proximity and radio deliveries of every '
                            'robot in one /swarm/sensor_batch per step and take force '
                            'commands from /swarm/cmd_batch (composed agents) instead of '
                            'the per-robot topics'),
    'truth_rate_hz': (2.0, 'Ground-truth publication rate (sim time)'),
    'marker_rate_hz': (1.0, 'RViz marker rate on /swarm/markers (sim time); 0: none'),
    'command_timeout_s': (0.5, 'Force commands older than this are dropped to zero'),
    'max_agent_lag_s': (0.2, 'Sim time the world may run ahead of the slowest agent; 0: off'),
    'truth_subscribers': (0, 'Hold the clock at 0 until this many /swarm/truth subscribers '
                             "(e.g. the launcher's monitor) have matched, for at most "
                             'wait_for_agents_s'),
    'wait_for_agents_s': (60.0, "Wall seconds to wait for every robot's first command"),
    'agent_stall_s': (10.0, 'Wall seconds after which a silent agent is not waited for'),
    'max_force': (50.0, 'Force commands are clamped to this magnitude (N)'),
    'loss': (0.0, 'Radio packet loss probability (settable at run time)'),
    'radio_range_m': (25.0, 'Radio range in metres, thesis 4.1 (settable at run time)'),
    'radio_wall_speed_mps': (0.0, 'Speed of a radio-opaque wall sweeping the workspace '
                                  'along +x from when set; 0: none (settable at run time)'),
    'half_size': (50.0, 'Workspace half width (m)'),
    'terrain': ('rough', 'pybullet terrain: rough or flat'),
    'seed': (0, 'Seed of the noise generators and the terrain'),
    'record_dir': ('', 'Folder for the run record (truth.csv, medium.json, separation.json); '
                       'empty: none'),
    'gui': (False, 'pybullet GUI (needs a display)'),
}


# Wall seconds between repeats of an unchanged /clock while the world waits for agents.
HELD_CLOCK_PERIOD_S = 0.25
# Running as fast as possible, /clock advances by at most this many physics steps at a
# time (0.1 s at 100 Hz): the agents' timers fire once per clock advance (rcl skips
# missed periods), so this is the longest the agents' inner loop holds one force.
STEPS_PER_TICK = 10


class PointMassBackend:
    """The headless point-mass model behind the Backend interface."""

    name = 'pointmass'

    def __init__(self, fleet, types, **_) -> None:
        from swarm_agent.dynamics import PointMassSwarm
        self.model = PointMassSwarm([types[r.type] for r in fleet],
                                    [[r.x, r.y] for r in fleet])

    def step(self, dt: float, forces: np.ndarray) -> None:
        self.model.step(dt, forces)

    def positions(self) -> np.ndarray:
        return self.model.positions

    def velocities(self) -> np.ndarray:
        return self.model.velocities

    def accelerations(self) -> np.ndarray:
        return self.model.accelerations()

    def yaws(self) -> np.ndarray:
        return np.zeros(len(self.model.positions))

    def close(self) -> None:
        pass


def _check_proximity_parameters(p: dict) -> None:
    """ValueError naming the proximity parameter that is out of range, and the fix."""
    for name, ok, wanted, example in (
            ('proximity_rate_hz', p['proximity_rate_hz'] >= 0, '>= 0 Hz (0: no sensor)', 10.0),
            ('proximity_range_m', p['proximity_range_m'] > 0, 'above 0 m', 3.0),
            ('proximity_std', p['proximity_std'] >= 0, '>= 0 m', 0.02)):
        if not (math.isfinite(p[name]) and ok):
            raise ValueError(f'parameter {name} must be a finite number {wanted}, got '
                             f'{p[name]}: set it in config/sim.yaml or with --ros-args '
                             f'-p {name}:={example}')


def make_backend(name: str, fleet, types, obstacles, half_size, terrain, seed, gui,
                 physics_hz: float = 100.0):
    """The physics backend by name ('auto' prefers pybullet's swarm_sim.world)."""
    if name in ('pybullet', 'auto'):
        try:
            from swarm_sim.world import PybulletBackend
        except ImportError:
            if name == 'pybullet':
                raise
        else:
            return PybulletBackend(fleet, types, obstacles=obstacles, half_size=half_size,
                                   terrain=terrain, seed=seed, gui=gui,
                                   physics_hz=physics_hz)
    return PointMassBackend(fleet, types)


class SimNode(Node):
    """The world; see the module docstring."""

    def __init__(self, **kwargs) -> None:
        super().__init__('sim', **kwargs)
        for name, (default, text) in PARAMETERS.items():
            self.declare_parameter(name, default, ParameterDescriptor(description=text))
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        _check_proximity_parameters(p)
        self.params = p
        self.fleet = load_fleet(p['fleet_file'])
        self.ids = [r.id for r in self.fleet]
        self.index = {r.id: i for i, r in enumerate(self.fleet)}
        self.n = len(self.fleet)
        self.is_beacon = np.array([r.is_beacon for r in self.fleet])
        types = load_robot_types()
        self.types = types
        obstacles = list(load_shape(p['shape']).obstacles) if p['shape'] else []
        self.obstacles = obstacles
        # Where the robots really stand: near the fleet file's positions, which are all
        # the agents know (swarm_sim.fleet.place_fleet, the same draw as headless).
        self.fleet = place_fleet(self.fleet, p['placement_std_m'], p['seed'],
                                 radii=[types[r.type].coverage_radius for r in self.fleet],
                                 obstacles=obstacles, half_size=p['half_size'])
        self.rng = np.random.default_rng(p['seed'])
        self.backend = make_backend(p['backend'], self.fleet, types, obstacles,
                                    p['half_size'], p['terrain'], p['seed'], p['gui'],
                                    p['physics_rate_hz'])
        self.medium = RadioMedium(MediumConfig(loss=p['loss'], range_m=p['radio_range_m']),
                                  self.rng, obstacles)
        if p['radio_wall_speed_mps'] > 0:
            self._start_wall(p['radio_wall_speed_mps'], 0.0)
        self.imu = ImuModel(self.n, self.rng)
        self.gps = GpsModel(self.rng, std=p['gps_std'])
        self.radii = np.array([types[r.type].coverage_radius for r in self.fleet])
        self.proximity = (ProximityModel(self.rng, range_m=p['proximity_range_m'],
                                         noise_std=p['proximity_std'])
                          if p['proximity_rate_hz'] > 0 else None)
        self.alive = np.ones(self.n, dtype=bool)
        self.forces = np.zeros((self.n, 2))
        self.force_time = np.full(self.n, -math.inf)
        self.force_stamp = np.full(self.n, -math.inf)   # agent clock of its last command
        self.force_wall = np.full(self.n, -math.inf)    # wall time it arrived
        self._started_wall = time.monotonic()
        self._clock_wall = -math.inf  # wall time of the last /clock message
        self._warned: set[int] = set()
        self.dt = 1.0 / p['physics_rate_hz']
        self.step_count = 0
        self.t = 0.0
        self._due = {k: 0.0 for k in ('imu', 'gps', 'range', 'proximity', 'radio', 'truth',
                                      'marker')}
        self._rx_batches: dict[int, list[tuple[float, Packet]]] = {}
        self._rx_grouped: list[tuple[float, Packet, list[int]]] = []
        # Closest approach of coverage circles at every physics step, and its minimum per
        # truth interval (written to record_dir/separation.json on close).
        self.separation = SeparationTracker()
        self._separation_series: tuple[list[float], list[float]] = ([], [])
        self._record = None
        if p['record_dir']:
            path = pathlib.Path(p['record_dir'])
            path.mkdir(parents=True, exist_ok=True)
            self._record = open(path / 'truth.csv', 'w', encoding='utf-8')  # noqa: SIM115
            self._record.write('t,id,x,y,vx,vy,alive\n')

        sensor, radio, state, imu, command = (
            QoSProfile(**q) for q in (qos.SENSOR, qos.RADIO, qos.STATE, qos.IMU, qos.COMMAND))
        self.clock_pub = self.create_publisher(Clock, '/clock', 10)
        self.truth_pub = self.create_publisher(SwarmTruth, '/swarm/truth', state)
        self.marker_pub = self.create_publisher(MarkerArray, '/swarm/markers', state)
        # What the markers show beyond the world: modes, goals and the shape, heard only
        # when markers are on (a state subscription per robot costs callbacks).
        self._modes: dict[int, int] = {}
        self._goals: list = []
        self._shape = None
        if p['marker_rate_hz'] > 0:
            latched = QoSProfile(**qos.LATCHED)
            self.create_subscription(GoalArray, '/swarm/goals', self._on_goals, latched)
            self.create_subscription(FormationShape, '/swarm/shape', self._on_shape, latched)
            for r in self.fleet:
                lean_subscription(self, AgentState, f'/agent_{r.id}/state',
                                  lambda m: self._modes.__setitem__(m.id, m.mode), state)
        self.imu_pubs, self.gps_pubs, self.range_pubs, self.rx_pubs = {}, {}, {}, {}
        self.proximity_pubs = {}
        # Per-robot topics without default QoS event handlers (agent_node.lean_publisher):
        # with them, 50 robots made a wait set of about 750 entities.
        # With sensor_batch, imu, ranges, proximity and radio/rx of every robot travel in
        # one /swarm/sensor_batch message per step instead (composed agents).
        self.batch_pub = (self.create_publisher(SensorBatch, '/swarm/sensor_batch', radio)
                          if p['sensor_batch'] else None)
        for r in self.fleet:
            ns = f'/agent_{r.id}'
            if self.batch_pub is None:
                self.imu_pubs[r.id] = lean_publisher(self, Imu, f'{ns}/imu', imu)
                self.range_pubs[r.id] = lean_publisher(self, RangeArray, f'{ns}/ranges',
                                                       sensor)
                if self.proximity is not None:
                    self.proximity_pubs[r.id] = lean_publisher(
                        self, ProximityArray, f'{ns}/proximity', sensor)
                self.rx_pubs[r.id] = lean_publisher(self, RadioPacketArray,
                                                    f'{ns}/radio/rx', radio)
            if r.is_beacon:
                self.gps_pubs[r.id] = lean_publisher(self, PoseWithCovarianceStamped,
                                                     f'{ns}/gps', sensor)
            if not p['sensor_batch']:
                lean_subscription(self, WrenchStamped, f'{ns}/cmd_force',
                                  lambda m, i=self.index[r.id]: self._on_force(i, m),
                                  command)
        if p['sensor_batch']:
            # Composed agents answer in kind: every command of a step in one ForceBatch.
            self.create_subscription(ForceBatch, '/swarm/cmd_batch', self._on_force_batch,
                                     QoSProfile(**qos.COMMAND_BATCH))
        self._tx_sub = self.create_subscription(RadioPacketArray, '/radio/tx', self._on_tx,
                                                radio)
        self.create_subscription(Int32MultiArray, '/swarm/kill', self._on_kill, 10)
        self.create_subscription(Int32MultiArray, '/swarm/radio_off',
                                 lambda m: self._on_radio(m, False), 10)
        self.create_subscription(Int32MultiArray, '/swarm/radio_on',
                                 lambda m: self._on_radio(m, True), 10)
        self.create_subscription(Float64MultiArray, '/swarm/move_obstacle',
                                 self._on_move_obstacle, 10)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.medium.update_positions(self.ids, self.backend.positions())
        self._imu_v = self.backend.velocities().copy()
        self._imu_t = 0.0
        self._wall0 = time.monotonic()
        self._sim0 = 0.0
        self._rtf = float(p['real_time_factor'])   # kept current by _on_set_parameters
        self._step_now = self.create_guard_condition(self._on_tick)
        self._observed = p['truth_subscribers'] <= 0
        self.create_timer(1.0 / p['clock_rate_hz'], self._on_tick)
        self.get_logger().info(
            f'{self.n} robots ({int(self.is_beacon.sum())} beacons), '
            f'{len(obstacles)} obstacles, backend {self.backend.name}, '
            f'{p["physics_rate_hz"]:.0f} Hz physics, real-time factor '
            f'{p["real_time_factor"] or "max"}')

    # -- inputs
    def _on_force(self, i: int, msg: WrenchStamped) -> None:
        self._command(i, msg.wrench.force.x, msg.wrench.force.y,
                      stamp_seconds(msg.header.stamp))
        self._step_when_answered()

    def _on_force_batch(self, msg: ForceBatch) -> None:
        n = len(msg.ids)
        if not len(msg.fx) == len(msg.fy) == len(msg.stamps) == n:
            self.get_logger().error(
                f'/swarm/cmd_batch: {n} ids but {len(msg.fx)} fx, {len(msg.fy)} fy and '
                f'{len(msg.stamps)} stamps; dropped', throttle_duration_sec=10.0)
            return
        for agent, fx, fy, stamp in zip(msg.ids, msg.fx, msg.fy, msg.stamps):
            i = self.index.get(int(agent))
            if i is None or not math.isfinite(stamp):
                self.get_logger().error(
                    f'/swarm/cmd_batch: a command for robot {agent} stamped {stamp} '
                    '(unknown robot or no valid stamp); ignored', throttle_duration_sec=10.0)
                continue
            self._command(i, fx, fy, stamp)
        self._step_when_answered()

    def _command(self, i: int, fx: float, fy: float, stamp: float) -> None:
        """Robot ``i``'s force command (N, map frame), stamped on its agent's clock."""
        f = np.array([fx, fy], dtype=float)
        if not np.all(np.isfinite(f)):
            if i not in self._warned:
                self._warned.add(i)
                self.get_logger().warning(
                    f'robot {self.ids[i]}: rejected a non-finite force command {f.tolist()}; '
                    'holding the last valid one')
            return
        norm = float(np.hypot(*f))
        if norm > self.params['max_force']:
            if i not in self._warned:
                self._warned.add(i)
                self.get_logger().warning(
                    f'robot {self.ids[i]}: force {norm:.1f} N clamped to '
                    f'{self.params["max_force"]} N')
            f *= self.params['max_force'] / norm
        self.forces[i] = f
        self.force_time[i] = self.t
        self.force_stamp[i] = stamp
        self.force_wall[i] = time.monotonic()

    def _step_when_answered(self) -> None:
        # As fast as possible and paced by the agents: step as soon as the last of them
        # has answered the current time, not at the next clock_rate_hz tick (on 2 cores
        # the ticks, not the agents, would hold 12 agents at 5x real time). Through a
        # guard condition, so the step runs after the callbacks of this wait: a radio
        # batch sent with the commands must be on the air before the step delivers
        # (stepping from this callback delivers it a tick late, once per hop of a flood,
        # and 50 agents' consensus rounds agree 0.90 instead of 0.99). Only once every
        # agent has caught up: stepping whenever max_agent_lag_s allows is no faster.
        lag = self.params['max_agent_lag_s']
        if (self._rtf <= 0.0 and lag > 0
                and self._steps_agents_allow() >= int(lag / self.dt + 1e-9)):
            self._step_now.trigger()

    def _on_tx(self, msg: RadioPacketArray) -> None:
        """Every agent's radio batches: this one and all that wait behind it.

        rclpy's executor takes one message per subscription per wait, and one process per
        agent means one /radio/tx batch per agent every 1/radio_tx_hz: 50 agents sent
        1000 a simulated second, which queued here (reliable, depth 1000) until frames
        went on the air up to 1.4 s late and cost rows missed their consensus round
        (round agreement 0.19). So the callback drains the queue, as the executor would
        take each message (``take_message`` on the subscription's handle), up to a few
        batches per robot so that a flood of batches cannot hold the world's step.
        """
        self._transmit(msg)
        sub = self._tx_sub
        for _ in range(4 * self.n):
            with sub.handle:
                taken = sub.handle.take_message(sub.msg_type, sub.raw)
            if taken is None:
                return
            self._transmit(taken[0])

    def _transmit(self, msg: RadioPacketArray) -> None:
        # A frame goes on the air when its agent sent it (its stamp, on the agent's sim
        # clock), not when its batch reached the world: the world may be up to
        # max_agent_lag_s ahead, and that wait is not radio latency.
        for stamp, packet in frames_or_log(msg, self.get_logger(), '/radio/tx'):
            if packet.source in self.index:
                sent = stamp if 0.0 < stamp < self.t else self.t
                self.medium.transmit(sent, packet)

    def _known_robots(self, msg: Int32MultiArray, topic: str) -> list[int]:
        """Fleet indices of the living robots a fault names; the others logged."""
        unknown = [int(a) for a in msg.data if int(a) not in self.index]
        if unknown:
            self.get_logger().warning(f'{topic}: no robot {unknown} in the fleet (ids '
                                      f'{min(self.ids)}..{max(self.ids)}); ignored')
        return [self.index[int(a)] for a in msg.data
                if int(a) in self.index and self.alive[self.index[int(a)]]]

    def _on_radio(self, msg: Int32MultiArray, on: bool) -> None:
        topic = '/swarm/radio_on' if on else '/swarm/radio_off'
        for i in self._known_robots(msg, topic):
            (self.medium.enable_radio if on else self.medium.disable_radio)(self.ids[i])
            self.get_logger().warning(f't={self.t:.1f} s: robot {self.ids[i]} radio '
                                      f'{"back on" if on else "off"} (fault injection)')

    def _on_move_obstacle(self, msg: Float64MultiArray) -> None:
        data = list(msg.data)
        if (len(data) != 3 or not all(math.isfinite(v) for v in data)
                or data[0] != int(data[0])):
            self.get_logger().warning(
                f'/swarm/move_obstacle: expected [index, dx, dy] with an integer index and '
                f'finite metres, got {data}; ignored')
            return
        k, dx, dy = int(data[0]), data[1], data[2]
        if not 0 <= k < len(self.obstacles):
            self.get_logger().warning(
                f'/swarm/move_obstacle: no obstacle {k} (the shape spec has '
                f'{len(self.obstacles)}, indices from 0); ignored')
            return
        if hasattr(self.backend, 'move_obstacle'):
            self.backend.move_obstacle(k, dx, dy)  # bodies; the point-mass model has none
        self.obstacles[k] = affinity.translate(self.obstacles[k], dx, dy)
        self.medium.set_obstacles(self.obstacles)
        self.get_logger().warning(f't={self.t:.1f} s: obstacle {k} moved by ({dx:g}, '
                                  f'{dy:g}) m (fault injection)')

    def _on_kill(self, msg: Int32MultiArray) -> None:
        for i in self._known_robots(msg, '/swarm/kill'):
            agent = self.ids[i]
            if self.alive[i]:
                self.alive[i] = False
                self.medium.remove(int(agent))
                if hasattr(self.backend, 'remove'):
                    self.backend.remove(i)  # the body leaves the world, not just the radio
                self.get_logger().warning(f'robot {agent} removed (fault injection)')

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        for param in params:
            if param.name in RUNTIME_SETTINGS:
                try:
                    RUNTIME_SETTINGS[param.name](param.value)
                except (TypeError, ValueError) as exc:
                    return SetParametersResult(successful=False, reason=f'{param.name}: {exc}')
        for param in params:
            if param.name == 'loss':
                self.medium.set_loss(float(param.value))
                self.get_logger().info(f't={self.t:.1f} s: packet loss set to {param.value}')
            elif param.name == 'radio_range_m':
                self.medium.set_range(float(param.value))
                self.get_logger().info(f't={self.t:.1f} s: radio range set to {param.value} m')
            elif param.name == 'radio_wall_speed_mps':
                self._start_wall(float(param.value), self.t)
            elif param.name == 'real_time_factor':
                self._wall0, self._sim0 = time.monotonic(), self.t
                self._rtf = float(param.value)
        return SetParametersResult(successful=True)

    def _start_wall(self, speed: float, t: float) -> None:
        wall = SweepingWall(t, speed, float(self.params['half_size'])) if speed > 0 else None
        self.medium.start_wall(wall)
        self.get_logger().info(f't={t:.1f} s: ' + (
            f'radio wall sweeping from x = {-wall.half_length:g} m at {speed} m/s'
            if wall else 'radio wall removed'))

    # -- stepping
    def _on_tick(self) -> None:
        rtf = self._rtf
        if rtf > 0:
            target = self._sim0 + (time.monotonic() - self._wall0) * rtf
            steps = int((target - self.t) / self.dt)
            steps = max(0, min(steps, 50))
        else:
            steps = STEPS_PER_TICK
        steps = min(steps, self._steps_agents_allow())
        for _ in range(steps):
            self._physics_step()
        if steps:
            self._publish_outputs()
        elif time.monotonic() - self._clock_wall >= HELD_CLOCK_PERIOD_S:
            # Held for a slow agent: repeat the unchanged time now and then, so that
            # late-starting nodes learn it and fire their timers. Not at every tick:
            # each /clock message wakes every agent process (50 of them per tick).
            self._publish_clock(self._stamp())
            self._log_hold()

    def _log_hold(self) -> None:
        """Name the agent the world waits for, when it has waited a wall second."""
        waited = self.alive & np.isfinite(self.force_stamp)
        if not waited.any() or time.monotonic() - self._started_wall < 5.0:
            return
        i = int(np.flatnonzero(waited)[np.argmin(self.force_stamp[waited])])
        held = time.monotonic() - self.force_wall[i]
        if held >= 1.0:
            self.get_logger().warning(
                f't={self.t:.2f} s: held by robot {self.ids[i]}: its last command is stamped '
                f'{self.force_stamp[i]:.2f} s and came {held:.1f} s (wall) ago',
                throttle_duration_sec=5.0)

    def _steps_agents_allow(self) -> int:
        """Physics steps possible without running ahead of the slowest living agent."""
        if not self._observed:
            # Start-up: hold t = 0 until the run's observers (truth_subscribers, the
            # launcher's monitor) are matched, or the start-up window is over; a swarm
            # running at 20x real time otherwise did its first minute unrecorded.
            self._observed = (self.truth_pub.get_subscription_count()
                              >= self.params['truth_subscribers']
                              or time.monotonic() - self._started_wall
                              >= self.params['wait_for_agents_s'])
            if not self._observed:
                return 0
        lag = float(self.params['max_agent_lag_s'])
        if lag <= 0.0:
            return 1 << 30
        wall = time.monotonic()
        # Robots not heard yet count as standing at t = 0 while the start-up window
        # lasts: the world waits at ``lag`` for their controllers to come up.
        silent = ~np.isfinite(self.force_stamp)
        starting = silent & (wall - self._started_wall < self.params['wait_for_agents_s'])
        waited = self.alive & (starting | (wall - self.force_wall < self.params['agent_stall_s']))
        if not waited.any():
            return 1 << 30
        slowest = float(np.where(silent, 0.0, self.force_stamp)[waited].min())
        return max(0, int((slowest + lag - self.t) / self.dt + 1e-9))

    def _physics_step(self) -> None:
        stale = self.t - self.force_time > self.params['command_timeout_s']
        forces = np.where((stale | ~self.alive)[:, None], 0.0, self.forces)
        self.backend.step(self.dt, forces)
        self.step_count += 1
        self.t = self.step_count * self.dt
        self.separation.update(self.backend.positions(), self.radii, self.alive)
        if hasattr(self.backend, 'count_body_contacts'):
            self.backend.count_body_contacts(self.separation.overlapping_pairs())
        if self.step_count % max(1, int(round(0.05 / self.dt))) == 0:
            living = np.flatnonzero(self.alive)
            self.medium.move_wall(self.t)
            self.medium.update_positions([self.ids[i] for i in living],
                                         self.backend.positions()[living])

    def _stamp(self):
        sec = int(self.t)
        return Time(sec=sec, nanosec=int(round((self.t - sec) * 1e9)) % 1_000_000_000)

    def _due_now(self, key: str, rate_param: str) -> bool:
        if self.t + 1e-9 >= self._due[key]:
            self._due[key] = self.t + 1.0 / self.params[rate_param]
            return True
        return False

    def _publish_clock(self, stamp) -> None:
        self.clock_pub.publish(Clock(clock=stamp))
        self._clock_wall = time.monotonic()

    def _publish_outputs(self) -> None:
        stamp = self._stamp()
        self._publish_clock(stamp)
        batch = {} if self.batch_pub is not None else None   # sensor_batch contents
        if batch is not None:
            # Kept grouped by frame, as the medium delivers them (one entry per frame).
            self._rx_grouped.extend((self.t, packet, receivers)
                                    for packet, receivers in self.medium.deliver_grouped(self.t))
        else:
            for receiver, packet in self.medium.deliver(self.t):
                self._rx_batches.setdefault(receiver, []).append((self.t, packet))
        if self._due_now('radio', 'radio_rate_hz'):
            if batch is not None:
                batch['rx'], self._rx_grouped = self._rx_grouped, []
            else:
                for receiver, frames in self._rx_batches.items():
                    self.rx_pubs[receiver].publish(frames_to_msg(frames, stamp))
            self._rx_batches = {}
        pos = self.backend.positions()
        if self._due_now('imu', 'imu_rate_hz'):
            # A real IMU reports the mean acceleration over its sample interval (it
            # integrates internally); sampling one physics step would alias the
            # control-rate force changes into the agents' velocity estimates.
            vel = self.backend.velocities()
            interval = max(self.t - self._imu_t, self.dt)
            mean_accel = (vel - self._imu_v) / interval
            self._imu_v, self._imu_t = vel.copy(), self.t
            accel = self.imu.measure(mean_accel)
            living = np.flatnonzero(self.alive)
            if batch is not None:
                batch.update(imu_ids=[self.ids[i] for i in living], imu_accel=accel[living],
                             imu_noise_std=self.imu.noise_std)
            else:
                for i in living:
                    msg = Imu()
                    msg.header.stamp = stamp
                    msg.header.frame_id = 'map'
                    msg.linear_acceleration.x = float(accel[i, 0])
                    msg.linear_acceleration.y = float(accel[i, 1])
                    msg.linear_acceleration_covariance[0] = self.imu.noise_std ** 2
                    msg.linear_acceleration_covariance[4] = self.imu.noise_std ** 2
                    self.imu_pubs[self.ids[i]].publish(msg)
        if self._due_now('gps', 'gps_rate_hz'):
            for i in np.flatnonzero(self.alive & self.is_beacon):
                fix, std = self.gps.measure(pos[i])
                msg = PoseWithCovarianceStamped()
                msg.header.stamp = stamp
                msg.header.frame_id = 'map'
                msg.pose.pose.position.x, msg.pose.pose.position.y = float(fix[0]), float(fix[1])
                msg.pose.covariance[0] = msg.pose.covariance[7] = std ** 2
                self.gps_pubs[self.ids[i]].publish(msg)
        if self._due_now('range', 'range_rate_hz'):
            beacons = [self.ids[i] for i in np.flatnonzero(self.alive & self.is_beacon)]
            ranges = []
            for i in np.flatnonzero(self.alive):   # beacons range the other beacons
                msg = RangeArray()
                msg.header.stamp = stamp
                msg.receiver = self.ids[i]
                msg.ranges = [RangeMeasurement(beacon_id=b, range=r, stddev=s)
                              for b, r, s in self.medium.toa_ranges(self.ids[i], beacons)]
                ranges.append(msg)
            if batch is not None:
                batch['ranges'] = ranges
            else:
                for msg in ranges:
                    self.range_pubs[msg.receiver].publish(msg)
        if self.proximity is not None and self._due_now('proximity', 'proximity_rate_hz'):
            # Every living robot gets its scan, an empty one too: nobody within range.
            scan = self.proximity.measure(pos, self.radii, self.alive)
            living = np.flatnonzero(self.alive)
            if batch is not None:
                batch.update(prox_ids=[self.ids[i] for i in living],
                             prox_counts=np.bincount(scan.observers, minlength=self.n)[living],
                             prox_offsets=scan.offsets, prox_radii=scan.radii,
                             prox_stddev=self.proximity.noise_std)
            else:
                for i in living:
                    self.proximity_pubs[self.ids[i]].publish(proximity_to_msg(
                        stamp, self.ids[i], *scan.of(i), self.proximity.noise_std))
        if batch:
            self.batch_pub.publish(sensor_batch_to_msg(stamp, **batch))
        if self._due_now('truth', 'truth_rate_hz'):
            self._publish_truth(stamp, pos)
            self._separation_series[0].append(self.t)
            self._separation_series[1].append(self.separation.take_interval_min())
        if self.params['marker_rate_hz'] > 0 and self._due_now('marker', 'marker_rate_hz'):
            self._publish_markers(stamp, pos)

    def _publish_truth(self, stamp, pos) -> None:
        vel = self.backend.velocities()
        yaw = self.backend.yaws()
        msg = SwarmTruth()
        msg.header.stamp = stamp
        msg.header.frame_id = 'map'
        for i, r in enumerate(self.fleet):
            msg.agents.append(AgentTruth(
                id=r.id, type=r.type, is_beacon=r.is_beacon, alive=bool(self.alive[i]),
                position=[float(pos[i, 0]), float(pos[i, 1])],
                velocity=[float(vel[i, 0]), float(vel[i, 1])], yaw=float(yaw[i])))
            if self._record is not None:
                self._record.write(f'{self.t:.3f},{r.id},{pos[i, 0]:.4f},{pos[i, 1]:.4f},'
                                   f'{vel[i, 0]:.4f},{vel[i, 1]:.4f},{int(self.alive[i])}\n')
        self.truth_pub.publish(msg)

    def _publish_markers(self, stamp, pos) -> None:
        self.marker_pub.publish(swarm_markers(
            stamp, self.ids, [r.type for r in self.fleet],
            [self.types[r.type].coverage_radius for r in self.fleet], pos, self.alive,
            modes=self._modes, goals=self._goals,
            region=self._shape.region if self._shape is not None else None,
            obstacles=self.obstacles, links=self._links_in_fleet_order()))

    def _links_in_fleet_order(self) -> np.ndarray:
        """The medium's adjacency, which covers the living robots only, by fleet index."""
        ids, links = self.medium.adjacency()
        at = [self.index[a] for a in ids]
        full = np.zeros((self.n, self.n), dtype=bool)
        full[np.ix_(at, at)] = links
        return full

    def _on_goals(self, msg: GoalArray) -> None:
        self._goals = goals_from_msg(msg)

    def _on_shape(self, msg: FormationShape) -> None:
        try:
            self._shape = shape_from_msg(msg)
        except ValueError as exc:
            self.get_logger().warning(f'/swarm/shape: {exc}; markers keep the last shape')

    def close(self) -> None:
        """Flush the run record and release the physics."""
        if self._record is not None:
            self._record.close()
            out = pathlib.Path(self.params['record_dir']) / 'medium.json'
            out.write_text(json.dumps(vars(self.medium.stats), indent=2), encoding='utf-8')
            # Body contacts: pybullet's robot-robot contact pairs (None: point masses).
            times, mins = self._separation_series
            (out.parent / 'separation.json').write_text(json.dumps(
                {**self.separation.result(),
                 'body_contacts': getattr(self.backend, 'body_contacts', None),
                 'series': {'times': times, 'min': mins}}), encoding='utf-8')
            self._record = None
        self.backend.close()


def main(args=None) -> None:
    """Run the simulator (``ros2 run swarm_sim sim_node``)."""
    rclpy.init(args=args)
    try:
        node = SimNode()
    except (FleetError, ShapeError, ValueError) as exc:
        print(f'sim_node: {exc}', file=sys.stderr)
        rclpy.try_shutdown()
        sys.exit(2)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.close()
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main(sys.argv)
