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

from collections.abc import Sequence
from dataclasses import dataclass
import math

import numpy as np

from swarm_agent.lqr import LqrGains
from swarm_common.jit import helper, kernel
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
    detour_after_s: float = tunable(
        0.0, 'A robot two radii or more from its goal, held below a quarter of its setpoint '
        'speed this long, goes round the robots round it, s (0: never)', low=0.0,
        high=600.0, live=True)

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
        self._held = HeldClock()
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
            self._held.reset()
        elif self._held.held_for(t, setpoint, command, self.params.give_way_after_s,
                                 to_goal < self.near_goal_m):
            self._until = t + self.params.give_way_s
            self._giving = True
            self.count += 1


class HeldClock:
    """How long in a row the collision filter has held a robot: its command slower than a
    quarter of its setpoint's speed, the setpoint not zero (``GiveWay``, ``detour.Detour``:
    the same clock, for robots near their goals and far from them)."""

    def __init__(self) -> None:
        self._since: float | None = None     # first call of the hold (s)

    def reset(self) -> None:
        self._since = None

    def held_for(self, t: float, setpoint, command, after_s: float,
                 applies: bool = True) -> bool:
        """Whether the robot, given ``command`` for ``setpoint`` (m/s each) at ``t``, has
        been held since a call ``after_s`` or more before (the clock then starts again);
        ``applies`` False (the robot outside the rule's reach) counts as not held."""
        wanted = float(np.hypot(*setpoint))
        if not (applies and wanted > 0.0 and float(np.hypot(*command)) < 0.25 * wanted):
            self._since = None
        elif self._since is None:
            self._since = t
        elif t - self._since >= after_s:
            self._since = None
            return True
        return False


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
    neighbour's constraint, saturated at ``v_max`` (the rules: ``_avoid``)."""
    v = np.array(velocity, dtype=float)
    offsets = np.ascontiguousarray(offsets, dtype=float).reshape(-1, 2)
    if not len(offsets):
        return v
    lead = own_velocity is not None and lag_s > 0.0
    ux, uy = (float(own_velocity[0]), float(own_velocity[1])) if lead else (0.0, 0.0)
    v[0], v[1] = _avoid(float(v[0]), float(v[1]), offsets,
                        np.ascontiguousarray(radii, dtype=float), float(own_radius),
                        params.avoid_buffer + (params.yield_margin if parked else 0.0),
                        params.avoid_rate, params.v_max, params.swerve, ux, uy,
                        float(lag_s) if lead else 0.0)
    return v


@kernel(0.3, 0.1, np.array([[1.0, 0.2], [0.9, -0.4]]), np.array([0.4, 0.5]), 0.4, 0.3,
        1.0, 0.5, 0.5, 0.1, 0.0, 0.6)
def _avoid(vx: float, vy: float, offsets: np.ndarray, radii: np.ndarray,
           own_radius: float, buffer: float, avoid_rate: float, v_max: float,
           swerve: float, ux: float, uy: float, lag_s: float) -> tuple[float, float]:
    """The collision filter of ``avoid_collisions`` on one robot's velocity (vx, vy).

    Per neighbour j at unit direction u_j and distance d_j, the gap h_j = d_j - (r_i +
    r_j + buffer) may close at most at avoid_rate * h_j, shared by the pair: u_j . v <=
    b_j = avoid_rate * h_j / 2, less avoid_rate * lag_s * (u_j . own velocity) when the
    constraint is aimed ``lag_s`` ahead (lag_s > 0). Only neighbours whose b_j is below
    v_max can bind. The velocity first swerves: a share ``swerve`` of its speed towards
    each closing neighbour is turned to the right of u_j (to the left where that would
    all but cancel the setpoint's own sideways part of a robot slowing for its goal).
    Then the closest velocity satisfying every constraint (``_closest_feasible``) is
    saturated at v_max.
    """
    k = offsets.shape[0]
    unit = np.empty((k, 2))
    bound = np.empty(k)
    m = 0
    for j in range(k):
        ox, oy = offsets[j, 0], offsets[j, 1]
        d = math.hypot(ox, oy)
        b = _gap_bound(d, radii[j], own_radius, buffer, avoid_rate)
        if lag_s > 0.0:
            b = b - avoid_rate * lag_s * ((ox * ux + oy * uy) / max(d, 1e-9))
        if b < v_max and d > 1e-9:
            unit[m, 0], unit[m, 1], bound[m] = ox / d, oy / d, b
            m += 1
    if m == 0:
        return vx, vy
    if swerve > 0.0:
        slowing = math.hypot(vx, vy) < v_max * (1.0 - 1e-9)     # not saturated
        sx = sy = 0.0
        for j in range(m):
            towards = unit[j, 0] * vx + unit[j, 1] * vy
            if towards > 0.0:
                rx, ry = unit[j, 1], -unit[j, 0]      # right of the neighbour's direction
                way = 1.0
                if slowing and abs(rx * vx + ry * vy + swerve * towards) < \
                        0.5 * swerve * towards:
                    way = -1.0
                sx += way * towards * rx
                sy += way * towards * ry
        vx, vy = vx + swerve * sx, vy + swerve * sy
    vx, vy = _closest_feasible(vx, vy, unit, bound, m)
    speed = math.hypot(vx, vy)
    if speed > v_max:
        return vx * (v_max / speed), vy * (v_max / speed)
    return vx, vy


@helper
def _gap_bound(d: float, radius: float, own_radius: float, buffer: float,
               avoid_rate: float) -> float:
    """b_j of ``_avoid`` before the lead term: half the rate times the gap h_j."""
    return 0.5 * avoid_rate * (d - (own_radius + radius + buffer))


def stays_parked(offsets, radii, own_radius: float, params: SetpointParams) -> bool:
    """True when no neighbour is closer than a parked robot's margin (every b_j >= 0):
    then v = 0 satisfies every constraint of ``avoid_collisions``, nothing swerves, and
    the filter gives the parked robot's zero setpoint back as zero. A parked robot's
    scan that says so changes nothing, so its brain need not recompute (issue 23: work
    only where input changes something). False does not promise a nonzero command (a
    robot boxed in on all sides gets the least-violating one, which may be zero)."""
    offsets = np.asarray(offsets, dtype=float).reshape(-1, 2)
    return stays_parked_each(offsets, np.asarray(radii, dtype=float).reshape(-1), [0],
                             [len(offsets)], [own_radius], [params])[0]


def stays_parked_each(offsets: np.ndarray, radii: np.ndarray, starts: Sequence[int],
                      ends: Sequence[int], own_radii: Sequence[float],
                      params: Sequence[SetpointParams]) -> list[bool]:
    """``stays_parked`` for many robots in one call: robot k saw the rows
    ``starts[k]:ends[k]`` of ``offsets`` (M, 2) and ``radii`` (M,), has coverage radius
    ``own_radii[k]`` and filter parameters ``params[k]``."""
    return _stays_parked(np.ascontiguousarray(offsets, dtype=float),
                         np.ascontiguousarray(radii, dtype=float),
                         np.array(starts, dtype=np.int64), np.array(ends, dtype=np.int64),
                         np.array(own_radii, dtype=float),
                         np.array([p.avoid_buffer + p.yield_margin for p in params]),
                         np.array([p.avoid_rate for p in params])).tolist()


@kernel(np.array([[1.0, 0.2], [0.9, -0.4]]), np.array([0.4, 0.5]), np.array([0, 1]),
        np.array([1, 2]), np.array([0.4, 0.3]), np.array([0.3, 0.3]), np.array([1.0, 1.0]))
def _stays_parked(offsets: np.ndarray, radii: np.ndarray, starts: np.ndarray,
                  ends: np.ndarray, own_radii: np.ndarray, buffers: np.ndarray,
                  rates: np.ndarray) -> np.ndarray:
    """``stays_parked_each``'s test, with ``_avoid``'s arithmetic (``_gap_bound``): at
    v = 0 a constraint binds where b_j < 0, among the neighbours ``_avoid`` keeps
    (d_j > 0); the parked margin is ``buffers[k]`` (avoid_buffer + yield_margin)."""
    out = np.ones(starts.shape[0], dtype=np.bool_)
    for k in range(starts.shape[0]):
        for j in range(starts[k], ends[k]):
            d = math.hypot(offsets[j, 0], offsets[j, 1])
            if d > 1e-9 and _gap_bound(d, radii[j], own_radii[k], buffers[k],
                                       rates[k]) < 0.0:
                out[k] = False
                break
    return out


@helper
def _closest_feasible(vx: float, vy: float, normals: np.ndarray, bounds: np.ndarray,
                      m: int) -> tuple[float, float]:
    """argmin |x - v| subject to normals[:m] @ x <= bounds[:m] (unit normals), in the plane.

    Written out because it is exact and tiny: the optimum of a two-variable QP lies at
    ``v`` itself, at the projection of ``v`` on one constraint line, or at the meeting
    point of two lines; the candidates are checked in that order and the first closest
    feasible one is kept. (A library QP solver costs more than the whole filter, which
    runs 12 times a second per robot.) When no point satisfies every constraint (boxed
    in on all sides), the first candidate that violates them least is returned.
    """
    safe = True
    for j in range(m):
        if normals[j, 0] * vx + normals[j, 1] * vy - bounds[j] > 0.0:
            safe = False
    if safe:
        return vx, vy                             # already safe (the common case)
    if m == 1:
        excess = normals[0, 0] * vx + normals[0, 1] * vy - bounds[0]
        return vx - excess * normals[0, 0], vy - excess * normals[0, 1]
    best_x, best_y, best_distance = vx, vy, math.inf      # closest feasible so far
    least_x, least_y, least_violation = vx, vy, math.inf  # least violating so far
    for c in range(-1, m + m * (m - 1) // 2):
        if c < 0:                                  # v itself
            x, y = vx, vy
        elif c < m:                                # v projected on line c (if outside)
            excess = max(normals[c, 0] * vx + normals[c, 1] * vy - bounds[c], 0.0)
            x, y = vx - excess * normals[c, 0], vy - excess * normals[c, 1]
        else:                                      # where lines i < j meet
            i, j = _pair(c - m, m)
            det = normals[i, 0] * normals[j, 1] - normals[i, 1] * normals[j, 0]
            if abs(det) <= 1e-9:
                continue
            x = (bounds[i] * normals[j, 1] - bounds[j] * normals[i, 1]) / det
            y = (normals[i, 0] * bounds[j] - normals[j, 0] * bounds[i]) / det
        violation = -math.inf
        for j in range(m):
            violation = max(violation, normals[j, 0] * x + normals[j, 1] * y - bounds[j])
        if violation <= 1e-9:
            distance = (x - vx) ** 2 + (y - vy) ** 2
            if distance < best_distance:
                best_x, best_y, best_distance = x, y, distance
        elif best_distance == math.inf and violation < least_violation:
            least_x, least_y, least_violation = x, y, violation
    if best_distance < math.inf:
        return best_x, best_y
    return least_x, least_y


@helper
def _pair(index: int, m: int) -> tuple[int, int]:
    """The ``index``-th pair (i, j), i < j < m, in row order (as ``np.triu_indices``)."""
    i = 0
    while index >= m - 1 - i:
        index -= m - 1 - i
        i += 1
    return i, i + 1 + index
