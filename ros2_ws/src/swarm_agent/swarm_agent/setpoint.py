"""Velocity setpoint generator of the outer loop (thesis 3.2.4, Fig. 3.32) and the
collision-avoidance filter that every command passes through.

The setpoint points along the path to the goal (the next waypoint of the visibility
graph path) with a magnitude proportional to the remaining path length, saturated at
``v_max`` (0.5 m/s in the thesis).

Collision avoidance (beyond the thesis's repulsive terms, which act on neighbours'
broadcast estimates and let robots touch: ``avoid_collisions``) is a safety filter in
the sense of control barrier functions: for each neighbour j at distance d_j along the
unit vector u_j, with gap h_j = d_j - (r_i + r_j + buffer), the commanded velocity
must satisfy u_j . v <= (rate / 2) h_j, so a pair can close its gap at most at
``rate`` times the gap (each robot takes half) and never crosses h = 0 in continuous
time; a robot inside the buffer (h_j < 0) must back away at (rate / 2) |h_j|. A
parked robot (setpoint zero) therefore yields to one that comes too close. Ahead of
the filter, part of the speed towards a close neighbour is turned to the right
(``swerve``): two robots meeting head-on, or a robot behind a parked one, would
otherwise stop in front of each other for good.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarm_common.parameters import tunable


@dataclass
class SetpointParams:
    """Outer-loop and avoidance parameters (defaults of agent_node's parameters)."""

    gain: float = tunable(0.4, 'Setpoint speed per metre of remaining path, 1/s (3.2.4)',
                          low=1e-3, high=100.0, live=True)
    v_max: float = tunable(0.5, 'Setpoint speed limit, m/s (3.2.4)', low=1e-3, high=10.0,
                           live=True)
    avoid_rate: float = tunable(
        1.0, 'A pair closes its gap at most this fast per metre of gap, 1/s',
        low=1e-3, high=100.0, live=True)
    avoid_buffer: float = tunable(0.3, 'Gap kept free beyond the summed coverage radii, m',
                                  low=0.0, high=10.0, live=True)
    swerve: float = tunable(0.5, 'Share of the speed towards a close neighbour turned right',
                            low=0.0, high=1.0, live=True)
    yield_margin: float = tunable(
        0.0, 'A parked robot steps aside for one closer than this beyond avoid_buffer, m',
        low=0.0, high=10.0, live=True)
    arrive_radius: float = tunable(0.02, 'Closer than this to the goal the setpoint is zero, m',
                                   low=0.0, high=10.0, live=True)

    def __post_init__(self) -> None:
        for name in ('gain', 'v_max', 'avoid_rate'):
            if not getattr(self, name) > 0.0:
                raise ValueError(f'setpoint parameter {name} must be positive, got '
                                 f'{getattr(self, name)}')
        if not (self.avoid_buffer >= 0.0 and self.yield_margin >= 0.0
                and 0.0 <= self.swerve <= 1.0):
            raise ValueError(f'avoid_buffer and yield_margin must be >= 0 m and swerve in '
                             f'[0, 1], got {self.avoid_buffer}, {self.yield_margin} and '
                             f'{self.swerve}')


def _saturate(v: np.ndarray, v_max: float) -> np.ndarray:
    speed = float(np.hypot(*v))
    return v * (v_max / speed) if speed > v_max else v


def velocity_setpoint(position, goal, params: SetpointParams, *,
                      waypoints=None) -> np.ndarray:
    """The 2-D velocity setpoint towards the goal in m/s (map frame), before avoidance."""
    position = np.asarray(position, dtype=float)
    goal = np.asarray(goal, dtype=float)
    if waypoints is not None and len(waypoints) > 2:
        pts = np.asarray(waypoints, dtype=float)
        remaining = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
        target = pts[1]
    else:
        remaining = float(np.hypot(*(goal - position)))
        target = goal
    direction = target - position
    dist = float(np.hypot(*direction))
    if remaining > params.arrive_radius and dist > 1e-9:
        return direction / dist * min(params.v_max, params.gain * remaining)
    return np.zeros(2)


def avoid_collisions(velocity, offsets, radii, own_radius: float,
                     params: SetpointParams, *, parked: bool = False) -> np.ndarray:
    """``velocity`` (m/s) made safe with respect to neighbours at ``offsets`` (k, 2:
    neighbour centre minus own centre, m) of coverage ``radii`` (k,); see the module
    docstring. A ``parked`` robot keeps ``yield_margin`` more. Returns the closest
    velocity to the swerved one that satisfies every neighbour's constraint, saturated
    at ``v_max``."""
    v = np.asarray(velocity, dtype=float).copy()
    offsets = np.asarray(offsets, dtype=float).reshape(-1, 2)
    if not len(offsets):
        return v
    d = np.hypot(offsets[:, 0], offsets[:, 1])
    buffer = params.avoid_buffer + (params.yield_margin if parked else 0.0)
    gap = d - (own_radius + np.asarray(radii, dtype=float) + buffer)
    bound = 0.5 * params.avoid_rate * gap
    # Only neighbours whose bound can bind at v_max matter (and none on top of us:
    # no direction to keep).
    near = (bound < params.v_max) & (d > 1e-9)
    if not near.any():
        return v
    unit, bound = offsets[near] / d[near, None], bound[near]
    if params.swerve > 0.0:
        towards = unit @ v
        closing = towards > 0.0
        right = np.column_stack([unit[:, 1], -unit[:, 0]])
        v = v + params.swerve * (towards[closing, None] * right[closing]).sum(axis=0)
    return _saturate(_closest_feasible(v, unit, bound), params.v_max)


def _closest_feasible(v: np.ndarray, normals: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """argmin |x - v| subject to normals @ x <= bounds (unit normals), in the plane.

    Written out because it is exact and tiny: the optimum of a two-variable QP lies at
    ``v`` itself, at the projection of ``v`` on one constraint line, or at the meeting
    point of two lines; the candidates are checked at once. (A library QP solver costs
    more than the whole filter, which runs 12 times a second per robot.) When no point
    satisfies every constraint (boxed in on all sides), the candidate that violates
    them least is returned.
    """
    excess = normals @ v - bounds
    if (excess <= 0.0).all():
        return v                                  # already safe (the common case)
    if len(bounds) == 1:
        return v - excess[0] * normals[0]
    candidates = [v[None, :], v - np.maximum(excess, 0.0)[:, None] * normals]
    i, j = np.triu_indices(len(bounds), 1)
    if len(i):
        det = normals[i, 0] * normals[j, 1] - normals[i, 1] * normals[j, 0]
        ok = np.abs(det) > 1e-9
        i, j, det = i[ok], j[ok], det[ok]
        x = (bounds[i] * normals[j, 1] - bounds[j] * normals[i, 1]) / det
        y = (normals[i, 0] * bounds[j] - normals[j, 0] * bounds[i]) / det
        candidates.append(np.column_stack([x, y]))
    points = np.vstack(candidates)
    violation = np.max(points @ normals.T - bounds, axis=1)
    feasible = violation <= 1e-9
    if feasible.any():
        distance = np.where(feasible, np.sum((points - v) ** 2, axis=1), np.inf)
        return points[int(np.argmin(distance))]
    return points[int(np.argmin(violation))]
