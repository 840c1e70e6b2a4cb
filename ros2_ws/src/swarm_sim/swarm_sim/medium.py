"""The radio medium of the simulated mesh (thesis 4.1), shared by sim_node and the evaluator.

Two robots share a link when they are within ``range_m`` (25 m) and the segment between
them crosses no obstacle (line of sight, shapely STRtree over the obstacles, tested
only for the pairs in range). Every transmission is heard by
each linked receiver independently, with probability ``1 - loss``, after the sender's
airtime (frames are serialised at ``bandwidth_bps`` per sender) plus ``latency_s``.
TOA ranges to direct neighbours are the true distance plus Gaussian noise of
``range_noise_std``: to beacons for trilateration (3.1.1) and, with ``peers``, to every
other neighbour (agents anchor on parked, localized neighbours: ``swarm_agent.localization``,
"Secondary anchors"). Peer ranges draw from a stream of their own, so that the beacon
ranges and the losses of a seed do not depend on them.

Faults at run time: ``set_loss``, ``set_range`` and a ``SweepingWall`` (a radio-opaque
wall crossing the workspace, ``start_wall`` / ``move_wall``); ``RUNTIME_SETTINGS`` names
the checks of the values sim_node accepts as run-time parameters.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
import heapq
import math

import numpy as np
import shapely
from shapely.geometry import box, Polygon

from swarm_agent.packet import BROADCAST, Packet
from swarm_common.jit import kernel
from swarm_common.parameters import tunable
from swarm_sim.rogue import check_rogue

FRAME_OVERHEAD_BYTES = 18  # XBee API frame + 802.15.4 header around the payload
WALL_THICKNESS_M = 1.0


def check_loss(loss: float) -> float:
    """A packet loss probability, or ValueError."""
    loss = float(loss)
    if not 0.0 <= loss <= 1.0:
        raise ValueError(f'packet loss must be in [0, 1], got {loss}')
    return loss


def check_range(range_m: float) -> float:
    """A radio range in metres (finite, > 0), or ValueError."""
    range_m = float(range_m)
    if not (math.isfinite(range_m) and range_m > 0.0):
        raise ValueError(f'radio range must be a positive number of metres, got {range_m}')
    return range_m


def check_wall_speed(speed: float) -> float:
    """Speed of a sweeping wall in m/s (0: no wall, else > 0 and finite), or ValueError."""
    speed = float(speed)
    if not (math.isfinite(speed) and speed >= 0.0):
        raise ValueError(f'wall speed must be 0 (no wall) or positive in m/s, got {speed}')
    return speed


# sim_node parameters that change the medium at run time, with the check of their value.
# 'rogue' (a transmitter without the key, ``swarm_sim.rogue``) is the world's, not the
# medium's: ``World.apply_setting`` takes it.
RUNTIME_SETTINGS: dict[str, Callable[[float], float]] = {
    'loss': check_loss, 'radio_range_m': check_range, 'radio_wall_speed_mps': check_wall_speed,
    'rogue': check_rogue}


def wall_polygon(x: float, half_length: float, thickness: float = WALL_THICKNESS_M) -> Polygon:
    """A wall ``thickness`` wide along y in [-half_length, half_length], centred on x."""
    return box(x - thickness / 2, -half_length, x + thickness / 2, half_length)


@dataclass
class SweepingWall:
    """A radio-opaque wall crossing the workspace along +x (a fault: cuts links only).

    Starts at ``x = -half_length`` at ``t0`` and moves at ``speed``; gone once past
    ``+half_length``.
    """

    t0: float
    speed: float
    half_length: float
    thickness: float = WALL_THICKNESS_M

    def x_at(self, t: float) -> float | None:
        """The wall's x at time t, None before it starts or after it has left."""
        x = -self.half_length + self.speed * (t - self.t0)
        if t < self.t0 or x > self.half_length:
            return None
        return x

    def at(self, t: float) -> Polygon | None:
        x = self.x_at(t)
        return None if x is None else wall_polygon(x, self.half_length, self.thickness)


@dataclass
class MediumConfig:
    """Radio parameters. The ``tunable`` fields are sim_node's ``medium.*`` parameters
    (swarm_sim.sim_parameters); range and loss are its live ``radio_range_m`` and
    ``loss`` (``RUNTIME_SETTINGS``)."""

    range_m: float = 25.0            # thesis 4.1
    line_of_sight: bool = tunable(True, 'Obstacles cut radio links (thesis 4.1)')
    loss: float = 0.0                # per-receiver packet loss probability
    latency_s: float = tunable(0.005, 'Radio latency, propagation and processing (s)',
                               low=0.0, high=10.0)
    bandwidth_bps: float = tunable(250_000.0, 'Radio air rate per transmitter (bit/s; '
                                              '802.15.4 / XBee: 250 kbit/s)',
                                   low=1.0, high=1e9)
    range_noise_std: float = tunable(0.3, 'TOA ranging noise (m, not given by the thesis)',
                                     low=0.0, high=100.0)


@dataclass
class MediumStats:
    """Counters since creation."""

    sent: int = 0
    delivered: int = 0
    dropped_loss: int = 0
    dropped_range: int = 0
    dropped_dead: int = 0
    bytes_sent: int = 0


class RadioMedium:
    """Links, losses, delays and TOA ranges; see the module docstring."""

    def __init__(self, config: MediumConfig, rng: np.random.Generator,
                 obstacles: Sequence[Polygon] = ()) -> None:
        check_loss(config.loss)
        check_range(config.range_m)
        self.config = config
        self.rng = rng
        self._peer_rng = rng.spawn(1)[0]
        self.stats = MediumStats()
        self.ids: list[int] = []
        self.index: dict[int, int] = {}
        self.positions = np.zeros((0, 2))
        self._links: np.ndarray = np.zeros((0, 0), dtype=bool)
        self._linked_ids: list[int] = []      # the ids of _links's rows
        self._neighbours: dict[int, list[int]] = {}
        self._dead: set[int] = set()
        # One entry per transmission: (arrival, order, packet, receivers that kept it).
        # Not one per receiver: a broadcast reaches tens of neighbours, and pushing and
        # popping each was a third of the simulator's time with 50 robots (py-spy).
        self._queue: list[tuple[float, int, Packet, list[int]]] = []
        self._busy_until: dict[int, float] = {}
        self._counter = 0
        self.wall: SweepingWall | None = None
        self._wall_shape: Polygon | None = None
        self.set_obstacles(obstacles)

    def set_obstacles(self, obstacles: Sequence[Polygon]) -> None:
        """Replace the obstacles that block line of sight (a sweeping wall stays)."""
        self.static_obstacles = [o for o in obstacles if o is not None and not o.is_empty]
        self._rebuild_obstacles()

    def _rebuild_obstacles(self) -> None:
        self.obstacles = self.static_obstacles + (
            [self._wall_shape] if self._wall_shape is not None else [])
        self._tree = shapely.STRtree(self.obstacles) if self.obstacles else None

    def set_loss(self, loss: float) -> None:
        self.config.loss = check_loss(loss)

    def set_range(self, range_m: float) -> None:
        """Change the radio range; links follow at the next ``update_positions``."""
        self.config.range_m = check_range(range_m)

    def start_wall(self, wall: SweepingWall | None) -> None:
        """Start (or, with None, remove) a sweeping wall; see ``move_wall``."""
        self.wall = wall
        self._wall_shape = None
        self._rebuild_obstacles()

    def move_wall(self, t: float) -> float | None:
        """Place the sweeping wall at time t (before ``update_positions``); its x or None.

        The wall is dropped once it has left the workspace.
        """
        if self.wall is None:
            return None
        x = self.wall.x_at(t)
        self._wall_shape = self.wall.at(t)
        if x is None and t >= self.wall.t0:
            self.wall = None
        self._rebuild_obstacles()
        return x

    def disable_radio(self, agent_id: int) -> None:
        self._dead.add(int(agent_id))

    def enable_radio(self, agent_id: int) -> None:
        self._dead.discard(int(agent_id))

    def remove(self, agent_id: int) -> None:
        """The robot is gone: no more links, queued frames to it are dropped."""
        self._dead.add(int(agent_id))

    def update_positions(self, ids: Sequence[int], positions) -> None:
        """True positions (N, 2) of the robots; recomputes the link graph."""
        self.ids = [int(i) for i in ids]
        self.index = {a: k for k, a in enumerate(self.ids)}
        self.positions = np.asarray(positions, dtype=float).reshape(-1, 2)
        n = len(self.ids)
        dead = np.zeros(n, dtype=bool)
        for d in self._dead:
            if d in self.index:
                dead[self.index[d]] = True
        links = _in_range(self.positions, float(self.config.range_m), dead)
        if self.config.line_of_sight and self._tree is not None and n > 1:
            pairs = np.argwhere(np.triu(links, 1))
            if len(pairs):
                lines = shapely.linestrings(np.stack(
                    [self.positions[pairs[:, 0]], self.positions[pairs[:, 1]]], axis=1))
                hit = pairs[np.unique(self._tree.query(lines, predicate='intersects')[0])]
                links[hit[:, 0], hit[:, 1]] = False
                links[hit[:, 1], hit[:, 0]] = False
        if (links.shape == self._links.shape and self.ids == self._linked_ids
                and np.array_equal(links, self._links)):
            return   # the same links: the neighbour lists stand (none is ever changed)
        self._links = links
        self._linked_ids = self.ids
        # Each robot's neighbours in id order: one nonzero over the link matrix, its
        # columns cut at the row ends (a quarter of the time of one search per row).
        rows, cols = np.nonzero(links)
        heard = np.asarray(self.ids, dtype=np.int64)[cols].tolist()
        ends = np.cumsum(np.bincount(rows, minlength=n)).tolist()
        self._neighbours = {a: heard[start:end]
                            for a, start, end in zip(self.ids, [0] + ends, ends)}

    def neighbours(self, agent_id: int) -> list[int]:
        return list(self._neighbours.get(int(agent_id), []))

    def adjacency(self) -> tuple[list[int], np.ndarray]:
        return list(self.ids), self._links.copy()

    def transmit(self, t: float, packet: Packet) -> None:
        """Queue a frame; each receiver in range draws its own loss."""
        sender = int(packet.source)
        self.stats.sent += 1
        self.stats.bytes_sent += len(packet.payload)
        if sender in self._dead or sender not in self.index:
            self.stats.dropped_dead += 1
            return
        airtime = 8.0 * (len(packet.payload) + FRAME_OVERHEAD_BYTES) / self.config.bandwidth_bps
        start = max(t, self._busy_until.get(sender, t))
        self._busy_until[sender] = start + airtime
        arrival = start + airtime + self.config.latency_s
        receivers = self._neighbours.get(sender, [])
        if packet.destination != BROADCAST:
            if packet.destination not in receivers:
                self.stats.dropped_range += 1
                return
            receivers = [packet.destination]
        if not receivers:
            return
        keep = self.rng.random(len(receivers)) >= self.config.loss
        # No loss drawn: the neighbour list itself (never changed; one is made anew
        # when the links change).
        kept = receivers if keep.all() else [r for r, ok in zip(receivers, keep.tolist())
                                             if ok]
        self.stats.dropped_loss += len(receivers) - len(kept)
        if kept:
            self._counter += 1
            heapq.heappush(self._queue, (arrival, self._counter, packet, kept))

    def deliver_grouped(self, t: float) -> list[tuple[Packet, list[int]]]:
        """Frames whose arrival time is <= t, in arrival order, each with its receivers."""
        out = []
        delivered = 0
        dead = self._dead
        while self._queue and self._queue[0][0] <= t:
            _, _, packet, receivers = heapq.heappop(self._queue)
            if dead:
                alive = [r for r in receivers if r not in dead]
                self.stats.dropped_dead += len(receivers) - len(alive)
                receivers = alive
            if receivers:
                out.append((packet, receivers))
                delivered += len(receivers)
        self.stats.delivered += delivered
        return out

    def deliver(self, t: float) -> list[tuple[int, Packet]]:
        """Frames whose arrival time is <= t, in arrival order, as (receiver, packet)."""
        return [(r, packet) for packet, receivers in self.deliver_grouped(t) for r in receivers]

    def toa_ranges(self, receiver: int, beacon_ids: Iterable[int], peers: bool = False
                   ) -> list[tuple[int, float, float]]:
        """(id, measured range, std) for the beacons that are direct neighbours, then,
        with ``peers``, for every other direct neighbour."""
        receiver = int(receiver)
        if receiver in self._dead or receiver not in self.index:
            return []
        near = self._neighbours.get(receiver, [])
        near_set = set(near)
        me = self.positions[self.index[receiver]]
        out = []
        std = self.config.range_noise_std
        heard = [b for b in beacon_ids if b in near_set]
        beacons = set(heard)
        if heard:
            # One draw of len(heard) normals is the same stream as one draw each.
            true = np.hypot(*(self.positions[[self.index[b] for b in heard]] - me).T)
            measured = np.maximum(true + self.rng.normal(0.0, std, len(heard)), 0.0)
            out += [(int(b), float(r), std) for b, r in zip(heard, measured)]
        others = [k for k in near if k not in beacons] if peers else []
        if others:
            rows = [self.index[k] for k in others]
            true = np.hypot(*(self.positions[rows] - me).T)
            measured = np.maximum(true + self._peer_rng.normal(0.0, std, len(rows)), 0.0)
            out += [(int(k), float(r), std) for k, r in zip(others, measured)]
        return out

@kernel(np.zeros((2, 2)), 1.0, np.zeros(2, dtype=np.bool_))
def _in_range(positions: np.ndarray, range_m: float, dead: np.ndarray) -> np.ndarray:
    """The (N, N) links by range alone: robots i != j at most ``range_m`` apart, neither
    dead (``RadioMedium.update_positions`` then cuts those without line of sight).

    Every pair, compiled: at 51 radios a k-d tree's pairs and the numpy that set them
    in a matrix took 55 us, the loops 2 us. The test is the tree's own (the squared
    distance against the squared range).
    """
    n = positions.shape[0]
    links = np.zeros((n, n), dtype=np.bool_)
    r2 = range_m * range_m
    for i in range(n):
        if dead[i]:
            continue
        for j in range(i + 1, n):
            if dead[j]:
                continue
            dx = positions[i, 0] - positions[j, 0]
            dy = positions[i, 1] - positions[j, 1]
            if dx * dx + dy * dy <= r2:
                links[i, j] = True
                links[j, i] = True
    return links


def apply_setting(medium: RadioMedium, name: str, value: float, t: float,
                  half_size: float) -> None:
    """Apply the run-time setting ``name`` of ``RUNTIME_SETTINGS`` at sim time ``t``: packet
    loss, radio range, or a wall sweeping the +/-``half_size`` workspace from ``t`` (speed
    0 removes it). ValueError for an unknown name."""
    if name == 'loss':
        medium.set_loss(value)
    elif name == 'radio_range_m':
        medium.set_range(value)
    elif name == 'radio_wall_speed_mps':
        medium.start_wall(SweepingWall(t, value, half_size) if value > 0 else None)
    else:
        raise ValueError(f'unknown medium setting {name!r}; use one of '
                         f'{", ".join(RUNTIME_SETTINGS)}')
