"""Run metrics of thesis chapter 4, from ground truth and the agents' beliefs.

Defined once here and assembled by ``trial_metrics``, which the headless evaluator, the
ROS launcher's report and every study call, so all report the same keys:

- ``total_displacement``: summed length of every robot's true trajectory (4.3.2).
- ``settling_time`` (eq. 4.1): the time from which every living robot is inside the
  formation shape and slower than 0.01 m/s for all later times. The run goes on for a
  hold window (``settle_hold_s``) after the condition holds; the time counts only if
  the condition then held to the end of the run and the window was complete, else
  ``settled`` is False and ``settling_time`` None. ``redepartures`` counts the times
  the condition broke after it had held (``SettleTracker``).
- ``displacement_lower_bound``: the minimum-sum assignment's summed shortest paths (in
  each type's free space) from the initial to the final positions, a bound no method
  can beat for the same final formation.
- ``least_settling_time``: the bottleneck (min-max) assignment's longest free-space
  path over the same cost matrices, divided by the speed limit ``V_MAX``: no method
  settles the same final formation sooner. ``settling_ratio`` is settling_time over it.
- ``min_separation_ratio`` and ``contacts``: the smallest distance between two living
  robots over the sum of their coverage radii, over every control (headless) or
  physics (pybullet) step, and the number of times a pair's coverage circles began to
  overlap (``SeparationTracker``); below 1 means the circles overlapped.
- ``epsilon_t`` / ``epsilon_g``: mesh irregularities of the final positions (eqs.
  3.104, 3.106) by ``swarm_mission.mesh_quality``.
- Beliefs (``belief_metrics``): localization error (max, 95th percentile, RMS) of the
  non-beacon agents after their first fix; agreement of the assignment consensus after
  the first complete round; duplicate goal claims over the whole run.
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
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching
from scipy.spatial import cKDTree
import shapely

from swarm_agent.costs import VisibilityGraph
from swarm_agent.free_space import grow_obstacles
from swarm_agent.setpoint import SetpointParams
from swarm_common.jit import kernel
from swarm_common.shapes import Shape
from swarm_mission.mesh_quality import epsilon_g, epsilon_t

SETTLE_SPEED = 0.01  # m/s, eq. 4.1
SETTLE_HOLD_S = 30.0  # s the settled condition must hold before a run may end
V_MAX = SetpointParams().v_max  # m/s, the robots' speed limit (thesis 3.2.4)
CHANGE_WINDOW_S = 20.0  # dispersion_during_change runs until this long after the last change
LAG_INSIDE = 0.95       # coverage_lags: share of the robots inside the new shape
SEPARATION_REACH = 1.5  # pairs closer than this many summed radii enter the minimum


def path_lengths(positions: np.ndarray) -> np.ndarray:
    """Length of each robot's polyline; ``positions`` is (T, N, 2)."""
    if len(positions) < 2:
        return np.zeros(positions.shape[1])
    return np.linalg.norm(np.diff(positions, axis=0), axis=2).sum(axis=0)


def inside_mask(shape: Shape, points: np.ndarray) -> np.ndarray:
    """Which points lie inside the formation region (vectorised)."""
    return shapely.contains_xy(shape.region, points[..., 0], points[..., 1])


def settled_now(shape: Shape, positions: np.ndarray, velocities: np.ndarray,
                alive: np.ndarray | None = None, speed: float = SETTLE_SPEED) -> bool:
    """Eq. 4.1's condition at one instant: every living robot inside and slow."""
    if alive is not None:
        positions, velocities = positions[alive], velocities[alive]
    v2 = velocities[:, 0] ** 2 + velocities[:, 1] ** 2
    if not np.all(v2 < speed * speed):    # the cheap test first: most steps end here
        return False
    return bool(np.all(inside_mask(shape, positions)))


class SettleTracker:
    """Eq. 4.1 with a hold window, fed the settled condition at every check.

    A streak starts when the condition turns true and ends when it turns false; a
    streak that ends after the robots had arrived (it began with a false-to-true
    transition) is a re-departure. A commanded change (a new shape, a removal, a
    fault) ends the streak without counting one: the robots are asked to move. The
    trial is settled when the last streak reached the end of the run and lasted at
    least ``hold_s``; ``settling_time`` is then when it began.
    """

    def __init__(self, hold_s: float = SETTLE_HOLD_S, t_start: float = 0.0) -> None:
        self.hold_s = float(hold_s)
        self.t_start = float(t_start)
        self.since: float | None = None     # start of the current streak
        self.redepartures = 0
        self._arrived = False               # the current streak began by arriving
        self._prev: bool | None = None      # the last condition; None after a change
        self._t_last = self.t_start

    def update(self, t: float, ok: bool) -> None:
        """The condition at time ``t``."""
        if ok:
            if self.since is None:
                self.since = t
                self._arrived = self._prev is False
        elif self.since is not None:
            self.redepartures += int(self._arrived)
            self.since = None
        self._prev = ok
        self._t_last = t

    def change(self, t: float) -> None:
        """A commanded change at ``t``: the current streak ends, not as a re-departure."""
        self.since = None
        self._prev = None
        self._t_last = t

    def held(self, t: float) -> bool:
        """The condition has held for the whole window up to ``t``."""
        return self.since is not None and t - self.since >= self.hold_s - 1e-9

    def result(self) -> dict[str, object]:
        """``settled``, ``settling_time`` (None unless settled), ``redepartures``."""
        settled = self.held(self._t_last)
        return {'settled': settled,
                'settling_time': self.since - self.t_start if settled else None,
                'redepartures': self.redepartures, 'settle_hold_s': self.hold_s}


def settle_from_record(times: np.ndarray, positions: np.ndarray, velocities: np.ndarray,
                       shape: Shape, alive: np.ndarray | None = None,
                       hold_s: float = SETTLE_HOLD_S,
                       change_times: Sequence[float] = ()) -> dict[str, object]:
    """``SettleTracker.result`` replayed over a record's samples (T frames, N robots),
    for records whose run did not track the condition itself (camera tracks)."""
    tracker = SettleTracker(hold_s, t_start=float(times[0]) if len(times) else 0.0)
    changes = sorted(change_times)
    for k, t in enumerate(times):
        while changes and changes[0] <= t:
            tracker.change(changes.pop(0))
        tracker.update(float(t), settled_now(shape, positions[k], velocities[k],
                                             None if alive is None else alive[k]))
    return tracker.result()


class SeparationTracker:
    """Closest approach of coverage circles and contacts, fed every simulation step.

    ``update`` takes the positions (N, 2), coverage radii (N,) and alive mask (N,) of
    one step. Pairs closer than ``SEPARATION_REACH`` times the largest summed radii are
    measured; ``min_ratio`` is the smallest distance / (r_i + r_j)
    seen, ``contacts`` the number of times a pair's circles began to overlap (a pair
    that stays overlapped counts once). ``take_interval_min`` returns the minimum since
    its last call, so a 2 Hz record can carry the minimum of the steps between samples.
    """

    def __init__(self) -> None:
        self.min_ratio = math.inf
        self.contacts = 0
        self.steps = 0
        self._interval_min = math.inf
        self._overlapping = np.zeros(0, dtype=np.int64)   # pair keys i * N + j, i < j
        self._n = 0

    def update(self, positions: np.ndarray, radii: np.ndarray,
               alive: np.ndarray | None = None) -> None:
        """Measure one step."""
        self.steps += 1
        n = self._n = len(positions)
        live = np.ones(n, dtype=bool) if alive is None else np.asarray(alive, dtype=bool)
        reach = 2.0 * float(radii[live].max()) * SEPARATION_REACH if live.any() else 0.0
        low, over = _separation(np.asarray(positions, dtype=float),
                                np.asarray(radii, dtype=float), live, reach)
        self.min_ratio = min(self.min_ratio, low)
        self._interval_min = min(self._interval_min, low)
        if len(over):
            self.contacts += int(np.count_nonzero(~np.isin(over, self._overlapping)))
        self._overlapping = over

    def overlapping_pairs(self) -> list[tuple[int, int]]:
        """The (i, j) index pairs, i < j, whose circles overlapped at the last update."""
        n = max(self._n, 1)
        return [(int(k) // n, int(k) % n) for k in self._overlapping]

    def take_interval_min(self) -> float:
        """The smallest ratio since the last call (inf: no pair within reach)."""
        low, self._interval_min = self._interval_min, math.inf
        return low

    def result(self) -> dict[str, object]:
        """``min_separation_ratio`` (inf: no pair ever within reach), ``contacts``."""
        return {'min_separation_ratio': self.min_ratio, 'contacts': self.contacts,
                'separation_steps': self.steps}


@kernel(np.zeros((2, 2)), np.ones(2), np.ones(2, dtype=np.bool_), 1.0)
def _separation(positions: np.ndarray, radii: np.ndarray, alive: np.ndarray,
                reach: float) -> tuple[float, np.ndarray]:
    """Over the pairs i < j of living robots at most ``reach`` apart: the smallest
    distance / (r_i + r_j) (inf: no such pair) and the pairs below 1 as keys i * N + j,
    in order (``SeparationTracker.update``).

    Every pair, compiled: 1,225 pairs of 50 robots cost less than building a k-d tree to
    find the few within reach (a tree query and the numpy around it took 36 us a step).
    """
    n = positions.shape[0]
    reach2 = reach * reach
    low = np.inf
    over = np.empty(n * (n - 1) // 2, dtype=np.int64)
    count = 0
    for i in range(n):
        if not alive[i]:
            continue
        for j in range(i + 1, n):
            if not alive[j]:
                continue
            dx = positions[i, 0] - positions[j, 0]
            dy = positions[i, 1] - positions[j, 1]
            d2 = dx * dx + dy * dy
            if d2 <= reach2:
                ratio = np.sqrt(d2) / (radii[i] + radii[j])
                if ratio < low:
                    low = ratio
                if ratio < 1.0:
                    over[count] = i * n + j
                    count += 1
    return low, over[:count].copy()


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


def free_space_costs(initial: np.ndarray, final: np.ndarray, types: np.ndarray,
                     shape: Shape, radii: Mapping[int, float]) -> list[np.ndarray]:
    """Per robot type (ascending), the matrix of free-space shortest-path lengths from
    each initial to each final position of that type."""
    types = np.asarray(types)
    costs = []
    for t in np.unique(types):
        idx = np.flatnonzero(types == t)
        graph = VisibilityGraph(grow_obstacles(list(shape.obstacles), radii[int(t)]))
        cost = graph.cost_matrix(initial[idx], final[idx])
        # A robot pressed against an obstacle sits inside its grown copy and has no
        # free-space path; the straight line still bounds its travel from below.
        straight = np.linalg.norm(initial[idx][:, None, :] - final[idx][None, :, :], axis=2)
        costs.append(np.where(np.isfinite(cost), cost, straight))
    return costs


def displacement_lower_bound(initial: np.ndarray, final: np.ndarray, types: np.ndarray,
                             shape: Shape, radii: Mapping[int, float]) -> float:
    """Optimal assignment of initial to final positions per type, by free-space paths."""
    return float(optimal_assigned_paths(initial, final, types, shape, radii).sum())


def optimal_assigned_paths(initial: np.ndarray, final: np.ndarray, types: np.ndarray,
                           shape: Shape, radii: Mapping[int, float],
                           costs: Sequence[np.ndarray] | None = None) -> np.ndarray:
    """The path length of every robot in the minimum-sum assignment of initial to final
    positions per type (sum: ``displacement_lower_bound``)."""
    if costs is None:
        costs = free_space_costs(initial, final, types, shape, radii)
    paths = []
    for cost in costs:
        rows, cols = linear_sum_assignment(cost)
        paths.append(cost[rows, cols])
    return np.concatenate(paths) if paths else np.zeros(0)


def bottleneck_value(cost: np.ndarray) -> float:
    """The bottleneck assignment's value: min over perfect matchings of the largest cost.

    Hand-written because scipy has no bottleneck linear assignment: a binary search over
    the sorted distinct costs for the smallest threshold whose graph of edges with cost
    <= threshold still has a perfect matching (``maximum_bipartite_matching``).
    ``cost`` is square (n, n) and finite; 0 for n = 0.
    """
    cost = np.asarray(cost, dtype=float)
    n = len(cost)
    if n == 0:
        return 0.0
    values = np.unique(cost)
    lo, hi = 0, len(values) - 1          # values[hi] (the largest cost) is always feasible
    while lo < hi:
        mid = (lo + hi) // 2
        matching = maximum_bipartite_matching(csr_matrix(cost <= values[mid]),
                                              perm_type='column')
        if np.all(matching >= 0):
            hi = mid
        else:
            lo = mid + 1
    return float(values[lo])


def least_settling_time(initial: np.ndarray, final: np.ndarray, types: np.ndarray,
                        shape: Shape, radii: Mapping[int, float],
                        costs: Sequence[np.ndarray] | None = None,
                        v_max: float = V_MAX) -> float:
    """Longest path of the bottleneck assignment per type (the largest over the types),
    at the speed limit: a robot bound for the far end of that path cannot settle sooner,
    whatever final position of its type it is given."""
    if costs is None:
        costs = free_space_costs(initial, final, types, shape, radii)
    longest = max((bottleneck_value(c) for c in costs), default=0.0)
    return longest / v_max


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


def trial_metrics(record: Mapping[str, np.ndarray], types: Sequence[int],
                  is_beacon: Sequence[bool], shape: Shape, radii: Mapping[int, float], *,
                  settling: Mapping[str, object] | None = None,
                  separation: Mapping[str, object] | None = None,
                  settle_hold_s: float = SETTLE_HOLD_S,
                  shapes: Sequence[tuple[float, Shape]] = ()) -> dict[str, object]:
    """Every per-trial metric of the module docstring, from a run's record.

    ``record`` holds ``times`` (T,), ``positions``/``velocities``/``estimates`` (T, N, 2),
    ``alive``/``modes``/``goal_ids``/``digests`` (T, N) and optionally ``rounds`` and
    ``localized`` (T, N). ``shape`` is the shape in force at the end; ``shapes`` the
    (time applied, Shape) of the run in order, for the shape-change metrics.
    ``settling`` is the run's ``SettleTracker.result()`` (without it the record's
    samples are replayed with ``settle_hold_s``); ``separation`` its
    ``SeparationTracker.result()`` (without it the separation keys are None: the
    record's samples would miss robots passing each other between them).
    """
    types = np.asarray(types)
    times = np.asarray(record['times'], dtype=float)
    positions = np.nan_to_num(np.asarray(record['positions'], dtype=float), nan=0.0)
    velocities = np.nan_to_num(np.asarray(record['velocities'], dtype=float), nan=0.0)
    alive = np.asarray(record['alive'], dtype=bool)
    alive_now = alive[-1]
    initial, final = positions[0][alive_now], positions[-1][alive_now]
    costs = free_space_costs(initial, final, types[alive_now], shape, radii)
    optimal = optimal_assigned_paths(initial, final, types[alive_now], shape, radii, costs)
    least = least_settling_time(initial, final, types[alive_now], shape, radii, costs)
    if settling is None:
        settling = settle_from_record(times, positions, velocities, shape, alive,
                                      settle_hold_s, [t for t, _ in shapes[1:]])
    settle = settling['settling_time']
    metrics: dict[str, object] = {
        'total_displacement': float(path_lengths(positions).sum()),
        'displacement_lower_bound': float(optimal.sum()),
        'least_settling_time': least,
        **settling,
        'settling_ratio': (float(settle) / least if settle is not None and least > 0
                           else None),
        'min_separation_ratio': None, 'contacts': None,
        **(separation or {}),
        'fraction_inside': float(inside_mask(shape, final).mean()) if len(final) else 0.0,
        'duration': float(times[-1] - times[0]),
    }
    metrics.update(mesh_metrics(final, shape))
    metrics.update(belief_metrics(record, types, is_beacon))
    metrics.update(change_metrics(times, positions, alive, shapes))
    return metrics


def agreement_by_sample(alive: np.ndarray, digests: np.ndarray,
                        types: Sequence[int]) -> np.ndarray:
    """Per record sample (T,), the share of living agents, any mode, whose assignment
    digest is their type's most common one (no digest: disagreeing); NaN before the
    first complete consensus round (the first sample at which every living agent holds a
    digest) and where nobody lives."""
    types = np.asarray(types)
    shares = np.full(len(alive), np.nan)
    started = False
    for k, (living, held) in enumerate(zip(alive, digests)):
        if not living.any():
            continue
        started = started or bool(np.all(held[living]))
        if not started:
            continue
        agreeing = 0
        for t in np.unique(types[living]):
            d = held[living & (types == t)]
            d = d[d != 0]
            if len(d):
                agreeing += int(np.unique(d, return_counts=True)[1].max())
        shares[k] = agreeing / int(living.sum())
    return shares


def _claims_beyond_first(goal_ids: np.ndarray) -> int:
    """Goal claims beyond the first per goal (goal id -1: no claim)."""
    claimed = goal_ids[goal_ids >= 0]
    return int(len(claimed) - len(np.unique(claimed)))


def belief_metrics(record: Mapping[str, np.ndarray], types: Sequence[int],
                   is_beacon: Sequence[bool]) -> dict[str, object]:
    """Localization error, assignment agreement and goal claims from a record of beliefs.

    Localization (``max_``, ``p95_``, ``rms_localization_error``): the distance from each
    non-beacon living agent's estimate to its true position, over every sample from its
    first fix on (``localized`` in the record, when it is recorded; else every sample).

    Agreement: agents of one type that used the same cost rows hold the same digest.
    From the first sample at which every living agent holds a digest (the first
    complete consensus round, ``first_consensus_time``) on, ``assignment_agreement`` is
    the mean over samples of the share of living agents, any mode, whose digest is their
    type's most common one; an agent with no digest disagrees. With ``rounds`` (the
    consensus round of each digest; the ROS monitor records them), ``round_agreement``
    is the share of agents, over every (type, round), whose digest is the round's most
    common one: the same question without the observation lag of states sampled while
    a round closes.

    Goal claims: claims beyond the first per goal among living agents, at the peak
    sample (``duplicate_goal_claims_peak``), summed over time in goal-seconds
    (``_integral``) and at the last sample (``_final``).
    """
    types = np.asarray(types)
    is_beacon = np.asarray(is_beacon, dtype=bool)
    alive = np.asarray(record['alive'], dtype=bool)
    digests = np.asarray(record['digests'])
    goal_ids = np.asarray(record['goal_ids'])
    samples = len(alive)
    times = np.asarray(record['times'], dtype=float) if 'times' in record \
        else np.arange(samples, dtype=float)
    # Localization.
    err = np.linalg.norm(np.asarray(record['estimates'], dtype=float)
                         - np.asarray(record['positions'], dtype=float), axis=2)
    fixed = alive.copy()
    if 'localized' in record:
        fixed &= np.logical_or.accumulate(np.asarray(record['localized'], dtype=bool), axis=0)
    agents = ~is_beacon if (~is_beacon).any() else np.ones_like(is_beacon)
    errors = err[:, agents][fixed[:, agents] & np.isfinite(err[:, agents])]
    # Agreement after the first complete round.
    shares = agreement_by_sample(alive, digests, types)
    complete = np.flatnonzero(np.isfinite(shares))
    rounds: dict[tuple[int, int], dict[int, int]] = {}
    if 'rounds' in record:
        for k, rnd in enumerate(np.asarray(record['rounds'])):
            for i in np.flatnonzero(alive[k] & (digests[k] != 0)):
                rounds.setdefault((int(types[i]), int(rnd[i])), {})[int(i)] = int(digests[k][i])
    agreeing_rounds = sum(max(np.unique(list(d.values()), return_counts=True)[1])
                          for d in rounds.values())
    # Duplicate goal claims over the run; each sample weighs until the next one.
    duplicates = np.array([_claims_beyond_first(goal_ids[k][alive[k]])
                           for k in range(samples)])
    weights = np.diff(times, append=times[-1]) if samples else np.zeros(0)
    modes_now = np.asarray(record['modes'])[-1][alive[-1]]
    return {
        'max_localization_error': float(errors.max()) if len(errors) else float('nan'),
        'p95_localization_error': (float(np.percentile(errors, 95)) if len(errors)
                                   else float('nan')),
        'rms_localization_error': (float(np.sqrt(np.mean(errors ** 2))) if len(errors)
                                   else float('nan')),
        'first_consensus_time': float(times[complete[0]]) if len(complete) else None,
        'assignment_agreement': (float(np.mean(shares[complete])) if len(complete)
                                 else float('nan')),
        'round_agreement': (float(agreeing_rounds / sum(len(d) for d in rounds.values()))
                            if rounds else float('nan')),
        'duplicate_goal_claims_peak': int(duplicates.max()) if samples else 0,
        'duplicate_goal_claims_integral': float(np.dot(duplicates, weights)),
        'duplicate_goal_claims_final': int(duplicates[-1]) if samples else 0,
        'final_modes_normal': float(np.mean(modes_now == 0)) if len(modes_now) else 0.0,
    }
