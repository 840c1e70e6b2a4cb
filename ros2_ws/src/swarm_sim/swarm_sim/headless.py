"""Headless evaluation: N agent brains and the world model in one process.

This is the Monte Carlo workhorse of thesis chapter 4. It runs exactly the code of the
ROS system (``AgentBrain`` built by ``make_brain``, ``Mission`` with the same
partitioners, and the very world model sim_node runs, ``swarm_sim.world_model.World``:
sensors, radio medium, faults, settled condition, truth record) but with the point-mass
backend (``swarm_sim.physics.PointMassBackend``) and direct calls instead of pybullet
and DDS, so a 50-agent trial takes seconds.

One control step (``control_dt``, 50 Hz by default, also the physics step) does, in
order: the scheduled shape changes, removals and fault events due; every living brain
steps (inner LQR loop; outer loop at 2 Hz; localization every 3 s) and hands its
packets to the medium, except a parked one with nothing due, which rests
(``AgentBrain.rest``: the same as its step; the counts are in the metrics,
``brain_steps``); the world steps and reports, stamped with the control instant:
the brains get the radio deliveries, IMU, ranges, proximity scans and GPS fixes due.
At every truth sample (``record_period_s``) the mission hears which agents are alive
over its radio, the beliefs are recorded beside the truth, and the run ends once the
settled condition (eq. 4.1) has held for ``settle_hold_s`` with nothing scheduled.

Radio frames are authenticated as on the robots (``swarm_agent.frame_auth``) under
``swarm_key_file`` (default: the development key); ``auth=False`` only for the
with/without comparison. The frames the brains and the mission's radio rejected, by kind,
are in the metrics (``frames_rejected``). ``rogues`` are transmitters without the key
(``swarm_sim.rogue``): the world hands them every delivery and their frames to every
living robot (``World.rogues``); the mission's radio hears them too.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
import time as wallclock

import numpy as np

from swarm_agent.agent_factory import make_brain, swarm_keyring
from swarm_agent.brain import AgentBrain
from swarm_agent.frame_auth import FrameAuth, FrameAuthError, ReplayStore
from swarm_agent.mission_radio import MeshListener
from swarm_agent.reception import receive, ReceiverSets
from swarm_agent.route_table import RouteStore
from swarm_common.fleet import place_fleet, PLACEMENT_STD_M, random_fleet, RobotSpec
from swarm_common.robot_types import load_robot_types
from swarm_common.shapes import Shape
from swarm_mission.mission import Mission, MissionConfig, SequenceStep
from swarm_sim.medium import MediumConfig, RadioMedium
from swarm_sim.metrics import SETTLE_HOLD_S, trial_metrics
from swarm_sim.mission_mesh import MediumWithMission, MISSION_RADIO_STREAM
from swarm_sim.physics import PointMassBackend
from swarm_sim.world_model import Readings, World, WorldConfig

METHODS = ('bubble', 'fractal', 'forces')


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
    medium_update_s: float = 0.1          # how often links are recomputed (as sim_node)
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
    # start from the fleet positions with this uncertainty (swarm_common.fleet.place_fleet).
    placement_std_m: float = PLACEMENT_STD_M
    # Where the mission computer's radio stands (m); None: the first shape's centroid.
    mission_position: tuple[float, float] | None = None
    remesh: str = 'incremental'           # bubble packing on a changed shape (MissionConfig)
    auth: bool = True                     # authenticated radio frames (frame_auth)
    swarm_key_file: str | None = None     # None: the development key (config/)
    # Rogue transmitters (swarm_sim.rogue): they overhear every delivery and their frames
    # reach every living robot and the mission's radio.
    rogues: Sequence = ()

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
        if self.auth:
            try:
                swarm_keyring(self.swarm_key_file)
            except FrameAuthError as exc:
                raise ScenarioError(str(exc)) from None


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
        backend = PointMassBackend(placed, self.types)
        self.dynamics = backend.model
        # The mission computer is a node of the mesh: it learns which agents are alive
        # from the route adverts its radio hears (swarm_agent.mission_radio).
        try:
            keyring = swarm_keyring(scenario.swarm_key_file) if scenario.auth else None
            self.mission_radio = MeshListener(
                self.ids, auth=FrameAuth(keyring) if keyring is not None else None)
        except (ValueError, FrameAuthError) as exc:
            raise ScenarioError(str(exc)) from None
        self.rejected: dict[str, int] = {}   # frames the removed brains had rejected
        self.medium = MediumWithMission(
            RadioMedium(scenario.medium, self.rng, obstacles), self.mission_radio,
            scenario.mission_position if scenario.mission_position is not None
            else scenario.shape.region.centroid.coords[0],
            np.random.default_rng([MISSION_RADIO_STREAM, scenario.seed]), obstacles)
        dt = scenario.control_dt
        self.world = World(placed, self.types, backend, WorldConfig(
            physics_dt=dt, link_period_s=scenario.medium_update_s, radio_period_s=0.0,
            imu_period_s=scenario.imu_period_s, range_period_s=scenario.range_period_s,
            gps_period_s=scenario.gps_period_s,
            proximity_period_s=scenario.proximity_period_s,
            record_period_s=scenario.record_period_s, half_size=scenario.half_size,
            settle_hold_s=scenario.settle_hold_s), self.rng, obstacles, self.medium)
        self.alive = self.world.alive
        self.radii = self.world.radii
        self._keyring = keyring
        # Every brain's route table and replay windows: one call per frame heard.
        self._routes, self._windows = RouteStore(), ReplayStore()
        self.brains: list[AgentBrain | None] = [self._new_brain(r, 0.0) for r in fleet]
        self._by_id = dict(zip(self.ids, self.brains))   # radio address -> brain (or None)
        self._heard = ReceiverSets(self._by_id.__getitem__)  # cleared as brains change
        self.mission = Mission(
            MissionConfig(method=scenario.method,
                          seed=scenario.seed if scenario.partition_seed is None
                          else scenario.partition_seed, remesh=scenario.remesh,
                          radio_range_m=scenario.medium.range_m),
            agent_types={r.id: r.type for r in fleet},
            radii={t: r.coverage_radius for t, r in self.types.items()},
            beacons={r.id for r in fleet if r.is_beacon})
        self.shapes: list[tuple[float, Shape]] = []
        self.brain_steps = {'steps': 0, 'active': 0, 'resting': 0}

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
            if i is not None and self.world.remove(i):
                _add_counts(self.rejected, self.brains[i].auth_stats)
                self.brains[i] = self._by_id[agent] = None
                self._heard.clear()
                self.mission.events.append(f't={t:.1f} s: agent {agent} removed')

    # ------------------------------------------------------------------ restarts
    def _new_brain(self, r: RobotSpec, boot_time_s: float, t: float = 0.0) -> AgentBrain:
        """Robot ``r``'s brain as its agent node builds it, booted at ``boot_time_s`` of
        simulated time (the clock of ``dsdv.boot_sequence`` here: runs stay reproducible),
        at run time ``t``. Its prior is the fleet position with the placement error; at
        ``t`` > 0 the body may have driven from there and still be driving, which the
        prior then says (``Localizer.restarted``, as a respawned agent node does), so the
        first trilateration places it (thesis 3.1.1)."""
        sc = self.scenario
        brain = make_brain(agent_id=r.id, agent_type=r.type, is_beacon=r.is_beacon,
                           method=sc.method, initial_position=(r.x, r.y),
                           seed=sc.seed * 100_003 + r.id,
                           localization_period_s=sc.localization_period_s,
                           initial_position_std=sc.placement_std_m,
                           keyring=self._keyring, auth=sc.auth, boot_time_s=boot_time_s,
                           route_store=self._routes, replay_store=self._windows)
        if t > 0.0:
            brain.localizer.restarted(t)
        return brain

    def restart(self, t: float, agent_ids: Sequence[int],
                boot_time_s: float | None = None) -> None:
        """Agents' processes crash and come back at ``t``: each brain is dropped with all
        it knew and a fresh one is built with the same id and configuration, booted at
        ``t``; the robot's body stays where it is. The new brain gets the mission's shape
        and goals at once, as a respawned agent node gets the transient-local topics.
        Removed agents stay removed; an id not in the fleet raises ScenarioError.
        ``boot_time_s`` replaces ``t`` as the boot clock reading (0: a router whose numbers
        start from 0 at every boot, for the comparison in docs/restarts.md)."""
        for agent in agent_ids:
            i = self.index.get(agent)
            if i is None:
                raise ScenarioError(f'cannot restart agent {agent}: not in the fleet')
            if self.brains[i] is None:
                continue
            _add_counts(self.rejected, self.brains[i].auth_stats)
            brain = self.brains[i] = self._by_id[agent] = self._new_brain(
                self.fleet[i], t if boot_time_s is None else boot_time_s, t)
            self._heard.clear()
            if self.mission.shape is not None:
                brain.set_shape(self.mission.shape, self.mission.shape_version)
                brain.set_goals(self.mission.goals, self.mission.goal_version)
            self.mission.events.append(f't={t:.1f} s: agent {agent} restarted')

    # ------------------------------------------------------------------ run
    def run(self, progress: Callable[[float, float], None] | None = None,
            sink: Callable[[dict], None] | None = None) -> TrialRecord:
        """Run until the settled condition has held for ``settle_hold_s`` after the last
        change with nothing scheduled, or for the duration (then not settled). ``sink``
        gets each sample of the record as it is taken (``run_record.RecordLog.add``)."""
        sc, world = self.scenario, self.world
        wall0 = wallclock.perf_counter()
        self._apply_shape(0.0, sc.shape)
        # Shapes, removals, then fault events: among equal times, in that order.
        for step in sorted(sc.sequence, key=lambda s: s.time):
            world.schedule(step.time, lambda t, shape=step.shape: self._apply_shape(t, shape))
        for t_remove, agents in sorted(sc.removals, key=lambda r: r[0]):
            world.schedule(t_remove, lambda t, agents=agents: self._remove(t, agents))
        for t_event, event in sorted(sc.events, key=lambda e: e[0]):
            world.schedule(t_event, lambda t, event=event: event(self, t))
        rec: dict[str, list] = {k: [] for k in (
            'times', 'positions', 'velocities', 'estimates', 'modes', 'alive', 'goal_ids',
            'digests', 'localized', 'min_separation')}
        forces = np.zeros((self.n, 2))
        stepped = resting = 0   # brain steps taken, and skipped as nothing was due
        world.refresh_links()   # settings applied before the run (a loss) hold from t = 0
        world.rogues = list(sc.rogues)
        for _ in range(int(round(sc.duration_s / sc.control_dt)) + 1):
            t = world.t
            world.run_due(t)
            # Brains: control step and packets out.
            for i, brain in enumerate(self.brains):
                if brain is None:
                    forces[i] = 0.0
                    continue
                if brain.rest(t):   # parked, nothing due: its force stays zero
                    resting += 1
                    continue
                stepped += 1
                out = brain.step(t)
                forces[i] = out.force
                for packet in out.packets:
                    self.medium.transmit(t, packet)
            world.command(forces)
            world.step()
            world.shape = self.mission.shape
            readings = world.sense(t)
            self._feed(readings)
            if readings.truth is not None:
                self._sample(readings, rec)
                if sink is not None:
                    sink({k: v[-1] for k, v in rec.items()})
                if progress is not None:
                    progress(t, sc.duration_s)
                # Never stop before a scheduled shape change, removal or fault, nor
                # before the observation time.
                if (world.settle.held(t) and t >= sc.min_duration_s
                        and not world.pending):
                    break
        self.brain_steps = {'steps': stepped + resting, 'active': stepped,
                            'resting': resting}
        return self._finish(rec, wallclock.perf_counter() - wall0)

    def _feed(self, readings: Readings) -> None:
        """The world's readings to the living brains: radio, IMU, ranges, proximity, GPS."""
        brains, heard_by = self.brains, self._heard
        for t, packet, receivers in readings.rx or ():
            # One transmission, all its receivers in one call (reception.receive); the
            # removed (while the frame was on the air) are left out.
            heard = heard_by(receivers)
            if heard is not None:
                receive(t, packet, heard)
        t = readings.t
        if readings.imu is not None:
            # Every living brain's sample in one call (one Kalman prediction for all).
            living = readings.living
            AgentBrain.take_imu(t, [brains[i] for i in living], readings.imu[living])
        for i, ranges in readings.ranges or ():
            brains[i].on_ranges(t, ranges)
        if readings.proximity is not None:
            # Every living brain's scan in one call (AgentBrain.take_proximity).
            scan, living = readings.proximity, readings.living
            starts, ends = scan.rows_of(living)
            AgentBrain.take_proximity(t, [brains[i] for i in living], scan.offsets,
                                      scan.radii, starts, ends)
        for i, fix, std in readings.gps or ():
            brains[i].on_gps(t, fix, std)

    def frames_rejected(self) -> dict[str, int]:
        """Frames the brains (living and removed) and the mission's radio rejected, by
        kind (``frame_auth.REJECTIONS``)."""
        counts = dict(self.rejected)
        for brain in self.brains:
            if brain is not None:
                _add_counts(counts, brain.auth_stats)
        if self.mission_radio.auth is not None:
            _add_counts(counts, self.mission_radio.auth.stats)
        return dict(sorted(counts.items()))

    def _sample(self, readings: Readings, rec: dict[str, list]) -> None:
        """A truth sample: liveness for self-repair over the radio, then the record.

        The mission learns which agents are alive from the routes its radio holds: a
        removed agent's neighbours time it out and advertise the broken route.
        """
        t = readings.t
        for agent in self.mission_radio.alive():
            self.mission.agent_seen(agent, t)
        version = self.mission.goal_version
        self.mission.check_liveness(t)
        if self.mission.goal_version != version:
            self._broadcast_mission()
            self.world.changed(t)
        self._record(readings, rec)

    def _record(self, readings: Readings, rec: dict[str, list]) -> None:
        truth = readings.truth
        snaps = [b.snapshot() if b is not None else None for b in self.brains]
        rec['times'].append(truth.t)
        rec['positions'].append(truth.positions)
        rec['velocities'].append(truth.velocities)
        rec['estimates'].append(np.array([s.position if s else [np.nan, np.nan]
                                          for s in snaps]))
        rec['modes'].append(np.array([s.mode if s else -1 for s in snaps]))
        rec['alive'].append(truth.alive)
        rec['goal_ids'].append(np.array([s.goal_id if s else -1 for s in snaps]))
        rec['digests'].append(np.array([s.assignment_digest if s else 0 for s in snaps]))
        rec['localized'].append(np.array([bool(s and s.localized) for s in snaps]))
        rec['min_separation'].append(truth.min_separation)

    def _finish(self, rec: dict[str, list], wall_s: float) -> TrialRecord:
        arrays = {k: np.asarray(v) for k, v in rec.items()}
        radii = {t: r.coverage_radius for t, r in self.types.items()}
        metrics = trial_metrics(arrays, self.robot_types, self.is_beacon, self.mission.shape,
                                radii, settling=self.world.settle.result(),
                                separation=self.world.separation.result(), shapes=self.shapes)
        metrics['outcome'] = 'settled' if metrics['settled'] else 'not settled'
        metrics['wall_seconds'] = wall_s
        metrics['real_time_factor'] = float(arrays['times'][-1] / max(wall_s, 1e-9))
        metrics['medium'] = dict(vars(self.medium.stats))
        metrics['auth'] = self.scenario.auth
        metrics['frames_rejected'] = self.frames_rejected()
        metrics['brain_steps'] = dict(self.brain_steps)
        if self.mission.last_result is not None:
            metrics['goal_epsilon_t'] = float(self.mission.last_result.epsilon_t)
            metrics['goal_epsilon_g'] = float(self.mission.last_result.epsilon_g)
        return TrialRecord(types=self.robot_types, beacons=self.is_beacon,
                           goals=list(self.mission.goals), shapes=self.shapes,
                           metrics=metrics, events=list(self.mission.events), **arrays)


def restart_event(agent_ids: Sequence[int]) -> Callable[[HeadlessSwarm, float], None]:
    """A ``Scenario.events`` hook restarting ``agent_ids``: ``(t, restart_event([7]))``."""
    ids = tuple(int(a) for a in agent_ids)
    return lambda swarm, t: swarm.restart(t, ids)


def _add_counts(total: dict[str, int], counts: dict[str, int]) -> None:
    for key, n in counts.items():
        total[key] = total.get(key, 0) + n
