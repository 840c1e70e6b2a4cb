"""The collision filter on robots with mass: the velocity it commands is tracked by the
LQR loop of eqs. 3.108-3.110 on the point mass with Table 4.1's friction, so the robot's
velocity trails the command by the loop's lag (``setpoint.tracking_lag_s``). The filter
must keep the buffer free for the robots as they move, not only for the commands.

The kinematic checks (velocity = command) are in test_control.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from swarm_agent.dynamics import PointMassSwarm
from swarm_agent.lqr import design_lqr, VelocityLoop
from swarm_agent.setpoint import (
    avoid_collisions,
    SetpointParams,
    tracking_lag_s,
    velocity_setpoint,
)
from swarm_common.robot_types import GRAVITY, load_robot_types, LqrDesign

TYPES = load_robot_types()
DESIGN = LqrDesign()
DT = 0.02                 # inner loop and physics step (50 Hz, headless evaluator)
SCAN = 0.1                # proximity sensor period (10 Hz, swarm_sim.sensors)
SCAN_NOISE = 0.02         # proximity offset noise per axis, m (swarm_sim.sensors)

pytestmark = pytest.mark.usefixtures('kernels')


@pytest.mark.parametrize('type_id, lag', [(1, 0.565), (2, 0.612), (3, 0.712)])
def test_tracking_lag_is_the_velocity_error_constant_of_the_loop(type_id, lag):
    """A setpoint ramping at 0.1 m/s^2 is followed, once transients have died out,
    (b + K_v) / K_e behind: the design model of eq. 3.108 integrated at 1 ms."""
    robot = TYPES[type_id]
    gains = design_lqr(robot, DESIGN)
    assert tracking_lag_s(robot.fluid_friction, gains) == pytest.approx(lag, abs=1e-3)
    loop = VelocityLoop(gains)
    v, dt, slope = 0.0, 1e-3, 0.1
    for k in range(int(10.0 / dt)):
        force = loop.step(dt, np.array([slope * k * dt, 0.0]), np.array([v, 0.0]))[0]
        v += dt * (force - robot.fluid_friction * v) / robot.mass
    assert (slope * 10.0 - v) / slope == pytest.approx(lag, rel=0.01)


def _drive(starts, goals, type_ids, *, params=None, with_lag=True, seconds=40.0, seed=0):
    """Robots of ``type_ids`` from ``starts`` to ``goals`` as a brain drives them:
    setpoint, then the filter on a noisy proximity scan every SCAN s (command held in
    between), tracked by each type's velocity loop on the point mass. Returns the
    smallest gap beyond the summed radii plus the buffer, and where the robots end."""
    params = params or SetpointParams()
    rng = np.random.default_rng(seed)
    robots = [TYPES[t] for t in type_ids]
    radii = np.array([r.coverage_radius for r in robots])
    gains = [design_lqr(r, DESIGN) for r in robots]
    lags = [tracking_lag_s(r.fluid_friction, g) if with_lag else 0.0
            for r, g in zip(robots, gains)]
    loops = [VelocityLoop(g, u_max=DESIGN.u_max + 2 * r.dry_friction * r.mass * GRAVITY)
             for r, g in zip(robots, gains)]
    body = PointMassSwarm(robots, starts)
    goals = np.asarray(goals, dtype=float)
    n = len(robots)
    command = np.zeros((n, 2))
    smallest = np.inf
    every = int(round(SCAN / DT))
    for k in range(int(seconds / DT)):
        p, v = body.positions, body.velocities
        if k % every == 0:
            for i in range(n):
                others = np.arange(n) != i
                seen = p[others] - p[i] + rng.normal(0.0, SCAN_NOISE, (n - 1, 2))
                want = velocity_setpoint(p[i], goals[i], params)
                command[i] = avoid_collisions(want, seen, radii[others], radii[i], params,
                                              own_velocity=v[i], lag_s=lags[i])
        body.step(DT, np.array([loops[i].step(DT, command[i], v[i]) for i in range(n)]))
        p = body.positions
        i, j = np.triu_indices(n, 1)
        gap = np.linalg.norm(p[i] - p[j], axis=1) - radii[i] - radii[j] - params.avoid_buffer
        smallest = min(smallest, float(gap.min()))
    return smallest, body.positions


def _ring(n: int, radius: float = 5.0) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    return radius * np.column_stack([np.cos(a), np.sin(a)])


CASES = {
    # Two type-3 robots (0.5 m, the slowest loop) meeting head-on at v_max.
    'head-on': ([[0.0, 0.0], [10.0, 0.0]], [[10.0, 0.0], [0.0, 0.0]], [3, 3]),
    # Paths crossing at right angles, type 3 and type 2, arriving together.
    'crossing': ([[0.0, -5.0], [-5.0, 0.0]], [[0.0, 5.0], [5.0, 0.0]], [3, 2]),
    # Six robots swapping places across a ring: every pair meets in the middle.
    'ring swap': (_ring(6), -_ring(6), [3, 2, 3, 2, 3, 2]),
}


@pytest.mark.parametrize('case', sorted(CASES))
def test_robots_with_mass_keep_the_buffer_free(case):
    """A pair closes its gap at most at ``avoid_rate`` per metre of the gap the robots
    will have one loop lag later: the buffer stays free (the command-only filter, with
    no lag, lets the robots' momentum carry them 15-34 cm into it), and they arrive."""
    starts, goals, type_ids = CASES[case]
    smallest, end = _drive(np.asarray(starts, float), goals, type_ids)
    assert smallest > 0.0
    np.testing.assert_allclose(end, goals, atol=0.05)


def test_eight_robots_swapping_across_a_ring_stay_within_the_budget():
    """Eight robots of the three types meet in the middle at once: what the lag model
    leaves out (the second-order loop, the turning lines of centres) takes at most the
    7 cm of the buffer that ``setpoint``'s budget gives it, and every robot arrives."""
    type_ids = [1, 2, 3, 1, 2, 3, 1, 2]
    ring = _ring(8)
    smallest, end = _drive(ring, -ring, type_ids, seconds=80.0)
    assert smallest > -0.07
    np.testing.assert_allclose(end, -ring, atol=0.05)


def test_without_the_lag_the_robots_overrun_the_buffer():
    """The same head-on meeting with the command-only filter: the loop lag (0.71 s for
    type 3) at a 1 m/s closing speed carries the pair well into the 0.3 m buffer."""
    starts, goals, type_ids = CASES['head-on']
    smallest, _ = _drive(np.asarray(starts, float), goals, type_ids, with_lag=False)
    assert smallest < -0.2


def test_the_bound_counts_the_robots_own_closing_speed():
    """u . v <= (rate / 2) h - rate * lag * (u . v_own): a robot already closing at
    0.4 m/s with a 0.7 s lag, 0.5 m beyond the buffer, is told to back away."""
    params = SetpointParams(swerve=0.0)
    ahead = [[0.3 + 0.5 + params.avoid_buffer + 0.5, 0.0]]
    v = avoid_collisions(np.array([0.5, 0.0]), ahead, [0.5], 0.3, params,
                         own_velocity=[0.4, 0.0], lag_s=0.7)
    want = 0.5 * params.avoid_rate * 0.5 - params.avoid_rate * 0.7 * 0.4
    np.testing.assert_allclose(v, [want, 0.0], atol=1e-12)
    assert want < 0.0
    # Moving across the line of centres adds nothing; standing still is the plain bound.
    across = avoid_collisions(np.array([0.5, 0.0]), ahead, [0.5], 0.3, params,
                              own_velocity=[0.0, 0.4], lag_s=0.7)
    np.testing.assert_allclose(across, [0.5 * params.avoid_rate * 0.5, 0.0], atol=1e-12)
