"""Artificial forces method (thesis 3.2.1.1): the agents reach a force balance and stop.

- ``ForceParams.setpoint`` is the steady velocity of the thesis's mass (eq. 3.75) with
  viscous and dry friction pushed by the artificial force (eq. 3.79).
- The buffer zone lets an agent cross the contour: no outward barrier at it.
- Eq. 3.88 vanishes at ``member_range`` without a jump.
- Two agents in a circle come to rest where eq. 3.88 balances eq. 3.84, under the force
  noise the brain measures; without the dry friction they never stop.
- A small headless swarm settles inside its shape (eq. 4.1) without overlapping coverage
  circles.
"""

from __future__ import annotations

import dataclasses
import pathlib

import numpy as np
import pytest
from scipy.optimize import brentq

from swarm_agent.forces import ForceParams, formation_force
from swarm_common.shapes import load_shape
from swarm_sim.headless import HeadlessSwarm, Scenario
from swarm_sim.metrics import inside_mask

PARAMS = ForceParams()
SQUARE = pathlib.Path(__file__).resolve().parents[2] / 'data' / 'square_8m.json'


def circle_contour(radius: float, step: float = 0.05) -> np.ndarray:
    """Equally spaced samples of a circle of ``radius`` around the origin (eq. 3.82)."""
    angles = np.linspace(0.0, 2 * np.pi, int(round(2 * np.pi * radius / step)), endpoint=False)
    return radius * np.column_stack([np.cos(angles), np.sin(angles)])


# -- from force to velocity setpoint

def steady_velocity(force: float, params: ForceParams, moving: bool, mass: float = 1.0) -> float:
    """Integrate m dv/dt = F - b v - F_k (moving; b = 1 / speed_per_newton) from v = 0 or a
    small forward speed, with the dry friction holding a mass at rest below F_s."""
    b = 1.0 / params.speed_per_newton
    v, dt = (1e-3 if moving else 0.0), mass / b / 50.0
    for _ in range(2000):
        if v <= 0.0 and force <= params.static_friction and not moving:
            return 0.0
        v = max(v + dt / mass * (force - b * v - params.kinetic_friction), 0.0)
        if v == 0.0:
            return 0.0
    return v


def test_setpoint_is_the_steady_velocity_of_a_mass_with_viscous_and_dry_friction():
    p = PARAMS
    assert 0 < p.kinetic_friction < p.static_friction
    direction = np.array([0.6, -0.8])
    for force in (0.5 * p.kinetic_friction, 0.5 * (p.kinetic_friction + p.static_friction),
                  1.5 * p.static_friction, 300.0):
        for at_rest in (True, False):
            v = p.setpoint(force * direction, 10.0, at_rest)
            expected = steady_velocity(force, p, moving=not at_rest)
            assert np.linalg.norm(v) == pytest.approx(expected, rel=1e-3, abs=1e-9)
            if expected > 0:
                np.testing.assert_allclose(v / np.linalg.norm(v), direction, atol=1e-12)
    # Continuous where a moving agent stops; saturated at v_max far from the balance.
    below = p.setpoint([p.kinetic_friction * (1 + 1e-9), 0.0], 0.5, at_rest=False)
    assert np.linalg.norm(below) < 1e-9
    np.testing.assert_allclose(p.setpoint([0.0, -1e5], 0.5, at_rest=True), [0.0, -0.5])


# -- buffer zone and eq. 3.88's range

def test_an_agent_crosses_the_contour_without_a_barrier():
    """Along a line through the contour of a 4 m circle, the force points inwards from 2 m
    outside to the inner edge of the buffer zone: no balance point outside the shape."""
    contour = circle_contour(4.0, 0.01)
    heading = np.array([np.cos(0.3), np.sin(0.3)])
    for r in np.arange(6.0, 4.0 - PARAMS.buffer, -0.01):
        f = formation_force(r * heading, np.zeros(2), r < 4.0, contour, None, None, 0.3, None,
                            PARAMS)
        assert np.dot(f, -heading) > 0.9 * np.linalg.norm(f), r
        assert np.linalg.norm(f) > PARAMS.static_friction, r     # it cannot park there


def test_inter_member_force_vanishes_continuously_at_member_range():
    r = 0.3
    d = np.linspace(2 * r + 0.2, PARAMS.member_range + 0.5, 400)
    mags = [np.linalg.norm(formation_force([0.0, 0.0], None, True, np.zeros((0, 2)),
                                           [[x, 0.0]], [r], r, None, PARAMS)) for x in d]
    assert np.all(np.diff(mags) <= 0)                       # repulsive, weaker with distance
    assert mags[-1] == 0.0

    def member(x: float) -> float:
        return np.linalg.norm(formation_force([0.0, 0.0], None, True, np.zeros((0, 2)),
                                              [[x, 0.0]], [r], r, None, PARAMS))

    # No jump at the range: eq. 3.88 cut there would drop by k_m / (3 - d_o)^2 = 260 N.
    edge = PARAMS.member_range
    assert member(edge - 1e-3) < 1.0 and member(edge + 1e-3) == 0.0


# -- two bodies come to rest

def _run_pair(params: ForceParams, seed: int, start, duration: float = 150.0):
    """Two robots (radius 0.3 m) in a 4 m circle from ``start`` (2, 2), as the brain drives
    them: the force every
    0.5 s (2 Hz outer loop) with 13 N of noise per axis (what a robot at rest measures:
    2 cm proximity noise), the velocity following the setpoint with the inner loop's
    0.5 s time constant. Returns times, positions, speeds."""
    rng = np.random.default_rng(seed)
    contour = circle_contour(4.0)
    radius, dt, period, tau = 0.3, 0.02, 0.5, 0.5
    z = np.array(start, dtype=float)
    v = np.zeros((2, 2))
    setpoint = np.zeros((2, 2))
    at_rest = [True, True]
    times, positions, speeds = [], [], []
    for k in range(int(duration / dt)):
        t = k * dt
        if k % int(period / dt) == 0:
            for i in range(2):
                f = formation_force(z[i], v[i], bool(np.hypot(*z[i]) < 4.0), contour,
                                    z[1 - i:2 - i], [radius], radius, None, params)
                setpoint[i] = params.setpoint(f + rng.normal(0.0, 13.0, 2), 0.5, at_rest[i])
                at_rest[i] = not setpoint[i].any()
        v += (setpoint - v) * (dt / tau)
        z += v * dt
        times.append(t)
        positions.append(z.copy())
        speeds.append(np.linalg.norm(v, axis=1))
    return np.array(times), np.array(positions), np.array(speeds)


def test_two_agents_come_to_rest_at_the_balance_of_eqs_3_84_and_3_88():
    # The balance on a diameter: eq. 3.88 at separation D equals eq. 3.84 at D / 2.
    contour = circle_contour(4.0)

    def force(z) -> np.ndarray:
        z = np.asarray(z, dtype=float)
        return formation_force(z, None, True, contour, [-z], [0.3], 0.3, None, PARAMS)

    half = brentq(lambda x: force([x, 0.0])[0], 0.35, 3.0)
    stiffness = (force([half - 0.01, 0.0])[0] - force([half + 0.01, 0.0])[0]) / 0.02
    # Pushed apart from 0.8 m (coverage circles 0.2 m apart), they stop on the way out
    # once the force falls below the kinetic friction: within F_s / K of the balance.
    tolerance = PARAMS.static_friction / stiffness
    for seed in range(3):
        angle = 0.7 * seed
        start = 0.4 * np.array([[np.cos(angle), np.sin(angle)]]) * [[1.0], [-1.0]]
        times, positions, speeds = _run_pair(PARAMS, seed, start)
        last = times >= times[-1] - 30.0
        assert speeds[last].max() < 0.01                 # eq. 4.1: at rest, and it stays
        end = positions[-1]
        assert np.all(np.hypot(end[:, 0], end[:, 1]) < 4.0)
        assert np.linalg.norm(end[0] - end[1]) == pytest.approx(2 * half, abs=2 * tolerance)
        assert np.linalg.norm(end.mean(axis=0)) < tolerance
        assert np.linalg.norm(force(end[0])) < PARAMS.static_friction
    # From anywhere they stop where the force is below the static friction, apart.
    times, positions, speeds = _run_pair(PARAMS, 3, [[-2.5, 1.0], [0.5, -0.2]])
    end = positions[-1]
    assert speeds[times >= times[-1] - 30.0].max() < 0.01
    for i in range(2):
        f = formation_force(end[i], None, True, contour, end[1 - i:2 - i], [0.3], 0.3, None,
                            PARAMS)
        assert np.linalg.norm(f) < PARAMS.static_friction
    assert np.linalg.norm(end[0] - end[1]) > 2 * (2 * 0.3)
    # Without dry friction (the force mapped straight to a velocity) the same noisy
    # force keeps them moving: they never settle.
    frictionless = dataclasses.replace(PARAMS, kinetic_friction=0.0, static_friction=0.0)
    times, _, speeds = _run_pair(frictionless, 0, start)
    assert speeds[times >= times[-1] - 30.0].max() > 0.01


# -- a small swarm in the headless evaluator

@pytest.mark.parametrize('seed', [0, 1])
def test_small_swarm_settles_inside_the_shape_without_overlap(seed):
    """Six robots of the three types from up to 15 m away into an 8 m square (3 beacons):
    settled by eq. 4.1 and held 30 s within the 200 s run, so by 170 s (they arrive in
    about 30 s at 0.5 m/s; a parked robot whose estimate a localization fix moves drives
    again, and eq. 4.1 counts settling from its last stop: over seeds 0-9 the settling
    times reach 157 s, seed 0's), no coverage circles overlapping on the way, spread out
    at the end, and no chasing: the distance travelled within 25 % of the least
    possible."""
    scenario = Scenario(shape=load_shape(str(SQUARE)), method='forces',
                        type_counts={1: 3, 2: 2, 3: 1}, n_beacons=3, half_size=15.0,
                        seed=seed, duration_s=200.0)
    record = HeadlessSwarm(scenario).run()
    metrics = record.metrics
    assert metrics['settled']
    assert metrics['min_separation_ratio'] >= 1.0 and metrics['contacts'] == 0
    final = record.positions[-1]
    assert inside_mask(scenario.shape, final).all()
    radii = np.array([{1: 0.15, 2: 0.3, 3: 0.5}[t] for t in record.types])
    d = np.linalg.norm(final[:, None] - final[None], axis=2) + np.eye(len(final)) * 1e9
    assert (d / (radii[:, None] + radii[None])).min() > 2.0        # spread out
    assert metrics['total_displacement'] <= 1.25 * metrics['displacement_lower_bound']
