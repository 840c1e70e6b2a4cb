"""Headless evaluation: N agent brains, the radio medium and point-mass dynamics in one process.

This is the Monte Carlo workhorse of thesis chapter 4. It runs exactly the code of the
ROS system (``AgentBrain`` built by ``make_brain``, ``RadioMedium``, ``Mission`` with the
same partitioners, the same sensor noise models) but replaces pybullet and DDS with a
vectorised point-mass model (``swarm_agent.dynamics``) and direct calls, so a 50-agent
trial takes seconds.

One control step (``control_dt``, 50 Hz by default) does, in order: every living brain
steps (inner LQR loop; outer loop at 2 Hz; localization every 3 s) and hands its packets
to the medium; the dynamics integrate the forces; the medium delivers due packets; the
IMU, range, GPS and proximity models feed the brains; the settled condition (eq. 4.1)
and the closest approach of the robots' coverage circles are checked
(``swarm_sim.metrics.SettleTracker``, ``SeparationTracker``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
import time as wallclock

import numpy as np

from swarm_agent.agent_factory import make_brain
from swarm_agent.brain import AgentBrain
from swarm_agent.dynamics import PointMassSwarm
from swarm_agent.mission_radio import MeshListener
from swarm_mission.mission import Mission, MissionConfig, SequenceStep
from swarm_mission.robot_types import load_robot_types
from swarm_mission.shapes import Shape
from swarm_sim.fleet import place_fleet, PLACEMENT_STD_M, random_fleet, RobotSpec
from swarm_sim.medium import MediumConfig, RadioMedium
from swarm_sim.metrics import (
    SeparationTracker,
    SETTLE_HOLD_S,
    settled_now,
    SettleTracker,
    trial_metrics,
)
from swarm_sim.mission_mesh import MediumWithMission
from swarm_sim.sensors import GpsModel, ImuModel, ProximityModel

METHODS = ('bubble', 'fractal', 'forces')
MISSION_RADIO_STREAM = 0x4D52   # seeds the mission radio's losses apart from the rest


class ScenarioError(ValueError):
    """A scenario that cannot run (unknown method, too many beacons, ...)."""


@dataclass
class Scenario:
    """One trial's setup. Defaults: the thesis scenario of chapter 4."""

    shape: Shape
    method: str = 'bubble'
    type_counts: dict[int, int] = field(default_factory=lambda: {1: 20, 2: 20, 3: 10})
    n_beacons: int = 8
    seed: int = 0
    duration_s: float = 600.0
    control_dt: float = 0.02              # inner loop period (50 Hz)
    medium_update_s: float = 0.1          # how often links are recomputed
    imu_period_s: float = 0.1             # IMU sample period (mean acceleration over it):
    #                                       sim_node's imu_rate_hz (10 Hz)
    range_period_s: float = 1.0           # TOA ranging rate
    gps_period_s: float = 1.0             # beacon GPS rate
    proximity_period_s: float = 0.1       # proximity sensor rate (10 Hz); 0: no sensor
    record_period_s: float = 0.5          # truth recording rate (2 Hz)
    settle_hold_s: float = SETTLE_HOLD_S  # run on this long after settling (eq. 4.1 hold)
    min_duration_s: float = 0.0           # never stop settled before this time (observation)
    localization_period_s: float = 3.0
    sequence: Sequence[SequenceStep] = ()  # further shapes at given times (4.3.4)
    removals: Sequence[tuple[float, Sequence[int]]] = ()  # (time, agent ids) to remove
    # Fault hooks: (time, fn) calls fn(swarm, t) once at that time, e.g. to change the
    # radio range or the medium's obstacles mid-run (scripts/fault_study.py).
    events: Sequence[tuple[float, Callable[[HeadlessSwarm, float], None]]] = ()
    medium: MediumConfig = field(default_factory=MediumConfig)
    fleet: Sequence[RobotSpec] | None = None
    half_size: float = 50.0
    partition_seed: int | None = None
    # Robots stand this far (m per axis, Gaussian) from their fleet positions; the brains
    # start from the fleet positions with this uncertainty (swarm_sim.fleet.place_fleet).
    placement_std_m: float = PLACEMENT_STD_M
    # Where the mission computer's radio stands (m); None: the first shape's centroid.
    mission_position: tuple[float, float] | None = None
    remesh: str = 'incremental'           # bubble packing on a changed shape (MissionConfig)

    def validate(self) -> None:
        """Raise ScenarioError with a one-line reason for an impossible setup."""
        n = sum(self.type_counts.values())
        if self.method not in METHODS:
            raise ScenarioError(f'unknown method {self.method!r}; use one of {METHODS}')
        if n <= 0:
            raise ScenarioError('the swarm needs at least one agent')
        if not 0 <= self.n_beacons <= n:
            raise ScenarioError(f'{self.n_beacons} beacons requested but the swarm has only '
                                f'{n} agents; use --beacons between 0 and {n}')


@dataclass
class TrialRecord:
    """Truth and belief over time, recorded at ``record_period_s``."""

    times: np.ndarray                 # (T,)
    positions: np.ndarray             # (T, N, 2) true
    velocities: np.ndarray            # (T, N, 2) true
    estimates: np.ndarray             # (T, N, 2) believed
    modes: np.ndarray                 # (T, N)
    alive: np.ndarray                 # (T, N) bool
    goal_ids: np.ndarray              # (T, N)
    digests: np.ndarray               # (T, N) assignment digests
    localized: np.ndarray             # (T, N) bool: the agent has had a fix of its own
    min_separation: np.ndarray        # (T,) smallest separation ratio of the control
    #                                   steps since the previous sample (inf: none near)
    types: np.ndarray                 # (N,)
    beacons: np.ndarray               # (N,) bool
    goals: list                       # final goals
    shapes: list                      # (time, Shape) in order of application
    metrics: dict
    events: list[str]


class HeadlessSwarm:
    """Steps one scenario; see the module docstring."""

    def __init__(self, scenario: Scenario) -> None:
        scenario.validate()
        self.scenario = scenario
        self.rng = np.random.default_rng(scenario.seed)
        self.types = load_robot_types()
        obstacles = list(scenario.shape.obstacles)
        fleet = list(scenario.fleet) if scenario.fleet is not None else random_fleet(
            scenario.type_counts, scenario.n_beacons, self.rng,
            half_size=scenario.half_size, obstacles=obstacles)
        self.fleet = fleet
        self.n = len(fleet)
        self.ids = [r.id for r in fleet]
        self.index = {r.id: i for i, r in enumerate(fleet)}
        self.robot_types = np.array([r.type for r in fleet])
        self.is_beacon = np.array([r.is_beacon for r in fleet])
        # The world places each robot near its fleet position; the brains know only the
        # fleet position and the placement error's standard deviation.
        placed = place_fleet(fleet, scenario.placement_std_m, scenario.seed,
                             radii=[self.types[r.type].coverage_radius for r in fleet],
                             obstacles=obstacles, half_size=scenario.half_size)
        start = np.array([[r.x, r.y] for r in placed], dtype=float)
        self.dynamics = PointMassSwarm([self.types[r.type] for r in fleet], start)
        # The mission computer is a node of the mesh: it learns which agents are alive
        # from the route adverts its radio hears (swarm_agent.mission_radio).
        try:
            self.mission_radio = MeshListener(self.ids)
        except ValueError as exc:
            raise ScenarioError(str(exc)) from None
        self.medium = MediumWithMission(
            RadioMedium(scenario.medium, self.rng, obstacles), self.mission_radio,
            scenario.mission_position if scenario.mission_position is not None
            else scenario.shape.region.centroid.coords[0],
            np.random.default_rng([MISSION_RADIO_STREAM, scenario.seed]), obstacles)
        self.imu = ImuModel(self.n, self.rng)
        self.gps = GpsModel(self.rng)
        self.proximity = ProximityModel(self.rng)
        self.radii = np.array([self.types[r.type].coverage_radius for r in fleet])
        self.brains: list[AgentBrain | None] = [
            make_brain(agent_id=r.id, agent_type=r.type, is_beacon=r.is_beacon,
                       method=scenario.method, initial_position=(r.x, r.y),
                       seed=scenario.seed * 100_003 + r.id,
                       localization_period_s=scenario.localization_period_s,
                       initial_position_std=scenario.placement_std_m)
            for r in fleet]
        self.alive = np.ones(self.n, dtype=bool)
        self.mission = Mission(
            MissionConfig(method=scenario.method,
                          seed=scenario.seed if scenario.partition_seed is None
                          else scenario.partition_seed, remesh=scenario.remesh,
                          radio_range_m=scenario.medium.range_m),
            agent_types={r.id: r.type for r in fleet},
            radii={t: r.coverage_radius for t, r in self.types.items()},
            beacons={r.id for r in fleet if r.is_beacon})
        self.shapes: list[tuple[float, Shape]] = []

    # ------------------------------------------------------------------ mission
    def _apply_shape(self, t: float, shape: Shape) -> None:
        self.mission.set_shape(shape)
        self.shapes.append((t, shape))
        self._broadcast_mission()

    def _broadcast_mission(self) -> None:
        for brain in self.brains:
            if brain is not None:
                brain.set_shape(self.mission.shape, self.mission.shape_version)
                brain.set_goals(self.mission.goals, self.mission.goal_version)

    def _remove(self, t: float, agent_ids: Sequence[int]) -> None:
        for agent in agent_ids:
            i = self.index.get(agent)
            if i is None or not self.alive[i]:
                continue
            self.alive[i] = False
            self.brains[i] = None
            self.medium.remove(agent)
            self.mission.events.append(f't={t:.1f} s: agent {agent} removed')

    # ------------------------------------------------------------------ run
    def run(self, progress: Callable[[float, float], None] | None = None) -> TrialRecord:
        """Run until the settled condition has held for ``settle_hold_s`` after the last
        change with nothing scheduled, or for the duration (then not settled)."""
        sc = self.scenario
        wall0 = wallclock.perf_counter()
        dt = sc.control_dt
        self._apply_shape(0.0, sc.shape)
        pending_shapes = sorted(sc.sequence, key=lambda s: s.time)
        pending_removals = sorted(sc.removals, key=lambda r: r[0])
        pending_events = sorted(sc.events, key=lambda e: e[0])
        steps = int(round(sc.duration_s / dt))
        every = {name: max(1, int(round(period / dt))) for name, period in (
            ('medium', sc.medium_update_s), ('range', sc.range_period_s),
            ('imu', sc.imu_period_s), ('proximity', sc.proximity_period_s or dt),
            ('gps', sc.gps_period_s), ('record', sc.record_period_s))}
        rec: dict[str, list] = {k: [] for k in (
            'times', 'positions', 'velocities', 'estimates', 'modes', 'alive', 'goal_ids',
            'digests', 'localized', 'min_separation')}
        beacon_ids = [self.ids[i] for i in np.flatnonzero(self.is_beacon)]
        forces = np.zeros((self.n, 2))
        settle = SettleTracker(sc.settle_hold_s)
        separation = SeparationTracker()
        self.medium.update_positions(self.ids, self.dynamics.positions)
        imu_v = self.dynamics.velocities.copy()
        for k in range(steps + 1):
            t = k * dt
            while pending_shapes and pending_shapes[0].time <= t:
                self._apply_shape(t, pending_shapes.pop(0).shape)
                settle.change(t)
            while pending_removals and pending_removals[0][0] <= t:
                self._remove(t, pending_removals.pop(0)[1])
                settle.change(t)
            while pending_events and pending_events[0][0] <= t:
                pending_events.pop(0)[1](self, t)
                settle.change(t)
            # Brains: control step and packets out.
            for i, brain in enumerate(self.brains):
                if brain is None:
                    forces[i] = 0.0
                    continue
                out = brain.step(t)
                forces[i] = out.force
                for packet in out.packets:
                    self.medium.transmit(t, packet)
            # Physics, and the metrics that need every step.
            self.dynamics.step(dt, np.where(self.alive[:, None], forces, 0.0))
            separation.update(self.dynamics.positions, self.radii, self.alive)
            settle.update(t, settled_now(self.mission.shape, self.dynamics.positions,
                                         self.dynamics.velocities, self.alive))
            if k % every['medium'] == 0:
                living = np.flatnonzero(self.alive)
                self.medium.update_positions([self.ids[i] for i in living],
                                             self.dynamics.positions[living])
            brains, index = self.brains, self.index
            for packet, receivers in self.medium.deliver_grouped(t):
                for receiver in receivers:   # 10^4 frames a sim-second: kept lean
                    brain = brains[index[receiver]]
                    if brain is not None:
                        brain.on_packet(t, packet)
            # Sensors.
            if k % every['imu'] == 0:
                # Mean acceleration over the IMU interval, as sim_node measures it.
                vel = self.dynamics.velocities
                accel = self.imu.measure((vel - imu_v) / (every['imu'] * dt))
                imu_v = vel.copy()
                for i, brain in enumerate(self.brains):
                    if brain is not None:
                        brain.on_imu(t, accel[i])
            if k % every['range'] == 0:
                for i, brain in enumerate(self.brains):
                    if brain is not None:
                        brain.on_ranges(t, self.medium.toa_ranges(self.ids[i], beacon_ids))
            if sc.proximity_period_s > 0 and k % every['proximity'] == 0:
                scan = self.proximity.measure(self.dynamics.positions, self.radii, self.alive)
                for i, brain in enumerate(self.brains):
                    if brain is not None:
                        brain.on_proximity(t, *scan.of(i))
            if k % every['gps'] == 0:
                for i, brain in enumerate(self.brains):
                    if brain is not None and self.is_beacon[i]:
                        fix, std = self.gps.measure(self.dynamics.positions[i])
                        brain.on_gps(t, fix, std)
            # Liveness for self-repair, over the radio: the agents the mission's radio
            # holds a route to. A removed agent's neighbours time it out and advertise
            # the broken route; the mission stops hearing of it.
            if k % every['record'] == 0:
                for agent in self.mission_radio.alive():
                    self.mission.agent_seen(agent, t)
                version = self.mission.goal_version
                self.mission.check_liveness(t)
                if self.mission.goal_version != version:
                    self._broadcast_mission()
                    settle.change(t)
                self._record(t, rec)
                rec['min_separation'].append(separation.take_interval_min())
                if progress is not None:
                    progress(t, sc.duration_s)
                # Never stop before a scheduled shape change, removal or fault, nor
                # before the observation time.
                if settle.held(t) and t >= sc.min_duration_s and not (
                        pending_shapes or pending_removals or pending_events):
                    break
        return self._finish(rec, wallclock.perf_counter() - wall0, settle, separation)

    def _record(self, t: float, rec: dict[str, list]) -> None:
        snaps = [b.snapshot() if b is not None else None for b in self.brains]
        rec['times'].append(t)
        rec['positions'].append(self.dynamics.positions.copy())
        rec['velocities'].append(self.dynamics.velocities.copy())
        rec['estimates'].append(np.array([s.position if s else [np.nan, np.nan]
                                          for s in snaps]))
        rec['modes'].append(np.array([s.mode if s else -1 for s in snaps]))
        rec['alive'].append(self.alive.copy())
        rec['goal_ids'].append(np.array([s.goal_id if s else -1 for s in snaps]))
        rec['digests'].append(np.array([s.assignment_digest if s else 0 for s in snaps]))
        rec['localized'].append(np.array([bool(s and s.localized) for s in snaps]))

    def _finish(self, rec: dict[str, list], wall_s: float, settle: SettleTracker,
                separation: SeparationTracker) -> TrialRecord:
        arrays = {k: np.asarray(v) for k, v in rec.items()}
        radii = {t: r.coverage_radius for t, r in self.types.items()}
        metrics = trial_metrics(arrays, self.robot_types, self.is_beacon, self.mission.shape,
                                radii, settling=settle.result(),
                                separation=separation.result(), shapes=self.shapes)
        metrics['outcome'] = 'settled' if metrics['settled'] else 'not settled'
        metrics['wall_seconds'] = wall_s
        metrics['real_time_factor'] = float(arrays['times'][-1] / max(wall_s, 1e-9))
        metrics['medium'] = dict(vars(self.medium.stats)) if hasattr(
            self.medium.stats, '__dict__') else dict(self.medium.stats)
        if self.mission.last_result is not None:
            metrics['goal_epsilon_t'] = float(self.mission.last_result.epsilon_t)
            metrics['goal_epsilon_g'] = float(self.mission.last_result.epsilon_g)
        return TrialRecord(types=self.robot_types, beacons=self.is_beacon,
                           goals=list(self.mission.goals), shapes=self.shapes,
                           metrics=metrics, events=list(self.mission.events), **arrays)
