"""The simulated world of the swarm (thesis 4.1-4.2): one object for sim_node and headless.

``World`` steps everything the world does over a physics backend
(``swarm_sim.physics.PhysicsBackend``: pybullet's rigid bodies or point masses):

- forces: the robots' commands, non-finite ones refused (the last valid one holds),
  larger than ``max_force`` scaled down to it, older than ``command_timeout_s`` dropped
  to zero, none for removed robots;
- the radio medium (``swarm_sim.medium``): the link graph refreshed from the true
  positions every ``link_period_s`` (0.1 s; a sweeping wall moved first), the frames
  delivered up to each report, handed out in batches every ``radio_period_s``;
- the sensors of 4.2 at their periods (``swarm_sim.sensors``): the IMU's mean
  acceleration over its sample period, TOA ranges of every living non-beacon robot to
  its living neighbours, beacons first (beacons have GPS; docs/localization.md says why
  they do not fuse ranges to each other; the other neighbours are for secondary
  anchors), the beacons' GPS, the proximity scans;
- faults: a robot removed (radio and body), its radio off and on, an obstacle moved
  (body and radio shadow), the run-time medium settings of ``RUNTIME_SETTINGS``, a
  rogue transmitter (``rogues``, ``swarm_sim.rogue``: it overhears every delivery and
  its frames reach every living robot with the next deliveries); and scheduled events,
  each a commanded change for the settled condition;
- metrics state: the closest approach of coverage circles at every step
  (``SeparationTracker``, with the backend's body contacts), the settled condition of
  eq. 4.1 with its hold window (``SettleTracker``, once a shape is given), and a truth
  sample (positions, velocities, headings, alive, the step-wise minimum separation)
  every ``record_period_s``.

One cycle is ``step()`` (one physics step of ``physics_dt``; the link refresh) as often
as the caller's pacing allows, then ``sense(t)``: the ``Readings`` due since the last
report, stamped ``t`` (the frames due by then, the sensors whose period has passed). A
period is a whole number of physics steps: a sensor due is sampled at the first report
at or after its due step, and is next due a period after that. sim_node stamps a report
with the world's time and converts it to messages; the headless evaluator reports after
every step, stamped with the instant its brains acted (the start of the step), and
calls the brains.

The random draws of a seed come in a fixed order from one generator: the IMU biases at
construction, then per report the medium's losses (at transmission), the IMU noise, the
ranges (living non-beacons in fleet order), the proximity noise and the GPS fixes (living
beacons in fleet order).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
import heapq
import math

import numpy as np
from shapely import affinity
from shapely.geometry import Polygon

from swarm_agent.packet import Packet
from swarm_common.robot_types import RobotType
from swarm_common.shapes import Shape
from swarm_sim.medium import apply_setting, RadioMedium, RUNTIME_SETTINGS
from swarm_sim.metrics import SeparationTracker, SETTLE_HOLD_S, settled_now, SettleTracker
from swarm_sim.physics import PhysicsBackend
from swarm_sim.rogue import make_rogue, ROGUE_KINDS
from swarm_sim.sensors import GpsModel, ImuModel, ProximityModel, ProximityScan

Frames = list[tuple[float, Packet, list[int]]]   # (delivery time, frame, receiver ids)


@dataclass
class WorldConfig:
    """Rates and limits of the world (sim_node's parameters, the headless Scenario's)."""

    physics_dt: float = 0.01          # s, one physics step (sim_node: 100 Hz)
    link_period_s: float = 0.1        # radio links recomputed from the true positions
    radio_period_s: float = 0.05      # deliveries handed out in batches (0: every report)
    imu_period_s: float = 0.1         # 10 Hz, the mean acceleration over the period
    range_period_s: float = 1.0       # TOA ranging
    gps_period_s: float = 1.0         # beacon GPS fixes
    gps_std: float = 2.0              # m per axis, thesis 4.2
    proximity_period_s: float = 0.1   # 0: no proximity sensor
    proximity_range_m: float = 3.0
    proximity_std: float = 0.02       # m per axis
    record_period_s: float = 0.5      # truth samples (2 Hz)
    command_timeout_s: float = math.inf   # older commands drop to zero force
    max_force: float = 50.0           # N, commands are scaled down to it
    half_size: float = 50.0           # m, the workspace (a sweeping wall crosses it)
    settle_hold_s: float = SETTLE_HOLD_S

    def check(self) -> None:
        """ValueError naming the setting out of range."""
        for name in ('physics_dt', 'link_period_s', 'imu_period_s', 'range_period_s',
                     'gps_period_s', 'record_period_s', 'max_force', 'half_size'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f'world setting {name} must be a positive number, got {value}')
        for name in ('radio_period_s', 'proximity_period_s', 'gps_std', 'proximity_std'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f'world setting {name} must be a finite number >= 0, got '
                                 f'{value}')


@dataclass
class TruthSample:
    """The true state at one record instant (what the run metrics are computed from)."""

    t: float
    positions: np.ndarray         # (N, 2) m
    velocities: np.ndarray        # (N, 2) m/s
    yaws: np.ndarray              # (N,) rad
    alive: np.ndarray             # (N,) bool
    min_separation: float         # smallest separation ratio of the steps since the last


@dataclass
class Readings:
    """What the world reports at ``t``; a field is None when nothing of it is due."""

    t: float
    living: np.ndarray                                     # fleet indices of the living
    rx: Frames | None = None                               # deliveries since the last batch
    rogue: list[Packet] | None = None                      # rogue frames sent now (in rx)
    imu: np.ndarray | None = None                          # (N, 2) m/s^2, map frame
    ranges: list[tuple[int, list[tuple[int, float, float]]]] | None = None
    proximity: ProximityScan | None = None
    gps: list[tuple[int, np.ndarray, float]] | None = None  # (index, fix, std) of beacons
    truth: TruthSample | None = None


@dataclass(order=True)
class _Event:
    t: float
    seq: int
    action: Callable[[float], None] = field(compare=False)


class World:
    """The world of one run; see the module docstring."""

    def __init__(self, fleet, types: dict[int, RobotType], backend: PhysicsBackend,
                 config: WorldConfig, rng: np.random.Generator,
                 obstacles: Sequence[Polygon] = (), medium=None) -> None:
        """``fleet`` where the robots stand (``swarm_common.fleet.place_fleet``); ``medium``
        a ``RadioMedium`` (default: one of ``MediumConfig()`` drawing from ``rng``) or a
        medium that wraps one (``MediumWithMission``)."""
        config.check()
        self.config = config
        self.fleet = list(fleet)
        self.n = len(self.fleet)
        self.ids = [r.id for r in self.fleet]
        self.index = {r.id: i for i, r in enumerate(self.fleet)}
        self.is_beacon = np.array([r.is_beacon for r in self.fleet], dtype=bool)
        self.radii = np.array([types[r.type].coverage_radius for r in self.fleet])
        self.obstacles = list(obstacles)
        self.backend = backend
        if medium is None:
            from swarm_sim.medium import MediumConfig
            medium = RadioMedium(MediumConfig(), rng, self.obstacles)
        self.medium = medium
        self.imu = ImuModel(self.n, rng)
        self.gps = GpsModel(rng, std=config.gps_std)
        self.proximity = (ProximityModel(rng, range_m=config.proximity_range_m,
                                         noise_std=config.proximity_std)
                          if config.proximity_period_s > 0 else None)
        self.dt = config.physics_dt
        self.steps = 0
        self.t = 0.0
        self.alive = np.ones(self.n, dtype=bool)   # changed in place, never replaced
        self.forces = np.zeros((self.n, 2))
        self.force_time = np.full(self.n, -math.inf)
        self.separation = SeparationTracker()
        self.settle = SettleTracker(config.settle_hold_s)
        self.shape: Shape | None = None          # settled condition tracked once set
        self._every = {key: max(1, int(round(period / self.dt))) for key, period in (
            ('links', config.link_period_s), ('radio', config.radio_period_s),
            ('imu', config.imu_period_s), ('range', config.range_period_s),
            ('gps', config.gps_period_s), ('proximity', config.proximity_period_s),
            ('record', config.record_period_s))}
        self._next = dict.fromkeys(self._every, 1)   # the first report after one step
        self._rx: Frames = []
        self.rogues: list = []                   # swarm_sim.rogue transmitters
        self.rogue_trailer = True                # the robots authenticate (set_rogue)
        self._events: list[_Event] = []
        self._event_seq = 0
        self.medium.update_positions(self.ids, self.backend.positions())
        self._imu_v = np.array(self.backend.velocities(), dtype=float)
        self._imu_steps = 0

    # -- commands
    def command(self, forces, rows=None) -> tuple[list[int], list[int]]:
        """Force commands (N, map frame) of the robots ``rows`` (default: all, in order).

        Returns the rows (refused as non-finite, scaled down to ``max_force``).
        """
        f = np.array(forces, dtype=float).reshape(-1, 2)
        rows = np.arange(self.n) if rows is None else np.asarray(rows, dtype=int)
        finite = np.isfinite(f).all(axis=1)
        norm = np.hypot(f[:, 0], f[:, 1])
        limit = self.config.max_force
        over = finite & (norm > limit)
        if over.any():
            f[over] *= (limit / norm[over])[:, None]
        self.forces[rows[finite]] = f[finite]
        self.force_time[rows[finite]] = self.t
        return rows[~finite].tolist(), rows[over].tolist()

    # -- faults
    def find(self, agent_ids) -> tuple[list[int], list[int]]:
        """(fleet indices of the living robots among ``agent_ids``, ids not in the fleet)."""
        unknown = [int(a) for a in agent_ids if int(a) not in self.index]
        living = [self.index[int(a)] for a in agent_ids
                  if int(a) in self.index and self.alive[self.index[int(a)]]]
        return living, unknown

    def remove(self, i: int) -> bool:
        """Robot ``i`` leaves the world (radio and body); False if it already had."""
        if not self.alive[i]:
            return False
        self.alive[i] = False
        self.medium.remove(self.ids[i])
        self.backend.remove(i)
        return True

    def set_radio(self, i: int, on: bool) -> None:
        """Robot ``i``'s radio dies or comes back; the robot stays in the world."""
        (self.medium.enable_radio if on else self.medium.disable_radio)(self.ids[i])

    def move_obstacle(self, k: int, dx: float, dy: float) -> None:
        """Obstacle ``k`` of the shape spec moves by (dx, dy) m: bodies and radio shadow
        (the agents are not told). ValueError naming a bad index or offset."""
        if not (math.isfinite(dx) and math.isfinite(dy)):
            raise ValueError(f'obstacle offsets must be finite metres, got ({dx}, {dy})')
        if not 0 <= k < len(self.obstacles):
            raise ValueError(f'no obstacle {k} (the shape spec has {len(self.obstacles)}, '
                             'indices from 0)')
        self.backend.move_obstacle(k, dx, dy)
        self.obstacles[k] = affinity.translate(self.obstacles[k], dx, dy)
        self.medium.set_obstacles(self.obstacles)

    def inject(self, fault: str, data: Sequence[float]) -> list[str]:
        """A fault as the fault topics name it, with its log lines (what happened, what
        was ignored and why): ``kill``, ``radio_off``, ``radio_on`` with robot ids, or
        ``move_obstacle`` with ``[index, dx, dy]``."""
        if fault == 'move_obstacle':
            data = list(data)
            try:
                if len(data) != 3 or not math.isfinite(data[0]) or data[0] != int(data[0]):
                    raise ValueError('expected [index, dx, dy] with an integer index and '
                                     f'finite metres, got {data}')
                self.move_obstacle(int(data[0]), data[1], data[2])
            except ValueError as exc:
                return [f'/swarm/move_obstacle: {exc}; ignored']
            return [f't={self.t:.1f} s: obstacle {int(data[0])} moved by ({data[1]:g}, '
                    f'{data[2]:g}) m (fault injection)']
        if fault not in ('kill', 'radio_off', 'radio_on'):
            raise ValueError(f'unknown fault {fault!r}; use kill, radio_off, radio_on or '
                             'move_obstacle')
        living, unknown = self.find(data)
        lines = [f'/swarm/{fault}: no robot {unknown} in the fleet (ids {min(self.ids)}..'
                 f'{max(self.ids)}); ignored'] if unknown else []
        for i in living:
            if fault == 'kill':
                self.remove(i)
                lines.append(f't={self.t:.1f} s: robot {self.ids[i]} removed (fault injection)')
            else:
                self.set_radio(i, fault == 'radio_on')
                lines.append(f't={self.t:.1f} s: robot {self.ids[i]} radio '
                             f'{"back on" if fault == "radio_on" else "off"} (fault injection)')
        return lines

    def apply_setting(self, name: str, value: float) -> None:
        """A run-time medium setting of ``RUNTIME_SETTINGS`` from now
        (``swarm_sim.medium.apply_setting``: packet loss, radio range, or a wall sweeping
        the workspace from x = -half_size, 0 removes it). ValueError naming an unknown
        setting or a bad value."""
        check = RUNTIME_SETTINGS.get(name)
        if name == 'rogue':
            self.set_rogue(check(value))
            return
        apply_setting(self.medium, name, check(value) if check else value, self.t,
                      self.config.half_size)

    def set_rogue(self, code: float) -> None:
        """From now a rogue of ``swarm_sim.rogue.ROGUE_KINDS[code - 1]`` transmits (0:
        none), its frames sealed with a bad tag when ``rogue_trailer``."""
        self.rogues = [make_rogue(ROGUE_KINDS[int(code) - 1], self.ids, self.rogue_trailer,
                                  self.t)] if code else []

    # -- scheduled events and the settled condition
    def schedule(self, t: float, action: Callable[[float], None]) -> None:
        """Call ``action(t_now)`` at the first report stamped ``t`` or later (in the order
        scheduled among equal times); a commanded change for the settled condition."""
        self._event_seq += 1
        heapq.heappush(self._events, _Event(float(t), self._event_seq, action))

    def run_due(self, t: float) -> int:
        """Run the scheduled events due at ``t``; how many ran."""
        ran = 0
        while self._events and self._events[0].t <= t:
            heapq.heappop(self._events).action(t)
            self.settle.change(t)
            ran += 1
        return ran

    @property
    def pending(self) -> int:
        """Scheduled events not run yet."""
        return len(self._events)

    def changed(self, t: float) -> None:
        """A commanded change at ``t`` (new goals, a fault): the settled streak ends."""
        self.settle.change(t)

    # -- stepping
    def step(self) -> None:
        """One physics step of ``physics_dt`` under the commanded forces."""
        stale = self.t - self.force_time > self.config.command_timeout_s
        self.backend.step(self.dt, np.where((stale | ~self.alive)[:, None], 0.0, self.forces))
        self.steps += 1
        self.t = self.steps * self.dt
        positions = self.backend.positions()
        self.separation.update(positions, self.radii, self.alive)
        self.backend.count_body_contacts(self.separation.overlapping_pairs())
        if self._due('links'):
            self.refresh_links()

    def refresh_links(self) -> None:
        """The medium's links from the living robots' true positions (a wall moved first)."""
        living = np.flatnonzero(self.alive)
        self.medium.move_wall(self.t)
        self.medium.update_positions([self.ids[i] for i in living],
                                     self.backend.positions()[living])

    def _due(self, key: str) -> bool:
        if self.steps >= self._next[key]:
            self._next[key] = self.steps + self._every[key]
            return True
        return False

    def sense(self, t: float | None = None) -> Readings:
        """The readings due now, stamped ``t`` (default: the world's time)."""
        t = self.t if t is None else float(t)
        alive = self.alive
        positions = self.backend.positions()
        if self.shape is not None:
            self.settle.update(t, settled_now(self.shape, positions,
                                              self.backend.velocities(), alive))
        out = Readings(t, np.flatnonzero(alive))
        delivered = self.medium.deliver_grouped(t)
        self._rx.extend((t, packet, receivers) for packet, receivers in delivered)
        if self.rogues:
            out.rogue = self._rogue(t, delivered, out.living)
        if self._due('radio'):
            out.rx, self._rx = self._rx, []
        if self._due('imu'):
            # A real IMU reports the mean acceleration over its sample period (it
            # integrates internally); sampling one physics step would alias the
            # control-rate force changes into the agents' velocity estimates.
            vel = np.array(self.backend.velocities(), dtype=float)
            interval = max(self.steps - self._imu_steps, self._every['imu']) * self.dt
            mean = (vel - self._imu_v) / interval
            self._imu_v, self._imu_steps = vel, self.steps
            out.imu = self.imu.measure(mean)
        if self._due('range'):
            beacons = [self.ids[i] for i in np.flatnonzero(alive & self.is_beacon)]
            out.ranges = [(int(i), self.medium.toa_ranges(self.ids[i], beacons, peers=True))
                          for i in out.living if not self.is_beacon[i]]
        if self.proximity is not None and self._due('proximity'):
            out.proximity = self.proximity.measure(positions, self.radii, alive)
        if self._due('gps'):
            out.gps = [(int(i), *self.gps.measure(positions[i]))
                       for i in np.flatnonzero(alive & self.is_beacon)]
        if self._due('record'):
            out.truth = TruthSample(
                t, np.array(positions, dtype=float), np.array(self.backend.velocities()),
                self.backend.yaws(), alive.copy(), self.separation.take_interval_min())
        return out

    def _rogue(self, t: float, delivered, living: np.ndarray) -> list[Packet]:
        """The rogues overhear this report's deliveries; their frames go to every living
        robot with them, and to the mission computer's radio when the medium has one."""
        frames = []
        for rogue in self.rogues:
            for packet, _ in delivered:
                rogue.overhear(t, packet)
            frames += rogue.frames(t)
        if frames:
            receivers = [self.ids[i] for i in living]
            self._rx.extend((t, packet, receivers) for packet in frames)
            listener = getattr(self.medium, 'listener', None)   # MediumWithMission
            for packet in frames if listener is not None else ():
                listener.on_packet(t, packet)
        return frames

    def links_by_index(self) -> np.ndarray:
        """The medium's link graph (it holds the living robots) as an (N, N) bool matrix."""
        ids, links = self.medium.adjacency()
        at = [self.index[a] for a in ids]
        full = np.zeros((self.n, self.n), dtype=bool)
        full[np.ix_(at, at)] = links
        return full

    def close(self) -> None:
        """Release the physics."""
        self.backend.close()
