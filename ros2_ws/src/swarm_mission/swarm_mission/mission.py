"""The mission planner: versioned shapes, shape sequences, partitioning and self-repair.

Pure logic shared by ``mission_node`` and the headless evaluator:

- ``set_shape`` validates and versions a shape and partitions it into typed goal
  states for the agents believed alive (bubble packing or randomized fractals;
  ``forces`` needs no partition, thesis 3.2.1.1). With bubble packing a changed shape is
  re-meshed incrementally from the previous goals (the background process of 4.3.4):
  every goal keeps its id, so the agents drive on to their moved goals without waiting
  for a new assignment. ``remesh='scratch'`` partitions every shape anew instead, with
  fresh ids, which the agents must re-assign (the latency the thesis describes).
- A sequence of ``SequenceStep`` switches shapes at given times (dynamic formations,
  4.3.4); ``morph_sequence`` builds the smooth changes of 4.3.4 from one shape.
- Given the fleet's beacons, every partition on which some placement of the beacons
  would leave a goal with fewer than three in radio reach marks beacon goals
  (``swarm_mission.beacon_goals``) so that each goal has three; a shape the beacons
  cannot serve so is refused with the number of beacons it needs.
- Agents report liveness (their state messages on ROS, or the brains in the
  evaluator); an agent silent for ``agent_timeout_s`` is declared lost and the shape is
  re-partitioned for the survivors (self-repair).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
import json
import logging
import math
from numbers import Real
import pathlib

import yaml

from swarm_common.goals import Goal, PartitionError
from swarm_common.shapes import load_shape, Shape, ShapeError
from swarm_mission.beacon_goals import (
    any_placement_serves,
    check_localizable,
    select_beacon_goals,
)
from swarm_mission.coverability import check_coverable
from swarm_mission.partition import METHODS, partition, PartitionResult

LOG = logging.getLogger(__name__)

REMESH = ('incremental', 'scratch')
MORPHS = ('move', 'rotate', 'grow')


@dataclass(frozen=True)
class SequenceStep:
    """Switch to ``shape`` at time ``time`` (seconds from the start of the run)."""

    time: float
    shape: Shape


def load_sequence(path: str | pathlib.Path, *, scale: float = 1.0) -> list[SequenceStep]:
    """Read a shape sequence file (YAML or JSON).

    Layout: ``{"sequence": [{"time": 0, "shape": "circle_314"}, {"time": 120,
    "shape": "path/to/shape.json"}, ...]}``; relative shape paths are resolved against
    the sequence file's folder. Raises ShapeError naming the bad entry.
    """
    path = pathlib.Path(path)
    try:
        text = path.read_text(encoding='utf-8')
    except OSError as exc:
        raise ShapeError(f'cannot read shape sequence {path}: {exc.strerror}') from exc
    try:
        data = json.loads(text) if path.suffix == '.json' else yaml.safe_load(text)
    except (ValueError, yaml.YAMLError) as exc:
        raise ShapeError(f'shape sequence {path} is not valid YAML/JSON: {exc}') from exc
    entries = data.get('sequence') if isinstance(data, dict) else None
    if not isinstance(entries, list) or not entries:
        raise ShapeError(f'shape sequence {path} needs a non-empty "sequence" list of '
                         '{time, shape} entries')
    steps = []
    for i, entry in enumerate(entries):
        try:
            t = float(entry['time'])
            spec = str(entry['shape'])
        except (KeyError, TypeError, ValueError):
            raise ShapeError(f'shape sequence {path} entry {i} needs a numeric "time" and '
                             'a "shape" name or path') from None
        candidate = path.parent / spec
        steps.append(SequenceStep(t, load_shape(str(candidate) if candidate.exists() else spec,
                                                scale=scale)))
    times = [s.time for s in steps]
    if times != sorted(times):
        raise ShapeError(f'shape sequence {path} times must increase, got {times}')
    return steps


def morph_sequence(shape: Shape, kind: str, amount: float | Sequence[float], *,
                   start: float, duration: float, steps: int) -> list[SequenceStep]:
    """A shape changing smoothly (4.3.4: "changed dynamically in a smooth fashion").

    ``steps`` shapes evenly spaced over ``duration`` seconds from ``start``; step k of n
    is the fraction k/n of the change: ``move`` translates the region by ``amount``
    metres along x, or by the vector (dx, dy) when ``amount`` is a pair, ``rotate`` turns
    it by ``amount`` degrees about its area centroid, ``grow`` scales it by
    ``1 + amount`` about that centroid. Workspace obstacles stay where they are. Raises
    ShapeError naming the bad argument.
    """
    from shapely import affinity

    if kind not in MORPHS:
        raise ShapeError(f'unknown shape change {kind!r}; use one of {", ".join(MORPHS)}')
    if not (isinstance(steps, int) and steps >= 1):
        raise ShapeError(f'a shape change needs steps >= 1, got {steps!r}')
    if not (math.isfinite(start) and math.isfinite(duration) and duration > 0):
        raise ShapeError(f'a shape change needs a finite start and a duration > 0 s, got '
                         f'start {start!r}, duration {duration!r}')
    values = (amount,) if isinstance(amount, Real) else tuple(amount)
    if kind == 'move' and len(values) == 1:
        values = (values[0], 0.0)
    if (len(values) != (2 if kind == 'move' else 1)
            or not all(math.isfinite(v) for v in values)
            or (kind == 'grow' and values[0] <= -1.0)):
        what = {'move': 'one or two finite numbers (m along x, or dx,dy)',
                'rotate': 'a finite number of degrees',
                'grow': 'a finite number above -1 (a scale of 1 + amount)'}[kind]
        raise ShapeError(f'{kind} amount must be {what}, got {amount!r}')
    about = tuple(shape.centroid)
    sequence = []
    for k in range(1, steps + 1):
        f = k / steps
        if kind == 'move':
            region = affinity.translate(shape.region, values[0] * f, values[1] * f)
        elif kind == 'rotate':
            region = affinity.rotate(shape.region, values[0] * f, origin=about)
        else:
            scale = 1.0 + values[0] * f
            region = affinity.scale(shape.region, scale, scale, origin=about)
        sequence.append(SequenceStep(start + duration * (k - 1) / steps,
                                     Shape(shape.name, region, shape.obstacles)))
    return sequence


def parse_morph(spec: str, shape: Shape) -> list[SequenceStep]:
    """``morph_sequence`` from ``KIND:AMOUNT@START+DURATION[/STEPS]`` (e.g.
    ``move:15@150+60``: 15 m along x from 150 s over 60 s; ``move:10,-5@...`` moves by
    (10, -5) m). STEPS defaults to one shape every 2 s, the consensus period. Raises
    ShapeError naming the spec."""
    try:
        kind, rest = spec.split(':', 1)
        amount, rest = rest.split('@', 1)
        start, rest = rest.split('+', 1)
        duration, _, steps = rest.partition('/')
        start_s, duration_s = float(start), float(duration)
        n = int(steps) if steps else max(1, round(duration_s / 2.0))
        return morph_sequence(shape, kind, [float(a) for a in amount.split(',')],
                              start=start_s, duration=duration_s, steps=n)
    except ValueError as exc:
        if isinstance(exc, ShapeError):
            raise ShapeError(f'shape change {spec!r}: {exc}') from None
        raise ShapeError(f'bad shape change {spec!r}; write KIND:AMOUNT@START+DURATION'
                         f'[/STEPS] with KIND one of {", ".join(MORPHS)}, e.g. '
                         'move:15@150+60') from None


@dataclass
class MissionConfig:
    """Mission parameters (YAML defaults in swarm_mission/config/mission.yaml)."""

    method: str = 'bubble'
    seed: int = 0
    agent_timeout_s: float = 6.0     # silence after which an agent is declared lost
    repair: bool = True              # re-partition for the survivors when agents are lost
    # The shape is partitioned shrunk by this band (m): a robot parks up to ~1 m off its
    # goal (0.3 m hold radius + localization error, RMS ~0.5 m), and the outer goals of
    # bubble packing lie only the largest coverage radius inside the contour.
    formation_margin: float = 0.6
    remesh: str = 'incremental'      # bubble packing on a changed shape: see REMESH
    radio_range_m: float = 25.0      # thesis 4.1 (swarm_sim MediumConfig.range_m): the
    #                                  reach of beacons that beacon goals are chosen for

    def __post_init__(self) -> None:
        if self.method not in (*METHODS, 'forces'):
            raise ShapeError(f'unknown formation method {self.method!r}; use one of '
                             f'{", ".join((*METHODS, "forces"))} (mission method)')
        if not (math.isfinite(self.radio_range_m) and self.radio_range_m > 0.0):
            raise ShapeError(f'radio_range_m must be a finite number > 0 m, got '
                             f'{self.radio_range_m!r} (mission radio_range_m)')
        if self.remesh not in REMESH:
            raise ShapeError(f'remesh must be one of {", ".join(REMESH)}, got '
                             f'{self.remesh!r} (mission remesh)')
        if not (math.isfinite(self.formation_margin) and self.formation_margin >= 0.0):
            raise ShapeError(f'formation_margin must be a finite number >= 0 m, got '
                             f'{self.formation_margin!r} (mission formation_margin_m)')


@dataclass
class Mission:
    """Versioned shape and goals for a swarm of known composition."""

    config: MissionConfig
    agent_types: dict[int, int]              # agent id -> robot type
    radii: dict[int, float]                  # robot type -> coverage radius
    beacons: set[int] | None = None          # ids of the position beacons (None: unknown,
    #                                          goals are then not marked for beacons)
    shape: Shape | None = None
    shape_version: int = 0
    goals: list[Goal] = field(default_factory=list)
    goal_version: int = 0
    last_result: PartitionResult | None = None
    alive: set[int] = field(default_factory=set)
    lost: set[int] = field(default_factory=set)
    _last_seen: dict[int, float] = field(default_factory=dict)
    _lost_at: dict[int, float] = field(default_factory=dict)
    events: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.alive = set(self.agent_types)

    def type_counts(self) -> dict[int, int]:
        """Composition of the agents believed alive."""
        counts: dict[int, int] = {}
        for agent in sorted(self.alive):
            counts[self.agent_types[agent]] = counts.get(self.agent_types[agent], 0) + 1
        return counts

    def beacon_counts(self) -> dict[int, int]:
        """Robot type -> beacons believed alive (empty when the beacons are unknown)."""
        counts: dict[int, int] = {}
        for agent in sorted(self.alive & (self.beacons or set())):
            counts[self.agent_types[agent]] = counts.get(self.agent_types[agent], 0) + 1
        return counts

    def set_shape(self, shape: Shape) -> bool:
        """Adopt a new shape version and partition it; False if partitioning failed.

        A shape the living swarm cannot cover (too small for its coverage discs, walled
        off by obstacles, a neck narrower than a robot) raises ShapeError naming the
        reason and is not adopted (``coverability.check_coverable``); so is, raising
        PartitionError, a shape that cannot be partitioned or whose goals the fleet's
        beacons cannot all serve (``beacon_goals.check_localizable``).
        """
        check_coverable(shape, self.type_counts(), self.radii)
        before = (self.shape, self.shape_version)
        self.shape = shape
        self.shape_version += 1
        try:
            return self.repartition(reason=f'shape {shape.name} (version '
                                           f'{self.shape_version})', strict=True)
        except (PartitionError, ShapeError):
            self.shape, self.shape_version = before
            raise

    def repartition(self, reason: str, strict: bool = False) -> bool:
        """Partition the current shape for the living agents and bump the goal version.

        With the fleet's beacons known, beacon goals are marked; a goal left with fewer
        than three beacons in reach raises PartitionError when ``strict`` (a new shape)
        and is logged otherwise (self-repair keeps the survivors going).
        """
        if self.shape is None:
            return False
        if self.config.method == 'forces':
            self.goals = []
            self.goal_version += 1
            self.events.append(f'goals v{self.goal_version}: none (forces) for {reason}')
            return True
        previous = self.goals if (self.config.method == 'bubble' and self.goals
                                  and self.config.remesh == 'incremental') else None
        result = partition(self.shape, self.type_counts(), self.radii, self.config.method,
                           seed=self.config.seed, previous=previous,
                           margin=self.config.formation_margin)
        if result.margin < self.config.formation_margin:
            LOG.warning('shape %s partitioned without its %.2f m margin (shrunk, it splits, '
                        'vanishes or is too small for the swarm)', self.shape.name,
                        self.config.formation_margin)
        goals = self._mark_beacon_goals(list(result.goals), strict)
        self.last_result = result
        self.goals = goals
        self.goal_version += 1
        self.events.append(
            f'goals v{self.goal_version}: {len(self.goals)} {self.config.method} goals for '
            f'{reason} in {result.seconds:.2f} s')
        LOG.info(self.events[-1])
        return True

    def _mark_beacon_goals(self, goals: list[Goal], strict: bool) -> list[Goal]:
        """``goals`` with beacon goals marked for the living beacons; as they are when the
        beacons are unknown or every placement of them serves every goal."""
        if self.beacons is None or not goals:
            return goals
        range_m = self.config.radio_range_m
        if any_placement_serves(goals, self.beacon_counts(), range_m, self.shape.obstacles):
            return goals
        plan = select_beacon_goals(goals, self.beacon_counts(), range_m, self.shape.obstacles,
                                   prefer={g.id for g in self.goals if g.beacon})
        if plan.uncovered:
            if strict:
                check_localizable(plan, self.shape.name, range_m, self.shape.obstacles)
            self.events.append(f'goals {list(plan.uncovered)} have fewer than '
                               f'{plan.need} beacons in radio reach')
            LOG.warning(self.events[-1])
        return plan.goals

    def agent_seen(self, agent_id: int, t: float) -> None:
        """Liveness report of one agent at time ``t``."""
        if agent_id in self.agent_types:
            self._last_seen[agent_id] = t

    def check_liveness(self, t: float) -> list[int]:
        """Declare agents silent for too long lost, and take back lost agents heard again
        since (an agent out of the mesh behind an obstacle is alive); re-partition if
        either happened. Returns the newly lost agents."""
        newly_lost = [a for a in sorted(self.alive)
                      if a in self._last_seen
                      and t - self._last_seen[a] > self.config.agent_timeout_s]
        rejoined = [a for a in sorted(self.lost)
                    if self._last_seen.get(a, -math.inf) > self._lost_at.get(a, math.inf)]
        if not newly_lost and not rejoined:
            return []
        reasons = []
        if newly_lost:
            self.alive -= set(newly_lost)
            self.lost |= set(newly_lost)
            self._lost_at.update({a: t for a in newly_lost})
            self.events.append(f't={t:.1f} s: agents {newly_lost} lost')
            LOG.warning(self.events[-1])
            reasons.append(f'losing {newly_lost}')
        if rejoined:
            self.alive |= set(rejoined)
            self.lost -= set(rejoined)
            self.events.append(f't={t:.1f} s: agents {rejoined} heard again')
            LOG.warning(self.events[-1])
            reasons.append(f'hearing {rejoined} again')
        if self.config.repair and self.alive:
            self.repartition(reason='self-repair after ' + ' and '.join(reasons))
        return newly_lost

    def resume(self, shape: Shape | None, shape_version: int, goals: Sequence[Goal],
               goal_version: int, lost: Iterable[int], t: float) -> None:
        """Take up a restarted mission's saved shape, goals, versions and lost agents at
        time ``t`` (``swarm_mission.mission_state``), without partitioning again. A lost
        agent heard after ``t`` rejoins as in ``check_liveness``."""
        self.shape, self.shape_version = shape, shape_version
        self.goals, self.goal_version = list(goals), goal_version
        self.lost = {a for a in lost if a in self.agent_types}
        self.alive = set(self.agent_types) - self.lost
        self._lost_at = {a: t for a in self.lost}
        self.events.append(f't={t:.1f} s: resumed shape '
                           f'{shape.name if shape else None} v{shape_version}, goals '
                           f'v{goal_version}, lost {sorted(self.lost)}')
