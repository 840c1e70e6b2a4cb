"""Run metrics of thesis chapter 4, from ground-truth trajectories.

Shared by the headless evaluator and the ROS launcher, so both report the same keys:

- ``total_displacement``: summed length of every robot's true trajectory (4.3.2).
- ``settling_time``: ``t_final - t_start`` where from ``t_final`` on every robot is inside
  the formation shape and slower than 0.01 m/s (eq. 4.1); ``None`` if never settled.
- ``epsilon_t`` / ``epsilon_g``: mesh irregularities of the final positions (eqs.
  3.104, 3.106) by ``swarm_mission.mesh_quality``.
- ``displacement_lower_bound``: the optimal assignment's summed shortest paths (in each
  type's free space) from the initial positions to the final positions, a bound no
  method can beat for the same final formation.
- ``longest_assigned_path``: the longest single path of that optimal assignment;
  divided by the 0.5 m/s speed limit it is the least time any method needs to settle.
- ``min_separation_ratio``: the smallest distance between two robots divided by the sum
  of their coverage radii over the run (below 1 means coverage circles overlapped).
- ``coverage_dispersion`` (for dynamic formations, 4.3.4): how well robots cover the
  shape in force at one instant, relative to an even spread. With shape changes,
  ``change_metrics`` adds ``coverage_lags`` (seconds after each change until 95 % of
  the robots are inside the new shape) and ``dispersion_during_change`` (the mean
  dispersion from the first change until ``CHANGE_WINDOW_S`` after the last).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import math

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree
import shapely

from swarm_agent.costs import VisibilityGraph
from swarm_agent.free_space import grow_obstacles
from swarm_mission.mesh_quality import epsilon_g, epsilon_t
from swarm_mission.shapes import Shape

SETTLE_SPEED = 0.01  # m/s, eq. 4.1
CHANGE_WINDOW_S = 20.0  # dispersion_during_change runs until this long after the last change
LAG_INSIDE = 0.95       # coverage_lags: share of the robots inside the new shape


def path_lengths(positions: np.ndarray) -> np.ndarray:
    """Length of each robot's polyline; ``positions`` is (T, N, 2)."""
    if len(positions) < 2:
        return np.zeros(positions.shape[1])
    return np.linalg.norm(np.diff(positions, axis=0), axis=2).sum(axis=0)


def inside_mask(shape: Shape, points: np.ndarray) -> np.ndarray:
    """Which points lie inside the formation region (vectorised)."""
    return shapely.contains_xy(shape.region, points[..., 0], points[..., 1])


def settling_time(times: np.ndarray, positions: np.ndarray, velocities: np.ndarray,
                  shape: Shape, alive: np.ndarray | None = None,
                  t_start: float = 0.0, speed: float = SETTLE_SPEED) -> float | None:
    """Eq. 4.1: first time from which all (alive) robots stay inside and slow; else None."""
    speeds = np.linalg.norm(velocities, axis=2)
    ok = inside_mask(shape, positions) & (speeds < speed)
    if alive is not None:
        ok |= ~alive
    all_ok = ok.all(axis=1)
    if not all_ok[-1]:
        return None
    bad = np.flatnonzero(~all_ok)
    first = 0 if len(bad) == 0 else bad[-1] + 1
    return float(times[first] - t_start)


def min_separation_ratio(positions: np.ndarray, radii: np.ndarray) -> float:
    """Smallest pairwise distance / (r_i + r_j) over all recorded frames."""
    best = math.inf
    max_r = float(np.max(radii))
    for frame in positions:
        tree = cKDTree(frame)
        pairs = tree.query_pairs(2.0 * max_r * 1.5, output_type='ndarray')
        if len(pairs) == 0:
            continue
        d = np.linalg.norm(frame[pairs[:, 0]] - frame[pairs[:, 1]], axis=1)
        ratio = d / (radii[pairs[:, 0]] + radii[pairs[:, 1]])
        best = min(best, float(ratio.min()))
    return best


# Mean distance from the points of a regular hexagon of area a to its centre, over sqrt(a):
# the least mean distance to the nearest of n robots over a region of area n a (the
# hexagonal lattice is the optimal covering of the plane; Fejes Toth).
HEXAGON_MEAN_DISTANCE = 0.3772


def coverage_dispersion(shape: Shape, points: np.ndarray, samples: int = 10_000) -> float:
    """Mean distance from the shape's area to the nearest robot, over the least possible.

    The coverage cost of locational optimisation (Cortes et al., IEEE TRA 2004) with a
    uniform density, evaluated on a grid of about ``samples`` points of the region and
    divided by ``HEXAGON_MEAN_DISTANCE * sqrt(area / n)``, its value for n robots on a
    hexagonal lattice filling the region. 1 is an even spread; robots bunched up, or left
    outside a shape that moved away from them, raise it. The thesis judges the response
    to a changing shape by how far the robots' coverage differs from it (Figs.
    4.37-4.39); this puts a number on that. ``points`` (n, 2); inf when n is 0.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    region = shape.region
    if len(points) == 0 or region.area <= 0.0:
        return math.inf
    step = math.sqrt(region.area / samples)
    x0, y0, x1, y1 = region.bounds
    gx, gy = np.meshgrid(np.arange(x0 + step / 2, x1, step), np.arange(y0 + step / 2, y1, step))
    grid = np.column_stack((gx.ravel(), gy.ravel()))
    grid = grid[shapely.contains_xy(region, grid[:, 0], grid[:, 1])]
    if len(grid) == 0:
        return math.inf
    distance, _ = cKDTree(points).query(grid)
    return float(distance.mean() / (HEXAGON_MEAN_DISTANCE * math.sqrt(region.area / len(points))))


def shape_response(times: np.ndarray, positions: np.ndarray, alive: np.ndarray,
                   shapes: Sequence[tuple[float, Shape]], start: float = -math.inf,
                   end: float = math.inf) -> dict[str, np.ndarray]:
    """Per recorded time, the share of living robots inside the shape in force
    (``inside``) and, for times in [start, end], its ``coverage_dispersion``
    (``dispersion``, NaN elsewhere: it costs a grid query per time). ``shapes`` are
    (time applied, Shape) in order; positions (T, N, 2), alive (T, N)."""
    switch_times = np.array([t for t, _ in shapes])
    inside = np.zeros(len(times))
    dispersion = np.full(len(times), np.nan)
    for k, t in enumerate(times):
        shape = shapes[max(0, int(np.searchsorted(switch_times, t + 1e-9)) - 1)][1]
        living = positions[k][alive[k]]
        inside[k] = float(inside_mask(shape, living).mean()) if len(living) else 0.0
        if start <= t <= end:
            dispersion[k] = coverage_dispersion(shape, living)
    return {'inside': inside, 'dispersion': dispersion}


def change_metrics(times: np.ndarray, positions: np.ndarray, alive: np.ndarray,
                   shapes: Sequence[tuple[float, Shape]]) -> dict[str, object]:
    """``coverage_lags`` and ``dispersion_during_change`` (module docstring) of a run
    whose shape changed; an empty dict if it never did."""
    switch_times = [t for t, _ in shapes]
    if len(switch_times) < 2:
        return {}
    first, last = switch_times[1], switch_times[-1] + CHANGE_WINDOW_S
    response = shape_response(times, positions, alive, shapes, start=first, end=last)
    lags: list[float | None] = []
    for i, begin in enumerate(switch_times[1:], start=1):
        until = switch_times[i + 1] if i + 1 < len(switch_times) else math.inf
        ok = np.flatnonzero((times >= begin) & (times < until)
                            & (response['inside'] >= LAG_INSIDE))
        lags.append(float(times[ok[0]] - begin) if len(ok) else None)
    window = response['dispersion'][(times >= first) & (times <= last)]
    return {'coverage_lags': lags,
            'dispersion_during_change': float(np.mean(window)) if len(window) else None}


def displacement_lower_bound(initial: np.ndarray, final: np.ndarray, types: np.ndarray,
                             shape: Shape, radii: Mapping[int, float]) -> float:
    """Optimal assignment of initial to final positions per type, by free-space paths."""
    return float(optimal_assigned_paths(initial, final, types, shape, radii).sum())


def optimal_assigned_paths(initial: np.ndarray, final: np.ndarray, types: np.ndarray,
                           shape: Shape, radii: Mapping[int, float]) -> np.ndarray:
    """The path length of every robot in the optimal assignment of initial to final
    positions per type (free-space shortest paths; sum: ``displacement_lower_bound``)."""
    paths = []
    for t in np.unique(types):
        idx = np.flatnonzero(types == t)
        graph = VisibilityGraph(grow_obstacles(list(shape.obstacles), radii[int(t)]))
        cost = graph.cost_matrix(initial[idx], final[idx])
        # A robot pressed against an obstacle sits inside its grown copy and has no
        # free-space path; the straight line still bounds its travel from below.
        straight = np.linalg.norm(initial[idx][:, None, :] - final[idx][None, :, :], axis=2)
        cost = np.where(np.isfinite(cost), cost, straight)
        rows, cols = linear_sum_assignment(cost)
        paths.append(cost[rows, cols])
    return np.concatenate(paths) if paths else np.zeros(0)


def mesh_metrics(points: np.ndarray, shape: Shape) -> dict[str, float]:
    """epsilon_t and epsilon_g of the final positions, both definitions (see mesh_quality)."""
    if len(points) < 4:
        return {'epsilon_t': float('nan'), 'epsilon_g': float('nan'),
                'epsilon_t_with_boundary': float('nan'),
                'epsilon_g_with_boundary': float('nan')}
    return {
        'epsilon_t': float(epsilon_t(points, shape)),
        'epsilon_g': float(epsilon_g(points, shape)),
        'epsilon_t_with_boundary': float(epsilon_t(points, shape, count_boundary=True)),
        'epsilon_g_with_boundary': float(epsilon_g(points, shape, count_boundary=True)),
    }


def run_metrics(times: np.ndarray, positions: np.ndarray, velocities: np.ndarray,
                types: Sequence[int], shape: Shape, radii: Mapping[int, float],
                alive: np.ndarray | None = None) -> dict[str, float | None]:
    """All per-trial metrics from a truth record (T frames, N robots)."""
    types = np.asarray(types)
    radius = np.array([radii[int(t)] for t in types])
    alive_now = np.ones(len(types), bool) if alive is None else alive[-1]
    final = positions[-1][alive_now]
    optimal = optimal_assigned_paths(positions[0][alive_now], final, types[alive_now], shape,
                                     radii)
    metrics: dict[str, float | None] = {
        'total_displacement': float(path_lengths(positions).sum()),
        'settling_time': settling_time(times, positions, velocities, shape, alive),
        'displacement_lower_bound': float(optimal.sum()),
        'longest_assigned_path': float(optimal.max()) if len(optimal) else float('nan'),
        'min_separation_ratio': min_separation_ratio(positions[:, alive_now],
                                                     radius[alive_now]),
        'fraction_inside': float(inside_mask(shape, final).mean()) if len(final) else 0.0,
        'duration': float(times[-1] - times[0]),
    }
    metrics.update(mesh_metrics(final, shape))
    return metrics


def _most_common(values: np.ndarray) -> int:
    """Most frequent value (smallest on ties)."""
    uniq, counts = np.unique(values, return_counts=True)
    return int(uniq[np.argmax(counts)])


def belief_metrics(record: Mapping[str, np.ndarray], types: np.ndarray,
                   is_beacon: np.ndarray) -> dict[str, float]:
    """Localization error and assignment agreement from a record of agent beliefs.

    ``record`` holds (T, N) arrays ``estimates`` (T, N, 2), ``positions``, ``alive``,
    ``modes``, ``digests`` and ``goal_ids``. Agents of one type that used the same cost
    rows hold the same digest; ``assignment_agreement`` is the mean share of assigned
    NORMAL agents whose digest is their type's most common one, sample by sample. With
    ``rounds`` (the consensus round of each digest; the ROS monitor records them),
    ``round_agreement`` is the share of agents, over every (type, round), whose digest
    is the round's most common one: the same question without the observation lag of
    states sampled while a round closes.
    """
    types = np.asarray(types)
    err = np.linalg.norm(record['estimates'] - record['positions'], axis=2)
    err = np.where(record['alive'], err, np.nan)
    loc = err[:, ~np.asarray(is_beacon)] if (~np.asarray(is_beacon)).any() else err
    agree = []
    for digests, alive, modes in zip(record['digests'], record['alive'], record['modes']):
        for t in np.unique(types):
            d = digests[alive & (modes == 0) & (digests != 0) & (types == t)]
            if len(d):
                agree.append(float(np.mean(d == _most_common(d))))
    rounds: dict[tuple[int, int], dict[int, int]] = {}
    if 'rounds' in record:
        for digests, alive, modes, rnd in zip(record['digests'], record['alive'],
                                              record['modes'], record['rounds']):
            for i in np.flatnonzero(alive & (modes == 0) & (digests != 0)):
                rounds.setdefault((int(types[i]), int(rnd[i])), {})[int(i)] = int(digests[i])
    agreeing = sum(max(np.unique(list(d.values()), return_counts=True)[1])
                   for d in rounds.values())
    final_goals = record['goal_ids'][-1][record['alive'][-1]]
    assigned = final_goals[final_goals >= 0]
    finite = np.isfinite(loc)
    return {
        'max_localization_error': float(np.nanmax(loc)) if finite.any() else float('nan'),
        'rms_localization_error': float(np.sqrt(np.nanmean(loc ** 2)))
        if finite.any() else float('nan'),
        'assignment_agreement': float(np.mean(agree)) if agree else float('nan'),
        'round_agreement': (float(agreeing / sum(len(d) for d in rounds.values()))
                            if rounds else float('nan')),
        'duplicate_goal_claims': int(len(assigned) - len(np.unique(assigned))),
        'final_modes_normal': float(np.mean(record['modes'][-1][record['alive'][-1]] == 0)),
    }
