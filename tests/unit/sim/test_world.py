"""The pybullet world (thesis 4.1): Table 4.1 dynamics, rough terrain, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry import box, Polygon

pytest.importorskip('pybullet')

from swarm_agent.dynamics import PointMassSwarm  # noqa: E402
from swarm_common.fleet import RobotSpec  # noqa: E402
from swarm_common.robot_types import GRAVITY, load_robot_types  # noqa: E402
from swarm_sim.world import PybulletBackend, robot_geometry, WorldError  # noqa: E402

TYPES = load_robot_types()
DT = 0.01


def one_robot(type_id: int, x: float = 0.0, y: float = 0.0, **kwargs) -> PybulletBackend:
    kwargs.setdefault('terrain', 'flat')
    return PybulletBackend([RobotSpec(0, type_id, False, x, y)], TYPES, **kwargs)


def test_pushed_robots_reach_the_terminal_velocity_of_table_4_1():
    """F = mu_1 m g + mu_2 v_t drives each type to v_t = 0.5 m/s, as the point-mass model.

    One robot of each type, side by side on flat ground, pushed from rest for four time
    constants m / mu_2 of the slowest type (46 s). The speed is then
    v_t (1 - exp(-t mu_2 / m)) analytically. Bullet applies the damping exactly per
    step and the Coulomb friction through its contact solver; the step-order difference
    is about (mu_2 / m) h / 2 = 0.1 %. A 2 % tolerance leaves room for the solver and
    the landing, and still catches a wrong mass, friction product or damping (each
    type's mu_1 m g is 1.6..2.9 N of a 1.7..3.0 N push, so a 10 % friction error moves
    v_t by 30..80 %).

    The point-mass model (swarm_agent.dynamics) at the same 10 ms step is compared too:
    its dry-friction impulse acts before the implicit damping, so it has no terminal
    speed bias and the two models must agree within the same 2 %.
    """
    ids = [1, 2, 3]
    types = [TYPES[k] for k in ids]
    v_t = 0.5
    force = np.array([[t.dry_friction * t.mass * GRAVITY + t.fluid_friction * v_t, 0.0]
                      for t in types])
    tau = np.array([t.mass / t.fluid_friction for t in types])
    duration = 4.0 * tau.max()
    start = [[-45.0, -10.0], [-45.0, 0.0], [-45.0, 10.0]]
    fleet = [RobotSpec(i, k, False, x, y) for i, (k, (x, y)) in enumerate(zip(ids, start))]
    world = PybulletBackend(fleet, TYPES, terrain='flat', half_size=50.0)
    model = PointMassSwarm(types, start)
    try:
        for _ in range(20):                       # land first
            world.step(DT, np.zeros((3, 2)))
        for _ in range(int(round(duration / DT))):
            world.step(DT, force)
            model.step(DT, force)
        v = world.velocities()
        expected = v_t * (1.0 - np.exp(-duration / tau))
        np.testing.assert_allclose(v[:, 0], expected, rtol=0.02)
        assert np.all(expected > 0.98 * v_t)
        np.testing.assert_allclose(v[:, 0], model.velocities[:, 0], rtol=0.02)
        assert np.all(np.abs(v[:, 1]) < 0.01)
        assert np.all(world.tilts() < math.radians(2.0))
    finally:
        world.close()


@pytest.mark.parametrize('type_id', [1, 3])
def test_a_push_below_dry_friction_does_not_move_a_robot(type_id):
    t = TYPES[type_id]
    world = one_robot(type_id)
    try:
        for _ in range(20):
            world.step(DT, np.zeros((1, 2)))
        start = world.positions()
        push = np.array([[0.8 * t.dry_friction * t.mass * GRAVITY, 0.0]])
        for _ in range(200):
            world.step(DT, push)
        assert np.linalg.norm(world.positions() - start) < 0.01
    finally:
        world.close()


def test_rough_terrain_matches_its_height_map():
    """The heightfield is where the generator put it (orientation and vertical offset)."""
    world = one_robot(2, terrain='rough', half_size=10.0, seed=4)
    try:
        rng = np.random.default_rng(1)
        xy = rng.uniform(-9.0, 9.0, (100, 2))
        xy = xy[np.linalg.norm(xy, axis=1) > 0.5]          # not on the robot
        ground = world.ground_height(xy)
        assert np.nanmax(np.abs(ground - world.heightmap.height_at(xy))) < 0.005
        assert world.heightmap.z.std() > 0.1
    finally:
        world.close()


def test_robots_on_rough_terrain_stay_upright_on_the_ground_and_inside():
    """Six robots pushed around at random for 20 s on rough ground."""
    fleet = [RobotSpec(i, 1 + i % 3, False, -6.0 + 2.5 * i, 1.5 * (-1) ** i)
             for i in range(6)]
    world = PybulletBackend(fleet, TYPES, terrain='rough', half_size=10.0, seed=2,
                            roughness=0.15)
    rng = np.random.default_rng(3)
    mass = np.array([TYPES[r.type].mass for r in fleet])
    max_tilt = 0.0
    try:
        for k in range(2000):
            if k % 100 == 0:
                heading = rng.uniform(-np.pi, np.pi, len(fleet))
                forces = (3.0 * mass)[:, None] * np.column_stack([np.cos(heading),
                                                                  np.sin(heading)])
            world.step(DT, forces)
            if k % 50 == 0:
                max_tilt = max(max_tilt, float(world.tilts().max()))
        assert world.time == pytest.approx(20.0)
        pos = world.positions()
        assert np.all(np.abs(pos) < 10.0)
        assert max_tilt < math.radians(30.0)
        radius = np.array([robot_geometry(TYPES[r.type])[0] for r in fleet])
        clearance = world.heights() - world.heightmap.height_at(pos)
        # The centre sits one sphere radius above the ground, give or take the bumps.
        assert np.all(clearance > 0.0)
        assert np.all(clearance < radius + 0.3)
    finally:
        world.close()


def test_sim_time_and_steps_follow_the_fixed_physics_rate():
    world = one_robot(1, physics_hz=100.0)
    try:
        zero = np.zeros((1, 2))
        for _ in range(50):
            world.step(0.01, zero)
        assert world.steps == 50
        assert world.time == pytest.approx(0.5)
        world.step(0.05, zero)                 # sub-stepped: five 10 ms steps
        assert world.steps == 55
        assert world.time == pytest.approx(0.55)
        world.step(0.015, zero)                # two 7.5 ms steps, never longer than 10 ms
        assert world.steps == 57
        assert world.time == pytest.approx(0.565)
        with pytest.raises(ValueError, match='dt'):
            world.step(float('nan'), zero)
        with pytest.raises(ValueError, match='shape'):
            world.step(0.01, np.zeros((2, 2)))
    finally:
        world.close()


def test_interface_matches_the_point_mass_backend():
    fleet = [RobotSpec(i, 1 + i % 3, False, 3.0 * i, 0.0, yaw=0.3 * i) for i in range(3)]
    world = PybulletBackend(fleet, TYPES, terrain='flat', half_size=20.0)
    try:
        assert world.name == 'pybullet'
        world.step(DT, np.zeros((3, 2)))
        for out in (world.positions(), world.velocities(), world.accelerations()):
            assert out.shape == (3, 2) and np.all(np.isfinite(out))
        np.testing.assert_allclose(world.positions(), [[0, 0], [3, 0], [6, 0]], atol=1e-3)
        np.testing.assert_allclose(world.yaws(), [0.0, 0.3, 0.6], atol=1e-3)
        # Accelerations: (F - mu_1 m g - mu_2 v) / m, per step or averaged between reads.
        t = TYPES[2]
        push = np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 0.0]])
        for k in range(30):
            world.step(DT, push)
            if k < 10 or k == 29:
                v = world.velocities()[1, 0]
                expected = (5.0 - t.dry_friction * t.mass * GRAVITY - t.fluid_friction * v) \
                    / t.mass
                assert world.accelerations()[1, 0] == pytest.approx(expected, rel=0.05)
        assert np.abs(world.accelerations()[[0, 2]]).max() < 1e-3
    finally:
        world.close()


def test_gui_visuals_build_in_direct_mode():
    """The GUI's visual shapes (spheres, cylindrical links, prisms) build without a display."""
    ell = Polygon([(2, -3), (4, -3), (4, 3), (-2, 3), (-2, 1), (2, 1)])
    fleet = [RobotSpec(i, 1 + i, False, -6.0 + 2.0 * i, -6.0) for i in range(3)]
    world = PybulletBackend(fleet, TYPES, obstacles=[ell], terrain='rough', half_size=10.0,
                            visuals=True)
    try:
        world.step(DT, np.ones((3, 2)))
        assert np.all(np.isfinite(world.positions()))
    finally:
        world.close()


def test_non_finite_and_huge_forces_are_sanitised_and_counted():
    fleet = [RobotSpec(i, 2, False, -5.0 + 5.0 * i, 0.0) for i in range(3)]
    world = PybulletBackend(fleet, TYPES, terrain='flat', half_size=20.0, max_force=10.0)
    try:
        bad = np.array([[np.nan, 1.0], [np.inf, -np.inf], [1e9, 0.0]])
        for _ in range(100):
            world.step(DT, bad)
        assert world.rejected_forces == 200
        assert world.clipped_forces == 100
        pos, vel = world.positions(), world.velocities()
        assert np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))
        assert np.linalg.norm(vel[:2], axis=1).max() < 1e-3        # NaN became zero
        t = TYPES[2]
        # The clipped robot moves as under 10 N: after 1 s at most (10/m - mu_1 g) * 1 s.
        assert 0.5 < vel[2, 0] <= (10.0 / t.mass - t.dry_friction * GRAVITY) * 1.0 + 1e-3
    finally:
        world.close()


@pytest.mark.parametrize('spec, obstacles, match', [
    (RobotSpec(0, 7, False, 0.0, 0.0), [], 'unknown robot type 7'),
    (RobotSpec(0, 1, False, 49.95, 0.0), [], 'outside the workspace'),
    (RobotSpec(0, 3, False, 0.0, -60.0), [], 'outside the workspace'),
    (RobotSpec(0, 1, False, float('nan'), 0.0), [], 'not finite'),
    (RobotSpec(0, 2, False, 5.0, 5.0), [box(4.0, 4.0, 6.0, 6.0)], 'inside an obstacle'),
    (RobotSpec(0, 3, False, 6.3, 5.0), [box(4.0, 4.0, 6.0, 6.0)], 'overlapping an obstacle'),
])
def test_bad_spawns_are_rejected_with_a_clear_error(spec, obstacles, match):
    with pytest.raises(WorldError, match=match):
        PybulletBackend([spec], TYPES, obstacles=obstacles, terrain='flat')


def test_overlapping_robots_and_bad_terrain_are_rejected():
    a, b = RobotSpec(0, 3, False, 0.0, 0.0), RobotSpec(1, 3, False, 0.8, 0.0)
    with pytest.raises(WorldError, match='robots 0 and 1 overlap'):
        PybulletBackend([a, b], TYPES, terrain='flat')
    with pytest.raises(WorldError, match='unknown terrain'):
        PybulletBackend([a], TYPES, terrain='lunar')
    with pytest.raises(ValueError):
        PybulletBackend([a], TYPES, obstacles=['not a polygon'], terrain='flat')


def test_concave_obstacles_and_walls_stop_robots():
    """An L-shaped obstacle (triangulated into prisms) and the wall hold pushed robots."""
    ell = Polygon([(2, -3), (4, -3), (4, 3), (-2, 3), (-2, 1), (2, 1)])
    fleet = [RobotSpec(0, 1, False, 0.0, -1.0), RobotSpec(1, 2, False, 0.0, -7.0)]
    world = PybulletBackend(fleet, TYPES, obstacles=[ell], terrain='flat', half_size=10.0)
    push = np.array([[5.0, 0.0], [0.0, -5.0]])   # into the L's inner face; into the wall
    try:
        for _ in range(600):
            world.step(DT, push)
        pos = world.positions()
        # Half the body's width along an axis: corner offset plus sphere radius.
        reach = [sum(robot_geometry(TYPES[k])[::-1]) for k in (1, 2)]
        assert 2.0 - reach[0] - 0.02 < pos[0, 0] < 2.0 - reach[0] + 0.01   # face x = 2
        assert -10.0 + reach[1] - 0.01 < pos[1, 1] < -10.0 + reach[1] + 0.02  # wall
    finally:
        world.close()


def test_removed_robots_and_moved_obstacles():
    fleet = [RobotSpec(i, 1, False, -4.0 + 4.0 * i, 0.0) for i in range(3)]
    world = PybulletBackend(fleet, TYPES, obstacles=[box(-1, 4, 1, 6)], terrain='flat',
                            half_size=10.0)
    try:
        world.step(DT, np.zeros((3, 2)))
        last = world.positions()[1].copy()
        world.remove(1)
        world.remove(1)                                   # idempotent
        for _ in range(50):
            world.step(DT, np.full((3, 2), 3.0))
        assert not world.alive[1]
        np.testing.assert_allclose(world.positions()[1], last)
        assert np.all(world.velocities()[1] == 0.0)
        assert np.all(world.velocities()[[0, 2], 0] > 0.0)
        world.move_obstacle(0, 0.0, -5.0)
        assert world.obstacles[0].bounds == (-1.0, -1.0, 1.0, 1.0)
        assert world.ground_height([[0.0, 0.0]])[0] > 0.5   # the prism is now there
    finally:
        world.close()
