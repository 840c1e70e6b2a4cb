"""One entry point for shape partitioning into typed goal states (thesis 3.2.2.1).

``partition(shape, type_counts, radii, method)`` dispatches to bubble packing
(Algorithm 1 + meshing, :mod:`swarm_mission.bubble_packing`; with ``previous`` goals
it re-meshes a changed shape from them, the background process of 4.3.4) or to
randomized fractals (Algorithm 2, :mod:`swarm_mission.fractals`), and measures the
result (eqs. 3.104, 3.106 by :mod:`swarm_mission.mesh_quality`).

The result is deterministic for a given seed: the only randomness is a
``numpy.random.Generator(PCG64(seed))`` and no clock enters the computation (the
elapsed time is only reported), so every agent computes the same partition.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
import logging
import math
import pathlib
import time

import numpy as np
import yaml

from swarm_common.goals import Goal, PartitionError
from swarm_common.paths import package_file
from swarm_common.shapes import Shape, ShapeError
from swarm_mission.bubble_packing import bubble_pack, BubbleConfig
from swarm_mission.fractals import FractalConfig, randomized_fractals
from swarm_mission.mesh_quality import irregularities

LOG = logging.getLogger(__name__)
METHODS = ('bubble', 'fractal')
DEFAULT_CONFIG = package_file('swarm_mission', 'config/partition.yaml')

__all__ = ['METHODS', 'PartitionConfig', 'PartitionError', 'PartitionResult',
           'load_partition_config', 'partition']


@dataclass
class PartitionConfig:
    """Parameters of both methods (defaults = config/partition.yaml)."""

    bubble: BubbleConfig = field(default_factory=BubbleConfig)
    fractal: FractalConfig = field(default_factory=FractalConfig)


def load_partition_config(path: str | pathlib.Path | None = None) -> PartitionConfig:
    """Read ``config/partition.yaml`` (or ``path``); unknown keys raise PartitionError."""
    path = pathlib.Path(path) if path else DEFAULT_CONFIG
    try:
        data = yaml.safe_load(path.read_text(encoding='utf-8')) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise PartitionError(f'cannot read partition config {path}: {exc}') from None
    parts = {}
    for key, cls in (('bubble', BubbleConfig), ('fractal', FractalConfig)):
        values = data.get(key) or {}
        known = {f.name for f in fields(cls)}
        unknown = set(values) - known
        if unknown:
            raise PartitionError(f'{path}: unknown {key} parameters {sorted(unknown)}; '
                                 f'known: {sorted(known)}')
        parts[key] = cls(**values)
    return PartitionConfig(**parts)


@dataclass
class PartitionResult:
    """Goals and how they were obtained; irregularities by both definitions."""

    goals: list[Goal]
    method: str
    iterations: int
    converged: bool
    seconds: float
    epsilon_t: float
    epsilon_g: float
    epsilon_t_with_boundary: float = float('nan')
    epsilon_g_with_boundary: float = float('nan')
    spacing: float = float('nan')
    seed: int = 0
    margin: float = 0.0        # m the shape was shrunk by before partitioning (``margin``)

    def metrics(self) -> dict:
        """The ``metrics.json`` content."""
        return {'method': self.method, 'agents': len(self.goals),
                'iterations': self.iterations, 'converged': self.converged,
                'seconds': self.seconds, 'epsilon_t': self.epsilon_t,
                'epsilon_g': self.epsilon_g,
                'epsilon_t_with_boundary': self.epsilon_t_with_boundary,
                'epsilon_g_with_boundary': self.epsilon_g_with_boundary,
                'spacing': self.spacing, 'seed': self.seed, 'margin': self.margin}


def _check_swarm(type_counts: Mapping[int, int], radii: Mapping[int, float]) -> list[int]:
    """Per-bubble types in type order; validates counts and radii."""
    types: list[int] = []
    if not type_counts:
        raise PartitionError('type_counts is empty; give e.g. {1: 20, 2: 20, 3: 10}')
    for t in sorted(type_counts):
        count = type_counts[t]
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
            raise PartitionError(f'agent count of type {t} must be a non-negative integer, '
                                 f'got {count!r}')
        if count and t not in radii:
            raise PartitionError(f'no coverage radius for robot type {t}; radii has types '
                                 f'{sorted(radii)}')
        if count:
            r = radii[t]
            if not (isinstance(r, (int, float, np.floating)) and math.isfinite(r) and r > 0):
                raise PartitionError(f'coverage radius of type {t} must be positive and '
                                     f'finite, got {r!r}')
        types.extend([int(t)] * int(count))
    if not types:
        raise PartitionError(f'the swarm has no agents ({dict(type_counts)}); give at least '
                             'one agent')
    return types


def _previous_start(previous: Sequence[Goal], types: list[int]) -> tuple[np.ndarray,
                                                                         np.ndarray,
                                                                         list[int]]:
    """Start positions from previous goals of matching type (incremental re-meshing).

    Bubble k of type t takes the k-th previous goal of type t (by id); surplus previous
    goals are dropped, missing ones are placed by Algorithm 1. Returns (positions,
    mask of bubbles with a previous position, goal ids).
    """
    by_type: dict[int, list[Goal]] = {}
    for g in sorted(previous, key=lambda g: g.id):
        if math.isfinite(g.x) and math.isfinite(g.y):
            by_type.setdefault(int(g.type), []).append(g)
    start = np.zeros((len(types), 2))
    mask = np.zeros(len(types), dtype=bool)
    ids: list[int] = []
    used = {g.id for g in previous}
    next_id = max(used, default=-1) + 1
    taken: dict[int, int] = {}
    for k, t in enumerate(types):
        j = taken.get(t, 0)
        taken[t] = j + 1
        if j < len(by_type.get(t, [])):
            g = by_type[t][j]
            start[k] = (g.x, g.y)
            mask[k] = True
            ids.append(int(g.id))
        else:
            ids.append(next_id)
            next_id += 1
    return start, mask, ids


def partition(shape: Shape, type_counts: Mapping[int, int], radii: Mapping[int, float],
              method: str = 'bubble', *, seed: int = 0,
              previous: Sequence[Goal] | None = None,
              config: PartitionConfig | None = None,
              margin: float = 0.0) -> PartitionResult:
    """Partition ``shape`` into one goal per agent: ``type_counts`` {type: count}.

    ``radii`` maps robot type to coverage radius (Table 4.1). ``method`` is 'bubble'
    (Algorithm 1 + meshing; ``previous`` goals -> incremental re-mesh of a changed
    shape, 4.3.4) or 'fractal' (Algorithm 2). Deterministic for a given seed. Raises
    PartitionError for a bad method, swarm or a shape too small (saying by how much).

    ``margin`` > 0 partitions the shape shrunk by that many metres (``Shape.inset``): the
    running system's band for localization error, so that a robot parked off its goal
    stays inside (mission ``formation_margin_m``). When the shrunk shape splits, vanishes
    or is too small for the swarm, the shape itself is partitioned; ``result.margin``
    says which was used.
    """
    if method not in METHODS:
        raise PartitionError(f'unknown partition method {method!r}; use one of {METHODS}')
    if not isinstance(shape, Shape):
        raise PartitionError(f'shape must be a swarm_common.shapes.Shape, got '
                             f'{type(shape).__name__}')
    config = config or PartitionConfig()
    types = _check_swarm(type_counts, radii)
    if not (isinstance(margin, (int, float)) and math.isfinite(margin) and margin >= 0):
        raise PartitionError(f'margin must be a finite number >= 0 m, got {margin!r}')
    if margin > 0:
        # Method and swarm are valid: a failure here is the shrunk shape's.
        try:
            result = partition(shape.inset(margin), type_counts, radii, method, seed=seed,
                               previous=previous, config=config)
        except (PartitionError, ShapeError):
            pass   # partition the shape itself below; result.margin stays 0
        else:
            result.margin = float(margin)
            return result
    bubble_radii = np.array([float(radii[t]) for t in types])
    rng = np.random.Generator(np.random.PCG64(int(seed)))
    started = time.perf_counter()   # reported only; never used by the algorithms
    ids = list(range(len(types)))
    if method == 'bubble':
        start = mask = None
        if previous:
            start, mask, ids = _previous_start(previous, types)
        x, iterations, converged, spacing = bubble_pack(
            shape.region, bubble_radii, rng, config.bubble, previous=start, previous_mask=mask)
    else:
        x = randomized_fractals(shape.region, bubble_radii, rng, config.fractal)
        iterations, converged, spacing = len(types), True, float('nan')
    seconds = time.perf_counter() - started
    goals = [Goal(id=int(i), type=t, x=float(p[0]), y=float(p[1]), radius=float(r))
             for i, t, p, r in zip(ids, types, x, bubble_radii)]
    quality = irregularities(x, shape)
    LOG.info('%s partition of %s: %d goals, %d iterations, eps_t %.2f, eps_g %.3f, %.2f s',
             method, shape.name, len(goals), iterations, quality['epsilon_t'],
             quality['epsilon_g'], seconds)
    return PartitionResult(goals=goals, method=method, iterations=iterations,
                           converged=converged, seconds=seconds, spacing=spacing,
                           seed=int(seed), **quality)
