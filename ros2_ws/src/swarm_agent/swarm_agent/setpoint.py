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
the filter, ``swerve`` times the speed towards a close neighbour (s = u_j . v > 0) is
turned sideways: two robots meeting head-on, or a robot behind a parked one, would
otherwise stop in front of each other for good. The turn is to the right, so that both
robots of a meeting turn the same way round each other (turns that cancel between the
two let the crossing pair and the ring swap of test_collision_dynamics 3-5 cm into the
buffer).
Against a setpoint that passes the neighbour on the left with a sideways part t
(positive to the right) the right turn leaves t + swerve s, zero at t = -swerve s, 26.6
degrees off the line of centres for swerve 0.5: pressed against the neighbour there,
the robot gets no command although its setpoint is not zero. Robots slowing for goals
that a neighbour stands on or beside press it exactly there, and hold it: three robots
around a gap narrower than the one passing through, the other two 2-3 cm from their
goals, hold each other still so for good (the hw_arrow case of docs/camera.md). A robot
whose setpoint is below ``v_max`` (slowing for its goal) therefore turns left instead
wherever the right turn would leave less than swerve s / 2 sideways (|t + swerve s| <
swerve s / 2): its sideways part is then at least swerve s / 2 in size, whichever way
it passes.

That guarantee holds for the velocity commanded, but a robot has mass: the LQR loop
(eqs. 3.108-3.110) follows a changing command about tau = (b + K_v) / K_e behind
(``tracking_lag_s``: 0.57-0.71 s for Table 4.1's types). Modelled as that lag, a pair
closing symmetrically at v each (dh/dt = -2 v) under the plain bound obeys tau h'' + h'
+ rate h = 0, which overshoots h = 0 whenever 4 tau rate > 1 (2.8 for type 3 at 1/s):
two robots meeting at 0.5 m/s each cross 0.3 m into the buffer. The filter therefore
bounds the gap the robot will have one lag later, h + tau dh/dt, with dh/dt taken as
twice its own measured closing speed u_j . v_i (the neighbour assumed to close as
fast; when it does not, the bound is only stricter):

    u_j . v <= (rate / 2) h_j - rate tau (u_j . v_i).

With the lag model this gives tau h'' + (1 + rate tau) h' + rate h = 0, roots -1/tau and
-rate: never oscillatory, and a pair entering the constraint at its edge approaches
as exp(-rate t), as the plain bound promises a kinematic robot. (A parked neighbour:
tau h'' + (1 + rate tau) h' + rate h / 2 = 0, also real roots.)

What the lag model leaves out is what ``avoid_buffer`` (0.3 m) is for, each term at
the thesis scenario's rates: the proximity scan's offset noise (2 cm per axis,
``swarm_sim.sensors``); the command held between scans (0.1 s, a further delay of 0.05 s
on average, 5 cm at the pair's 1 m/s closing speed, 10 cm at worst); the robot's own
velocity estimate (its error e_v, about 0.05 m/s, moves where a pair stops by 2 tau e_v,
7 cm); and the second-order loop and the turning line of centres as robots pass, which
the lag model ignores (4 cm into the buffer when eight robots of mixed types swap
places across a ring, test_collision_dynamics; 7 cm without the scan noise). Together
about 26 cm of the 30. Offsets from the
neighbours' broadcast estimates (no fresh scan) carry both robots' localization errors,
0.5 m and more, which this budget does not cover.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarm_agent.lqr import LqrGains
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
    swerve: float = tunable(0.5, 'Share of the speed towards a close neighbour turned aside',
                            low=0.0, high=1.0, live=True)
    yield_margin: float = tunable(
        0.0, 'A parked robot steps aside for one closer than this beyond avoid_buffer, m',
        low=0.0, high=10.0, live=True)
    arrive_radius: float = tunable(0.02, 'Closer than this to the goal the setpoint is zero, m',
                                   low=0.0, high=10.0, live=True)
    give_way_after_s: float = tunable(
        0.0, 'A robot within two radii of its goal, held below a quarter of its setpoint '
        'speed this long, gives way, s (0: never)', low=0.0, high=600.0, live=True)
    give_way_s: float = tunable(5.0, 'How long a held robot gives way (keeps yield_margin), s',
                                low=0.0, high=600.0, live=True)

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


class GiveWay:
    """Whether a robot held still by its neighbours short of its goal gives way now.

    Beyond the thesis. The filter is a local rule, and several robots around one gap
    can hold each other still for good, each one's every safe direction pointing away
    from its goal: on the arena (hardware parameters: no buffer, goals a few centimetres
    apart) the big robot slowing for the centre goal of hw_square and the two robots
    crossing the square round it pressed on one another 0.12-0.52 m from their goals
    (docs/camera.md, "Robots that hold each other"). A robot within two of its coverage
    radii of its goal whose commanded speed stays below a quarter of its setpoint's for
    ``give_way_after_s`` therefore keeps ``yield_margin`` more from everyone for
    ``give_way_s``, as a parked robot does: it backs off a few centimetres and opens the
    gap, while still heading for its goal.

    Held is slow, not slow along the setpoint: a robot sliding round a parked one makes
    little progress along its setpoint, and giving way there (its own margin growing)
    kept one from passing robot 0 of hw_line for good. Near its goal only: a robot that
    close to its goal stands where others pass, while one farther out is passing, and
    the parked robots it presses yield to it anyway; giving way wherever it was held cost
    the line's kinematic replay 4 % of its median travel (docs/camera.md). Off
    (``give_way_after_s`` 0) in the simulation, whose ``yield_margin`` is zero.
    """

    NEAR_GOAL_RADII = 2.0        # gives way within this many of its radii of the goal

    def __init__(self, params: SetpointParams, radius: float) -> None:
        self.params = params
        self.near_goal_m = self.NEAR_GOAL_RADII * radius
        self._blocked_since: float | None = None
        self._until = -np.inf
        self._giving = False
        self.count = 0                      # give-ways so far

    def active(self, t: float) -> bool:
        """Giving way at ``t``."""
        return t < self._until

    def ended(self, t: float) -> bool:
        """True once, at the first call after a give-way ended (recompute the command)."""
        if self._giving and not self.active(t):
            self._giving = False
            return True
        return False

    def observe(self, t: float, setpoint, command, to_goal: float) -> None:
        """The command the filter gave at ``t`` for ``setpoint`` (m/s each), the robot
        ``to_goal`` m from its goal (inf: none)."""
        if self.params.give_way_after_s <= 0.0 or self.active(t):
            self._blocked_since = None
            return
        wanted = float(np.hypot(*setpoint))
        if (wanted == 0.0 or to_goal >= self.near_goal_m
                or float(np.hypot(*command)) >= 0.25 * wanted):
            self._blocked_since = None
        elif self._blocked_since is None:
            self._blocked_since = t
        elif t - self._blocked_since >= self.params.give_way_after_s:
            self._until = t + self.params.give_way_s
            self._blocked_since = None
            self._giving = True
            self.count += 1


def _saturate(v: np.ndarray, v_max: float) -> np.ndarray:
    speed = float(np.hypot(*v))
    return v * (v_max / speed) if speed > v_max else v


def tracking_lag_s(fluid_friction: float, gains: LqrGains) -> float:
    """How far in time (s) the robot's velocity trails a steadily changing setpoint.

    The closed velocity loop of eqs. 3.108-3.110, m dv/dt = -b v - K_v v - K_e e with
    e the integral of v - v_ref, has the transfer function K_e / (m s^2 + (b + K_v) s +
    K_e) from v_ref to v; its velocity-error constant gives the steady lag behind a ramp
    of the setpoint, (b + K_v) / K_e. With Table 4.1 and eq. 3.111's weights this is
    0.57 s (type 1), 0.61 s (type 2) and 0.71 s (type 3).
    """
    return (fluid_friction + gains.k_v) / gains.k_e


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
                     params: SetpointParams, *, parked: bool = False,
                     own_velocity=None, lag_s: float = 0.0) -> np.ndarray:
    """``velocity`` (m/s) made safe with respect to neighbours at ``offsets`` (k, 2:
    neighbour centre minus own centre, m) of coverage ``radii`` (k,); see the module
    docstring. A ``parked`` robot keeps ``yield_margin`` more. ``own_velocity`` (m/s,
    the robot's measured velocity) and ``lag_s`` (s, ``tracking_lag_s``) aim the
    constraint at the gap ``lag_s`` ahead, where the robot's velocity loop will have
    brought it. Returns the closest velocity to the swerved one that satisfies every
    neighbour's constraint, saturated at ``v_max``."""
    v = np.asarray(velocity, dtype=float).copy()
    offsets = np.asarray(offsets, dtype=float).reshape(-1, 2)
    if not len(offsets):
        return v
    d = np.hypot(offsets[:, 0], offsets[:, 1])
    buffer = params.avoid_buffer + (params.yield_margin if parked else 0.0)
    gap = d - (own_radius + np.asarray(radii, dtype=float) + buffer)
    bound = 0.5 * params.avoid_rate * gap
    if own_velocity is not None and lag_s > 0.0:
        # Own closing speed u_j . v_i, doubled for the pair: dh/dt = -2 u_j . v_i when
        # the neighbour closes as fast (an overestimate, so safe, when it does not).
        closing = (offsets @ np.asarray(own_velocity, dtype=float)) / np.maximum(d, 1e-9)
        bound = bound - params.avoid_rate * lag_s * closing
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
        # Right; left where the right turn would all but cancel the setpoint's own
        # sideways part of a robot slowing for its goal (module docstring).
        slowing = np.hypot(*v) < params.v_max * (1.0 - 1e-9)     # not saturated
        left = slowing & (np.abs(right @ v + params.swerve * towards)
                          < 0.5 * params.swerve * towards)
        way = np.where(left, -1.0, 1.0)
        v = v + params.swerve * ((way * towards)[closing, None] * right[closing]).sum(axis=0)
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
