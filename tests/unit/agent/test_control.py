"""Control layer: LQR velocity loop, setpoints, artificial forces, point-mass dynamics.

- LQR of eqs. 3.108-3.111 per robot type of Table 4.1: gains against the closed form,
  stable closed loop, step response (Fig. 3.34), tracking on the friction model.
- Point mass with Coulomb (mu_1 m g) and fluid (mu_2 v) friction (dynamics.py): terminal
  velocity, time constant, break-away force and stopping time from its own equations,
  compiled and as the kernel's Python source.
- Velocity setpoint generator (thesis 3.2.4, Fig. 3.32): saturation at 0.5 m/s.
- Artificial forces (thesis 3.2.1.1, eqs. 3.80-3.93): outside agents are pulled in,
  inside agents are pushed apart and away from the boundary.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
import yaml

from swarm_agent.dynamics import PointMassSwarm
from swarm_agent.forces import ForceParams, formation_force
from swarm_agent.lqr import (
    bandwidth_rad_s,
    closed_loop,
    design_lqr,
    design_model,
    step_response,
    VelocityLoop,
)
from swarm_agent.setpoint import avoid_collisions, SetpointParams, velocity_setpoint
from swarm_common.robot_types import GRAVITY, load_robot_types, LqrDesign, RobotType

TYPES = load_robot_types()
DESIGN = LqrDesign()          # eq. 3.111: t1=1.5 s, t2=0.01 s, 1 m/s, 4 m, 3 N
TYPE_IDS = sorted(TYPES)
V_MAX = 0.5                   # m/s, thesis 3.2.4


def weights(design: LqrDesign) -> tuple[float, float, float]:
    """q1, q2, r1 of eq. 3.111 (Bryson's rule)."""
    return (1.0 / (design.t1 * design.x1_max ** 2), 1.0 / (design.t2 * design.x2_max ** 2),
            1.0 / design.u_max ** 2)


def closed_form_gains(robot: RobotType, design: LqrDesign) -> tuple[float, float]:
    """K_v, K_e solving the Riccati equation of eqs. 3.108-3.110 in closed form.

    Return-difference identity p(s) p(-s) = o(s) o(-s) + (q2 - q1 s^2) / r1 with the
    open-loop o(s) = m s^2 + b s and closed-loop p(s) = m s^2 + (b + K_v) s + K_e gives
    K_e = sqrt(q2 / r1) and (b + K_v)^2 = b^2 + q1 / r1 + 2 m K_e.
    """
    q1, q2, r1 = weights(design)
    m, b = robot.mass, robot.fluid_friction
    k_e = math.sqrt(q2 / r1)
    return math.sqrt(b * b + q1 / r1 + 2 * m * k_e) - b, k_e


# -- LQR (eqs. 3.108-3.111)

@pytest.mark.parametrize('type_id', TYPE_IDS)
def test_lqr_gains_match_the_riccati_closed_form_and_are_stable(type_id, record_property):
    robot = TYPES[type_id]
    gains = design_lqr(robot, DESIGN)
    k_v, k_e = closed_form_gains(robot, DESIGN)
    assert gains.k_v == pytest.approx(k_v, rel=1e-9)
    assert gains.k_e == pytest.approx(k_e, rel=1e-9) and k_e == pytest.approx(7.5)
    a, b = design_model(robot)
    a_cl = a - b @ np.array([[gains.k_v, gains.k_e]])
    np.testing.assert_allclose(closed_loop(robot, gains)[0], a_cl, atol=1e-12)
    poles = np.linalg.eigvals(a_cl)
    assert (poles.real < 0).all()
    # Characteristic polynomial m s^2 + (b + K_v) s + K_e.
    np.testing.assert_allclose(np.sort_complex(poles), np.sort_complex(
        np.roots([robot.mass, robot.fluid_friction + k_v, k_e])), rtol=1e-9)
    record_property('gains', {'k_v': gains.k_v, 'k_e': gains.k_e, 'poles': str(poles)})
    print(f'type {type_id}: K_v={gains.k_v:.3f} N s/m K_e={gains.k_e:.3f} N/m poles={poles}')


@pytest.mark.parametrize('type_id', TYPE_IDS)
def test_step_response_reaches_the_setpoint_with_small_overshoot(type_id):
    robot = TYPES[type_id]
    gains = design_lqr(robot, DESIGN)
    times, v = step_response(robot, gains, t_end=8.0)
    # V / V_ref = K_e / (m s^2 + (b + K_v) s + K_e): unit DC gain, no zero.
    m, c, k = robot.mass, robot.fluid_friction + gains.k_v, gains.k_e
    zeta = c / (2 * math.sqrt(m * k))
    assert 0.7 < zeta < 1.0
    overshoot = math.exp(-math.pi * zeta / math.sqrt(1 - zeta * zeta))
    assert v[-1] == pytest.approx(1.0, abs=1e-6)
    assert v.max() - 1.0 == pytest.approx(overshoot, abs=1e-4)
    assert v.max() - 1.0 < 0.02
    # 2 % settling within the envelope bound 4 / (zeta w_n) of a second-order system.
    settle = times[np.flatnonzero(np.abs(v - 1.0) > 0.02)[-1] + 1]
    assert settle < 4.0 / (zeta * math.sqrt(k / m))
    # -3 dB bandwidth from the magnitude of the closed form at the reported frequency.
    w = bandwidth_rad_s(robot, gains)
    mag = k / abs(complex(k - m * w * w, c * w))
    assert mag == pytest.approx(1 / math.sqrt(2), rel=1e-2)
    assert 1.5 < w < 3.0


@pytest.mark.usefixtures('kernels')
@pytest.mark.parametrize('type_id', TYPE_IDS)
def test_velocity_loop_tracks_on_the_friction_model(type_id):
    """The integral state cancels dry friction: no steady-state error, small overshoot."""
    robot = TYPES[type_id]
    loop = VelocityLoop(design_lqr(robot, DESIGN),
                        u_max=DESIGN.u_max + 2 * robot.dry_friction * robot.mass * GRAVITY)
    sim = PointMassSwarm([robot], [[0.0, 0.0]])
    setpoint, dt = np.array([V_MAX * 0.6, V_MAX * 0.8]), 0.005
    trace = []
    for _ in range(int(10.0 / dt)):
        force = loop.step(dt, setpoint, sim.velocities[0])
        sim.step(dt, force[None])
        trace.append(sim.velocities[0].copy())
    trace = np.array(trace)
    np.testing.assert_allclose(trace[-1], setpoint, atol=1e-5)
    assert np.linalg.norm(trace, axis=1).max() < V_MAX * 1.02
    # The steady force balances fluid plus Coulomb friction.
    expected = robot.fluid_friction * V_MAX + robot.dry_friction * robot.mass * GRAVITY
    assert np.hypot(*force) == pytest.approx(expected, rel=1e-3)


# -- point-mass dynamics (dynamics.py)

def run_force(robots: list[RobotType], force: np.ndarray, seconds: float,
              dt: float = 0.002) -> tuple[PointMassSwarm, np.ndarray]:
    """Apply a constant force (N, 2) for ``seconds``; return the sim and speed history."""
    sim = PointMassSwarm(robots, np.zeros((len(robots), 2)))
    speeds = []
    for _ in range(int(round(seconds / dt))):
        sim.step(dt, force)
        speeds.append(np.linalg.norm(sim.velocities, axis=1))
    return sim, np.array(speeds)


@pytest.mark.usefixtures('kernels')
def test_constant_force_reaches_the_analytic_terminal_velocity():
    """m dv/dt = F - mu_2 v - mu_1 m g  =>  v_inf = (F - mu_1 m g) / mu_2, tau = m / mu_2."""
    robots = [TYPES[t] for t in TYPE_IDS]
    direction = np.array([0.6, -0.8])
    f = 6.0
    tau = np.array([r.mass / r.fluid_friction for r in robots])
    v_inf = np.array([(f - r.dry_friction * r.mass * GRAVITY) / r.fluid_friction
                      for r in robots])
    dt = 0.005      # the implicit scheme's bias is mu_1 g dt: under 0.1 % here
    sim, speeds = run_force(robots, np.tile(f * direction, (3, 1)), 9 * tau.max(), dt)
    np.testing.assert_allclose(np.linalg.norm(sim.velocities, axis=1), v_inf, rtol=2e-3)
    np.testing.assert_allclose(sim.velocities / np.linalg.norm(sim.velocities, axis=1)[:, None],
                               np.tile(direction, (3, 1)), atol=1e-12)
    # After one time constant: v_inf (1 - 1/e).
    at_tau = speeds[np.round(tau / dt).astype(int) - 1, np.arange(3)]
    np.testing.assert_allclose(at_tau, v_inf * (1 - math.exp(-1)), rtol=5e-3)


@pytest.mark.usefixtures('kernels')
def test_a_force_that_is_not_finite_acts_as_numpy_makes_it_finite():
    """NaN is no force, an infinity the largest float (np.nan_to_num): a controller's
    bad output moves no robot to NaN."""
    robots = [TYPES[1]] * 4
    bad = np.array([[np.nan, 1.0], [np.inf, -2.0], [-np.inf, np.nan], [3.0, -4.0]])
    raw, clean = (PointMassSwarm(robots, np.zeros((4, 2))) for _ in range(2))
    with np.errstate(over='ignore'):     # the largest float over a mass overflows
        raw.step(0.02, bad)
        clean.step(0.02, np.nan_to_num(bad))
    assert np.array_equal(raw.positions, clean.positions)
    assert np.array_equal(raw.velocities, clean.velocities)
    assert np.isfinite(raw.positions[[0, 3]]).all()


@pytest.mark.usefixtures('kernels')
def test_force_below_coulomb_friction_does_not_move_a_robot_at_rest():
    robots = [TYPES[t] for t in TYPE_IDS]
    break_away = np.array([r.dry_friction * r.mass * GRAVITY for r in robots])
    assert break_away[2] > DESIGN.u_max      # type 3 cannot start with u_max = 3 N alone
    forces = np.column_stack([0.99 * break_away, np.zeros(3)])
    sim, speeds = run_force(robots, forces, 2.0)
    assert (speeds == 0.0).all() and (sim.positions == 0.0).all()
    sim, speeds = run_force(robots, np.column_stack([1.01 * break_away, np.zeros(3)]), 2.0)
    assert (speeds[-1] > 0.0).all()


@pytest.mark.usefixtures('kernels')
def test_sliding_robot_stops_in_the_analytic_time():
    """Unforced: m dv/dt = -mu_2 v - mu_1 m g  =>  t_stop = (m / mu_2) ln(1 + mu_2 v0 / F_c)."""
    robots = [TYPES[t] for t in TYPE_IDS]
    v0, dt = 0.5, 0.001
    sim = PointMassSwarm(robots, np.zeros((3, 2)), np.tile([v0, 0.0], (3, 1)))
    stopped = np.full(3, np.nan)
    for k in range(1, 2001):
        sim.step(dt, np.zeros((3, 2)))
        newly = (np.linalg.norm(sim.velocities, axis=1) == 0.0) & np.isnan(stopped)
        stopped[newly] = k * dt
    expected = [r.mass / r.fluid_friction * math.log(
        1 + r.fluid_friction * v0 / (r.dry_friction * r.mass * GRAVITY)) for r in robots]
    np.testing.assert_allclose(stopped, expected, atol=2 * dt)
    assert (sim.velocities == 0.0).all()       # stopped exactly, no chattering


# -- velocity setpoint generator (3.2.4, Fig. 3.32)

@pytest.mark.usefixtures('kernels')
def test_setpoint_saturates_at_half_a_metre_per_second():
    params = SetpointParams()
    assert params.v_max == V_MAX
    far = velocity_setpoint([0.0, 0.0], [30.0, 40.0], params)
    np.testing.assert_allclose(far, [0.3, 0.4], atol=1e-12)    # 0.5 m/s towards the goal
    near = velocity_setpoint([0.0, 0.0], [0.3, 0.4], params)   # 0.5 m away
    np.testing.assert_allclose(near, params.gain * np.array([0.3, 0.4]), atol=1e-12)
    assert np.hypot(*velocity_setpoint([0, 0], [0.01, 0.0], params)) == 0.0   # arrived
    # Along a path: aim at the next waypoint, speed from the remaining path length.
    path = np.array([[0.0, 0.0], [0.0, 0.5], [10.0, 0.5]])
    v = velocity_setpoint(path[0], path[-1], params, waypoints=path)
    np.testing.assert_allclose(v, [0.0, V_MAX], atol=1e-12)
    # Crowded by neighbours on every side: still at most 0.5 m/s.
    ring = np.array([[np.cos(a), np.sin(a)] for a in np.linspace(0, 5, 6)]) * 0.35
    crowded = avoid_collisions(far, ring, np.full(6, 0.3), 0.5, params)
    assert np.hypot(*crowded) <= V_MAX + 1e-12


# -- collision avoidance: the safety filter of swarm_agent.setpoint

def _gap_bounds(v, offsets, radii, own, params):
    """u_j . v - (rate / 2) h_j for every neighbour: <= 0 means the constraint holds."""
    d = np.linalg.norm(offsets, axis=1)
    gap = d - (own + radii + params.avoid_buffer)
    return (offsets / d[:, None]) @ v - 0.5 * params.avoid_rate * gap


@pytest.mark.usefixtures('kernels')
def test_filter_leaves_free_motion_alone_and_bounds_the_closing_speed():
    params = SetpointParams(swerve=0.0)
    v = np.array([0.5, 0.0])
    # Nobody near, or a neighbour behind: unchanged.
    np.testing.assert_array_equal(avoid_collisions(v, np.zeros((0, 2)), [], 0.3, params), v)
    np.testing.assert_array_equal(avoid_collisions(v, [[-0.7, 0.0]], [0.3], 0.3, params), v)
    # A neighbour ahead 0.5 m beyond the buffer: closing speed rate/2 * 0.5 = 0.25 m/s.
    ahead = [[0.3 + 0.3 + params.avoid_buffer + 0.5, 0.0]]
    np.testing.assert_allclose(avoid_collisions(v, ahead, [0.3], 0.3, params),
                               [0.5 * params.avoid_rate * 0.5, 0.0], atol=1e-12)
    # Motion across the line to the neighbour is free.
    across = np.array([0.0, 0.4])
    np.testing.assert_allclose(avoid_collisions(across, ahead, [0.3], 0.3, params), across)


@pytest.mark.usefixtures('kernels')
def test_a_parked_robot_yields_to_a_neighbour_inside_the_buffer():
    params = SetpointParams()
    inside = 0.15 + 0.15 + params.avoid_buffer - 0.2      # 0.2 m inside the buffer
    v = avoid_collisions(np.zeros(2), [[0.0, inside]], [0.15], 0.15, params)
    np.testing.assert_allclose(v, [0.0, -0.5 * params.avoid_rate * 0.2], atol=1e-9)
    # At the buffer's edge it stays parked.
    edge = [[0.0, 0.15 + 0.15 + params.avoid_buffer + 0.01]]
    assert not avoid_collisions(np.zeros(2), edge, [0.15], 0.15, params).any()


@pytest.mark.usefixtures('kernels')
def test_a_parked_robot_with_a_yield_margin_steps_aside_before_contact():
    """yield_margin (hardware: goals 0.34 m apart): a robot squeezing past a parked one
    at the buffer's edge moves it aside; without the margin it would wedge."""
    params = SetpointParams(avoid_buffer=0.0, yield_margin=0.03)
    at_edge = [[0.0, 0.16 + 0.11 + 0.01]]       # 1 cm beyond contact, inside the margin
    moving = avoid_collisions(np.zeros(2), at_edge, [0.11], 0.16, params)
    parked = avoid_collisions(np.zeros(2), at_edge, [0.11], 0.16, params, parked=True)
    assert not moving.any()
    np.testing.assert_allclose(parked, [0.0, -0.5 * params.avoid_rate * 0.02], atol=1e-12)


@pytest.mark.usefixtures('kernels')
def test_filter_is_the_closest_safe_velocity():
    """The exact two-variable QP: never worse than SLSQP on random cases."""
    from scipy.optimize import minimize
    params = SetpointParams(swerve=0.0, v_max=10.0)
    rng = np.random.default_rng(3)
    for _ in range(30):
        k = rng.integers(1, 5)
        offsets = rng.uniform(-1.5, 1.5, (k, 2))
        radii = rng.uniform(0.15, 0.5, k)
        want = rng.uniform(-1.0, 1.0, 2)
        got = avoid_collisions(want, offsets, radii, 0.3, params)
        cons = {'type': 'ineq', 'fun': lambda v, *a: -_gap_bounds(v, *a),
                'args': (offsets, radii, 0.3, params)}
        best = minimize(lambda v, w: np.sum((v - w) ** 2), np.zeros(2), args=(want,),
                        constraints=[cons],
                        method='SLSQP', options={'ftol': 1e-12})
        if not best.success:
            continue
        assert np.all(_gap_bounds(got, offsets, radii, 0.3, params) <= 1e-6)
        assert np.sum((got - want) ** 2) <= best.fun + 1e-6


# -- artificial forces (3.2.1.1, eqs. 3.80-3.93)

HALF = 2.0


def square_contour(step: float = 0.01) -> np.ndarray:
    """Equally spaced samples of the square [-2, 2]^2 boundary (eq. 3.82), closed."""
    n = int(round(2 * HALF / step))
    s = np.linspace(-HALF, HALF, n, endpoint=False)
    return np.vstack([np.column_stack([s, np.full(n, -HALF)]),
                      np.column_stack([np.full(n, HALF), s]),
                      np.column_stack([-s, np.full(n, HALF)]),
                      np.column_stack([np.full(n, -HALF), -s])])


CONTOUR = square_contour()


def shape_force(position, inside: bool, params: ForceParams | None = None) -> np.ndarray:
    """Boundary forces only (no neighbours, no obstacles) on an agent of radius 0.15 m."""
    return formation_force(position, np.zeros(2), inside, CONTOUR, None, None, 0.15, None,
                           params or ForceParams())


def test_agents_outside_the_shape_are_pulled_inwards():
    params = ForceParams()
    rng = np.random.default_rng(3)
    for angle in rng.uniform(0, 2 * np.pi, 20):
        z = np.array([np.cos(angle), np.sin(angle)]) * rng.uniform(3.0, 20.0)
        if np.abs(z).max() <= HALF + params.buffer:
            continue
        f = shape_force(z, inside=False)
        assert np.dot(f, -z) > 0.95 * np.linalg.norm(f) * np.linalg.norm(z)
    # Far away, eq. 3.81 is k_a (centroid - z) and eq. 3.89 is k_t l(C) along the unit
    # vector (the contour integral of unit vectors that all point the same way).
    z = np.array([60.0, 0.0])
    expected = params.k_a * -z + params.k_t * 8 * HALF * np.array([-1.0, 0.0])
    np.testing.assert_allclose(shape_force(z, inside=False), expected, rtol=1e-3, atol=1.0)


def test_boundary_repels_inside_agents_towards_the_middle():
    assert np.linalg.norm(shape_force([0.0, 0.0], inside=True)) < 1e-6 * ForceParams().k_r
    for z in ([1.9, 0.0], [0.0, -1.9], [-1.8, 1.7]):
        f = shape_force(z, inside=True)
        assert np.dot(f, z) < 0 and np.linalg.norm(f) > ForceParams().k_r


def test_inside_agents_are_pushed_apart_by_eq_3_88():
    params = ForceParams()
    a, b, r = np.array([0.3, 0.0]), np.array([-0.3, 0.0]), 0.15
    f_a = formation_force(a, np.zeros(2), True, CONTOUR, [b], [r], r, None, params)
    f_b = formation_force(b, np.zeros(2), True, CONTOUR, [a], [r], r, None, params)
    assert np.dot(f_a, a - b) > 0 and np.dot(f_b, b - a) > 0
    np.testing.assert_allclose(f_a, -f_b, atol=1e-9)          # symmetric pair
    # Member part: k_m (z_i - z_j) / d / (d - d_o)^2 with d_o = r_i + r_j (eq. 3.87),
    # shifted by its value at member_range so that it vanishes there without a jump.
    member = f_a - shape_force(a, inside=True, params=params)
    d, d_o = 0.6, 2 * r
    shift = params.k_m / (params.member_range - d_o) ** 2
    np.testing.assert_allclose(member, [params.k_m / (d - d_o) ** 2 - shift, 0.0],
                               rtol=1e-12)
    # Beyond member_range a neighbour exerts nothing.
    far = formation_force(a, np.zeros(2), True, CONTOUR, [[0.3, params.member_range + 1]],
                          [r], r, None, params)
    np.testing.assert_allclose(far, shape_force(a, inside=True, params=params))


def test_obstacle_samples_repel_by_eq_3_93():
    params = ForceParams()
    obstacle = np.column_stack([np.full(201, 1.0), np.linspace(-1, 1, 201)])   # wall x = 1
    f = formation_force([0.0, 0.0], np.zeros(2), True, CONTOUR, None, None, 0.15, obstacle,
                        params) - shape_force([0.0, 0.0], inside=True, params=params)
    assert f[0] < 0 and abs(f[1]) < 1e-9 * abs(f[0])
    step = 0.01
    gap = np.hypot(1.0, obstacle[:, 1]) - 0.15
    expected = params.k_o * step * np.sum(-1.0 / gap ** 4)
    assert f[0] == pytest.approx(expected, rel=1e-9)


# -- swarm_eval.lqr_report (scripts/lqr_report.py)

def test_lqr_report_writes_gains_and_step_plot(tmp_path, capsys):
    from swarm_eval import lqr_report

    assert lqr_report.main(['--out', str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert 'Table 4.2' in printed and 'differ' in printed
    data = json.loads((tmp_path / 'lqr.json').read_text(encoding='utf-8'))
    assert (tmp_path / 'step.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert sorted(data['types']) == ['1', '2', '3']
    for type_id, entry in data['types'].items():
        robot = TYPES[int(type_id)]
        ours, table = entry['ours'], entry['table_4_2']
        k_v, k_e = closed_form_gains(robot, DESIGN)
        assert ours['k_v'] == pytest.approx(k_v) and ours['k_e'] == pytest.approx(k_e)
        assert all(re < 0 for re, _ in ours['poles'] + table['poles'])
        assert ours['overshoot_percent'] < 2.0 and table['overshoot_percent'] == 0.0
        assert (table['k_e'], table['k_v']) == lqr_report.TABLE_4_2[int(type_id)]
        # The weights reported as needed for a Table 4.2 row do reproduce it.
        fit = table['fit']
        refit = design_lqr(robot, LqrDesign(t1=1.0 / fit['q1'], u_max=fit['u1max_N']))
        assert (refit.k_e, refit.k_v) == pytest.approx((table['k_e'], table['k_v']), rel=1e-6)
    assert lqr_report.main(['--robot-types', str(tmp_path / 'missing.yaml')]) == 2


def test_control_yaml_states_the_setpoint_and_forces_defaults():
    """config/control.yaml documents SetpointParams and ForceParams: keep them equal."""
    import pathlib

    path = (pathlib.Path(__file__).resolve().parents[3] / 'ros2_ws' / 'src' / 'swarm_agent'
            / 'config' / 'control.yaml')
    data = yaml.safe_load(path.read_text())
    for section, params in (('setpoint', SetpointParams()), ('forces', ForceParams())):
        defaults = dataclasses.asdict(params)
        assert set(data[section]) <= set(defaults), f'{section}: unknown keys'
        for key, value in data[section].items():
            assert defaults[key] == pytest.approx(value), f'{section}.{key}'


def test_the_compiled_point_masses_step_as_their_source_to_the_bit():
    """The point-mass kernel compiled gives the very numbers of its Python source (one
    step of 50 robots with random states and forces, some of them stopping)."""
    from swarm_agent.dynamics import _step
    from swarm_common import jit
    rng = np.random.default_rng(3)
    robots = [TYPES[t] for t in rng.choice(TYPE_IDS, 50)]
    sim = PointMassSwarm(robots, rng.uniform(-20, 20, (50, 2)),
                         rng.normal(0.0, 0.3, (50, 2)) * (rng.random((50, 1)) < 0.8))
    forces = rng.normal(0.0, 8.0, (50, 2))
    args = (sim.positions, sim.velocities, forces, sim.mass, sim.fluid, sim.dry, GRAVITY, 0.02)
    compiled = _step(*args)
    jit.use_python(True)
    try:
        source = _step(*args)
    finally:
        jit.use_python(False)
    for a, b in zip(compiled, source):
        np.testing.assert_array_equal(a, b)
    assert (np.hypot(*compiled[1].T) == 0.0).any()     # some robots stopped by dry friction
