"""Beacon goals: which goals the position beacons take so that every goal is localizable.

A robot without a position sensor localizes by trilateration against the position
beacons that are its direct neighbours (thesis 3.1.1): within radio range and line of
sight, and at least three of them, since fewer give no 2-D fix (3.1.1, n < 3) and the
robot turns LOST and then RETURN_HOME (3.1.3). The beacons are robots of the swarm and
take goals like every other robot, so where they park decides which goals can be held:
on a long shape, a goal far from three beacons is one its robot can never stay on.

``any_placement_serves`` tells whether beacon goals are needed at all: on a compact
shape every goal has three beacons in reach wherever they park, and the beacons are left
free to take the nearest goals. Otherwise ``select_beacon_goals`` marks, for each robot
type, exactly as many goals as the fleet has beacons of that type as *beacon goals*
(``Goal.beacon``); the assignment then gives beacon goals to beacons only
(``swarm_agent.costs.class_costs``). Every goal that is not a beacon goal needs ``need``
beacon goals within ``reach * range_m`` and line of sight (a beacon goal's own robot has
its GPS). The choice is a set multi-cover solved exactly as a small integer programme
(scipy ``milp``, HiGHS; see ``_solve``): least shortfall first, then the goals that were
beacon goals before (re-meshing a changing shape keeps the beacons where they are), then
the most goals with a spare beacon in reach. Range alone does not make a good fix:
beacons all on one side of a goal fix it badly across that direction (horizontal
dilution of precision, HDOP; the normal matrix U^T U of the range fix, cf. eq. 3.17).
Swaps of a beacon goal for another goal of its type that keep every goal covered and
lower the worst HDOP over the goals by more than ``HDOP_GAIN`` follow (a previous beacon
goal only while the worst HDOP exceeds ``HDOP_LIMIT``). ``check_localizable`` refuses a
plan that leaves a goal short, with one line naming the fewest beacons of any types that
would serve the shape's goals (``beacons_needed``, the same programme).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.spatial import cKDTree
import shapely
from shapely.geometry import Polygon

from swarm_common.goals import Goal, goal_positions, PartitionError

MIN_BEACONS = 3       # beacons a 2-D trilateration needs (thesis 3.1.1)
REACH = 0.9           # fraction of the radio range a goal's beacons may be away
SOLVER_TIME_LIMIT_S = 10.0
HDOP_GAIN = 0.05      # a geometry swap must lower the worst HDOP by this fraction
HDOP_LIMIT = 3.0      # a previous beacon goal is given up for geometry only above this


@dataclass(frozen=True)
class BeaconPlan:
    """Goals with their beacon flags set, and the goals still short of beacons.

    ``cover`` holds, per goal (in the order of ``goals``), the number of beacon goals
    within reach of it; ``uncovered`` the ids of the goals that are not beacon goals and
    have fewer than ``need`` of them.
    """

    goals: list[Goal]
    cover: np.ndarray
    uncovered: tuple[int, ...]
    need: int


def radio_links(points: np.ndarray, range_m: float,
                obstacles: Sequence[Polygon] = ()) -> np.ndarray:
    """(n, n) bool: pairs of ``points`` within ``range_m`` whose segment crosses no obstacle
    (the link rule of the radio medium, thesis 3.1.2); the diagonal is True."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    n = len(pts)
    links = np.eye(n, dtype=bool)
    if n < 2:
        return links
    pairs = cKDTree(pts).query_pairs(float(range_m), output_type='ndarray')
    if not len(pairs):
        return links
    solid = [o for o in obstacles if o is not None and not o.is_empty]
    if solid:
        lines = shapely.linestrings(np.stack([pts[pairs[:, 0]], pts[pairs[:, 1]]], axis=1))
        hit = shapely.STRtree(solid).query(lines, predicate='intersects')
        ok = np.ones(len(pairs), dtype=bool)
        ok[np.unique(hit[0])] = False
        pairs = pairs[ok]
    links[pairs[:, 0], pairs[:, 1]] = True
    links[pairs[:, 1], pairs[:, 0]] = True
    return links


def _solve(links: np.ndarray, need: int, types: np.ndarray, quota: Mapping[int, int] | None,
           prefer: np.ndarray) -> np.ndarray:
    """The beacon goals (bool mask) of the integer programme in the module docstring.

    Variables: x (goal is a beacon goal), y (goal has ``need + 1`` beacons in reach or is
    a beacon goal), s (beacons a goal lacks, continuous). Cover of goal j:
    ``sum_i L_ij x_i + need x_j + s_j >= need`` and ``sum_i L_ij x_i + (need + 1) x_j >=
    (need + 1) y_j``. With ``quota`` each type t has exactly ``quota[t]`` beacon goals and
    the objective is ``W sum s - P prefer.x - sum y`` (P > n, W > P beacons + n: shortfall
    first, then staying put, then spare cover); without it the objective is ``sum x`` under
    ``s = 0`` (the fewest beacons of any type).
    """
    n = len(types)
    cover = links.T.astype(float)
    eye = np.eye(n)
    zeros = np.zeros((n, n))
    if quota is None:
        c = np.r_[np.ones(n), np.zeros(n), np.zeros(n)]
        upper = np.r_[np.ones(n), np.zeros(n), np.zeros(n)]
    else:
        beacons = max(1, sum(quota.values()))
        keep = n + 1.0
        c = np.r_[-keep * prefer, -np.ones(n), np.full(n, keep * (beacons + 2))]
        upper = np.r_[np.ones(n), np.ones(n), np.full(n, float(need))]
    constraints = [
        LinearConstraint(np.hstack([cover + need * eye, zeros, eye]), lb=need),
        LinearConstraint(np.hstack([cover + (need + 1) * eye, -(need + 1) * eye, zeros]),
                         lb=0.0),
    ]
    if quota is not None:
        per_type = np.array([np.r_[types == t, np.zeros(2 * n)] for t in sorted(quota)],
                            dtype=float)
        counts = np.array([quota[t] for t in sorted(quota)], dtype=float)
        constraints.append(LinearConstraint(per_type, lb=counts, ub=counts))
    result = milp(c, constraints=constraints, bounds=Bounds(np.zeros(3 * n), upper),
                  integrality=np.r_[np.ones(2 * n), np.zeros(n)],
                  options={'time_limit': SOLVER_TIME_LIMIT_S})
    if result.x is None:
        raise PartitionError(f'the beacon goal selection found no solution in '
                             f'{SOLVER_TIME_LIMIT_S:g} s ({result.message}); use fewer goals')
    return np.round(result.x[:n]).astype(bool)


def hdop(points: np.ndarray, links: np.ndarray, chosen: np.ndarray) -> np.ndarray:
    """Horizontal dilution of precision of each goal's fix from the beacon goals in reach.

    ``sqrt(trace((U^T U)^-1))`` over the unit vectors U from the goal to those beacons
    (range error 1); inf with fewer than two directions, 0 for the beacon goals.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    d = pts[None, chosen, :] - pts[:, None, :]                  # (goal, beacon, 2)
    norm = np.linalg.norm(d, axis=2)
    use = links[:, chosen] & (norm > 1e-9)
    u = np.where(use[..., None], d / np.where(norm > 1e-9, norm, 1.0)[..., None], 0.0)
    gxx = np.sum(u[..., 0] ** 2, axis=1)
    gyy = np.sum(u[..., 1] ** 2, axis=1)
    gxy = np.sum(u[..., 0] * u[..., 1], axis=1)
    det = gxx * gyy - gxy ** 2
    with np.errstate(divide='ignore', invalid='ignore'):
        out = np.where(det > 1e-9 * np.maximum(gxx + gyy, 1e-12) ** 2,
                       np.sqrt((gxx + gyy) / det), np.inf)
    out[chosen] = 0.0
    return out


def _improve_geometry(points: np.ndarray, links: np.ndarray, chosen: np.ndarray,
                      types: np.ndarray, need: int, keep: np.ndarray) -> np.ndarray:
    """Best-improvement swaps (beacon goal for a goal of its type) that keep every covered
    goal covered and lower the worst HDOP by more than ``HDOP_GAIN``; a goal of ``keep``
    (a beacon goal before) is swapped out only while the worst HDOP exceeds
    ``HDOP_LIMIT``, so a changing shape does not shuffle the beacons."""
    chosen = chosen.copy()

    def score(mask: np.ndarray) -> tuple[int, float]:
        cover = links[mask].sum(axis=0)
        short = int(np.sum(~mask & (cover < need)))
        values = hdop(points, links, mask)[~mask & (cover >= need)]
        return short, float(values.max()) if len(values) else 0.0

    best = score(chosen)
    for _ in range(4 * int(chosen.sum()) + 1):
        move, value = None, best
        for b in np.flatnonzero(chosen & ~(keep & (best[1] <= HDOP_LIMIT))):
            for c in np.flatnonzero(~chosen & (types == types[b])):
                chosen[b], chosen[c] = False, True
                trial = score(chosen)
                chosen[b], chosen[c] = True, False
                if trial[0] <= best[0] and trial[1] < (1.0 - HDOP_GAIN) * value[1]:
                    move, value = (b, c), trial
        if move is None:
            break
        chosen[move[0]], chosen[move[1]] = False, True
        best = value
    return chosen


def any_placement_serves(goals: Sequence[Goal], beacons: Mapping[int, int], range_m: float,
                         obstacles: Sequence[Polygon] = (), *, need: int = MIN_BEACONS,
                         reach: float = REACH) -> bool:
    """True when every goal has ``need`` beacons in reach wherever the beacons park.

    The worst placement for goal j puts each type's beacons first on the goals of that
    type out of j's reach: j keeps ``sum_t max(0, b_t - out_t(j))`` of them. A goal whose
    type has as many beacons as goals is always a beacon goal itself. Then beacon goals
    are not needed (a compact shape: thesis circle_314, 20 m across).
    """
    goals = list(goals)
    if not goals:
        return True
    types = np.array([g.type for g in goals])
    links = radio_links(goal_positions(goals), reach * range_m, obstacles)
    for j in range(len(goals)):
        own = int(types[j])
        if beacons.get(own, 0) >= int(np.sum(types == own)):
            continue
        worst = 0
        for t in np.unique(types):
            out = int(np.sum((types == t) & ~links[j]))
            worst += max(0, int(beacons.get(int(t), 0)) - out)
        if worst < need:
            return False
    return True


def select_beacon_goals(goals: Sequence[Goal], beacons: Mapping[int, int], range_m: float,
                        obstacles: Sequence[Polygon] = (), *, need: int = MIN_BEACONS,
                        reach: float = REACH, prefer: Collection[int] = ()) -> BeaconPlan:
    """Mark ``beacons[t]`` goals of each type t as beacon goals (see the module docstring).

    ``beacons``: robot type -> number of beacons of that type (at most its goals);
    ``range_m``: the radio range, of which ``reach`` is used; ``obstacles``: what blocks
    line of sight; ``prefer``: ids of the goals that were beacon goals before.
    """
    goals = list(goals)
    if not goals:
        return BeaconPlan([], np.zeros(0, dtype=int), (), need)
    types = np.array([g.type for g in goals])
    links = radio_links(goal_positions(goals), reach * range_m, obstacles)
    quota = {int(t): int(beacons.get(int(t), 0)) for t in np.unique(types)}
    for t, count in quota.items():
        if not 0 <= count <= int(np.sum(types == t)):
            raise PartitionError(f'{count} beacons of type {t} but {int(np.sum(types == t))} '
                                 'goals of that type; give each type at most one beacon '
                                 'per robot')
    wanted = set(prefer)
    keep = np.array([g.id in wanted for g in goals])
    chosen = _solve(links, need, types, quota, keep.astype(float))
    chosen = _improve_geometry(goal_positions(goals), links, chosen, types, need, keep)
    cover = links[chosen].sum(axis=0)
    uncovered = tuple(g.id for g, c, b in zip(goals, cover, chosen) if not b and c < need)
    marked = [replace(g, beacon=bool(b)) for g, b in zip(goals, chosen)]
    return BeaconPlan(marked, cover, uncovered, need)


def beacons_needed(goals: Sequence[Goal], range_m: float, obstacles: Sequence[Polygon] = (),
                   *, need: int = MIN_BEACONS, reach: float = REACH) -> int:
    """The fewest beacons (of any types) that leave no goal short of ``need`` in reach."""
    goals = list(goals)
    if not goals:
        return 0
    types = np.array([g.type for g in goals])
    links = radio_links(goal_positions(goals), reach * range_m, obstacles)
    return int(_solve(links, need, types, None, np.zeros(len(goals))).sum())


def check_localizable(plan: BeaconPlan, shape_name: str, range_m: float,
                      obstacles: Sequence[Polygon] = (), *, reach: float = REACH) -> None:
    """PartitionError with one line when ``plan`` leaves a goal short of beacons:
    ``shape X needs at least K beacons for a R m radio; the fleet has B: use --beacons K``.
    """
    if not plan.uncovered:
        return
    fleet = sum(1 for g in plan.goals if g.beacon)
    k = max(beacons_needed(plan.goals, range_m, obstacles, need=plan.need, reach=reach),
            fleet + 1)
    raise PartitionError(
        f'shape {shape_name} needs at least {k} beacons for a {range_m:g} m radio; the fleet '
        f'has {fleet}: use --beacons {k} ({len(plan.uncovered)} goals would have fewer than '
        f'{plan.need} beacons within {reach * range_m:g} m)')
