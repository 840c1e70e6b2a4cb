"""The world model (swarm_sim.world_model): one object for sim_node and the evaluator.

Driven through a scripted backend whose motion is known, so the figures are first
principles: sensor periods counted in physics steps, the IMU's mean acceleration over
its period, force limits, faults, scheduled events, and the same object behind the
headless evaluator and sim_node's parameters.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry import box

from swarm_agent.packet import BROADCAST, Packet
from swarm_common.fleet import RobotSpec
from swarm_common.robot_types import load_robot_types
from swarm_sim.medium import MediumConfig, RadioMedium
from swarm_sim.physics import PhysicsBackend, PointMassBackend
from swarm_sim.world_model import World, WorldConfig

TYPES = load_robot_types()


class ScriptedBackend:
    """Robots moving at velocity ``a * t`` (constant acceleration ``a``), whatever the
    force; it records the forces it was given."""

    name = 'scripted'
    body_contacts = None

    def __init__(self, start, accel) -> None:
        self.start = np.array(start, dtype=float)
        self.accel = np.array(accel, dtype=float)
        self.t = 0.0
        self.forces: list[np.ndarray] = []
        self.removed: list[int] = []
        self.moved: list[tuple[int, float, float]] = []

    def step(self, dt, forces) -> None:
        self.forces.append(np.array(forces))
        self.t += dt

    def positions(self):
        return self.start + 0.5 * self.accel * self.t ** 2

    def velocities(self):
        return self.accel * self.t

    def yaws(self):
        return np.zeros(len(self.start))

    def count_body_contacts(self, pairs):
        return None

    def remove(self, i) -> None:
        self.removed.append(i)

    def move_obstacle(self, k, dx, dy) -> None:
        self.moved.append((k, dx, dy))

    def close(self) -> None:
        pass


FLEET = [RobotSpec(0, 1, True, 0.0, 0.0), RobotSpec(1, 1, True, 6.0, 0.0),
         RobotSpec(2, 1, False, 3.0, 4.0), RobotSpec(3, 2, False, 40.0, 0.0)]


def _world(accel=None, obstacles=(), **config) -> World:
    accel = np.zeros((len(FLEET), 2)) if accel is None else accel
    backend = ScriptedBackend([[r.x, r.y] for r in FLEET], accel)
    rng = np.random.default_rng(0)
    world = World(FLEET, TYPES, backend, WorldConfig(**config), rng, obstacles,
                  RadioMedium(MediumConfig(range_noise_std=0.0), rng, obstacles))
    world.imu.bias[:] = 0.0
    world.imu.noise_std = 0.0
    return world


def test_both_backends_declare_the_physics_interface():
    assert isinstance(PointMassBackend(FLEET, TYPES), PhysicsBackend)
    assert isinstance(ScriptedBackend([[0, 0]], [[0, 0]]), PhysicsBackend)
    pytest.importorskip('pybullet')
    from swarm_sim.world import PybulletBackend
    world = PybulletBackend(FLEET, TYPES, terrain='flat', half_size=45.0)
    try:
        assert isinstance(world, PhysicsBackend)
    finally:
        world.close()


def test_sensor_periods_are_counted_in_physics_steps():
    """At 100 Hz physics: IMU and proximity every 10 steps, ranges and GPS every 100,
    radio batches every 5, truth every 50, from the first step on."""
    world = _world()
    due = {k: [] for k in ('rx', 'imu', 'ranges', 'proximity', 'gps', 'truth')}
    for step in range(1, 201):
        world.step()
        readings = world.sense()
        for key in due:
            if getattr(readings, key) is not None:
                due[key].append(step)
    assert due['imu'] == due['proximity'] == list(range(1, 201, 10))
    assert due['ranges'] == due['gps'] == [1, 101]
    assert due['rx'] == list(range(1, 201, 5))
    assert due['truth'] == [1, 51, 101, 151]
    assert world.t == pytest.approx(2.0)


def test_a_late_report_samples_what_is_due_and_the_next_a_period_later():
    """Reports every 7 steps: the IMU (period 10 steps) is sampled at the first report at
    or after each due step, and the next one is due a period after that report."""
    world = _world()
    sampled = []
    for _ in range(8):
        for _ in range(7):
            world.step()
        if world.sense().imu is not None:
            sampled.append(world.steps)
    assert sampled == [7, 21, 35, 49]


def test_the_imu_reports_the_mean_acceleration_over_its_period():
    """v = a t: the mean acceleration over any interval is a, sampled every 10 steps or
    late; the first sample divides by the period (the robot was at rest before t = 0)."""
    accel = np.array([[0.3, -0.1], [0.0, 0.2], [1.0, 1.0], [0.0, 0.0]])
    world = _world(accel)
    for steps in (10, 10, 25, 10):
        for _ in range(steps):
            world.step()
        readings = world.sense()
        assert readings.imu is not None
        np.testing.assert_allclose(readings.imu, accel, atol=1e-12)


def test_forces_are_limited_refused_timed_out_and_zero_for_the_removed():
    world = _world(max_force=10.0, command_timeout_s=0.5)
    refused, clamped = world.command([[30.0, 40.0], [math.nan, 1.0], [1.0, 2.0], [0.0, 0.0]])
    assert refused == [1] and clamped == [0]
    world.step()
    np.testing.assert_allclose(world.backend.forces[-1], [[6, 8], [0, 0], [1, 2], [0, 0]])
    world.command([[math.inf, 0.0]], rows=[0])       # refused: the last valid one holds
    world.remove(2)
    world.step()
    np.testing.assert_allclose(world.backend.forces[-1], [[6, 8], [0, 0], [0, 0], [0, 0]])
    for _ in range(50):                              # 0.5 s later the command is stale
        world.step()
    assert not world.backend.forces[-1].any()


def test_ranges_go_to_the_living_non_beacons_and_not_from_the_removed():
    """TOA ranges (noise 0 here) to beacon neighbours within the radio range: beacons
    (0 and 1) have GPS and get none; robot 3, 34 m off, hears nobody; a removed beacon
    is ranged by nobody, before the links are refreshed too."""
    world = _world()
    world.step()
    ranges = dict(world.sense().ranges)
    assert sorted(ranges) == [2, 3]
    assert ranges[2] == [(0, 5.0, 0.0), (1, 5.0, 0.0)] and ranges[3] == []
    world.remove(1)
    for _ in range(100):
        world.step()
    ranges = dict(world.sense().ranges)
    assert sorted(ranges) == [2, 3] and ranges[2] == [(0, 5.0, 0.0)]
    assert world.backend.removed == [1]


def test_radio_frames_are_delivered_in_batches_with_their_delivery_time():
    world = _world(radio_period_s=0.05)
    world.step()
    world.sense()                                     # the first batch: nothing yet
    world.medium.transmit(world.t, Packet(source=0, destination=BROADCAST, kind=0,
                                          sequence=1, ttl=1, payload=b'hi'))
    batches = []
    for _ in range(10):
        world.step()
        rx = world.sense().rx
        if rx is not None:
            batches.append(rx)
    delivered = [(round(t, 2), sorted(receivers)) for t, _, receivers in batches[0]]
    assert delivered == [(0.02, [1, 2])]              # robot 3 is out of range
    assert batches[1] == []


def test_faults_on_command_name_what_they_ignore():
    world = _world(obstacles=[box(2.0, -1.0, 4.0, 1.0)])
    lines = world.inject('kill', [3, 99])
    assert lines[0].startswith('/swarm/kill: no robot [99] in the fleet')
    assert 'robot 3 removed' in lines[1] and not world.alive[3]
    assert world.inject('kill', [3]) == []            # already gone: nothing to do
    assert 'robot 0 radio off' in world.inject('radio_off', [0])[0]
    assert 'ignored' in world.inject('move_obstacle', [1.0, 0.0, 2.0])[0]   # no obstacle 1
    assert 'ignored' in world.inject('move_obstacle', [0.0, math.nan, 2.0])[0]
    assert 'moved by (0, 5) m' in world.inject('move_obstacle', [0.0, 0.0, 5.0])[0]
    assert world.backend.moved == [(0, 0.0, 5.0)]
    assert world.obstacles[0].centroid.y == pytest.approx(5.0)
    with pytest.raises(ValueError, match='unknown fault'):
        world.inject('explode', [0])
    with pytest.raises(ValueError, match='radio range must be a positive'):
        world.apply_setting('radio_range_m', -1.0)
    world.apply_setting('radio_wall_speed_mps', 2.0)
    assert world.medium.wall is not None and world.medium.wall.t0 == world.t


def test_scheduled_events_run_in_order_and_end_the_settled_streak():
    world = _world()
    ran = []
    world.schedule(0.5, lambda t: ran.append(('b', t)))
    world.schedule(0.2, lambda t: ran.append(('a', t)))
    world.schedule(0.5, lambda t: ran.append(('c', t)))
    world.settle.update(0.0, True)
    assert world.run_due(0.3) == 1 and world.settle.since is None
    assert world.pending == 2
    world.run_due(0.5)
    assert ran == [('a', 0.3), ('b', 0.5), ('c', 0.5)] and world.pending == 0


def test_a_bad_setting_is_refused_with_its_name():
    with pytest.raises(ValueError, match='world setting imu_period_s must be a positive'):
        _world(imu_period_s=0.0)
    with pytest.raises(ValueError, match='world setting proximity_std must be a finite'):
        _world(proximity_std=math.nan)


def test_the_evaluator_and_sim_node_build_the_same_world(tmp_path):
    """HeadlessSwarm runs a World over point masses; sim_node's parameters build one too."""
    from swarm_common.fleet import save_fleet
    from swarm_common.shapes import load_shape
    from swarm_sim.headless import HeadlessSwarm, Scenario
    from swarm_sim.sim_parameters import SIM_PARAMETERS, world_from_parameters

    swarm = HeadlessSwarm(Scenario(shape=load_shape('circle_314'),
                                   type_counts={1: 4}, n_beacons=3, duration_s=1.0))
    assert isinstance(swarm.world, World)
    assert isinstance(swarm.world.backend, PointMassBackend)
    assert swarm.world.alive is swarm.alive
    save_fleet(tmp_path / 'fleet.yaml', FLEET)
    params = {name: spec.default for name, spec in SIM_PARAMETERS.items()}
    params.update(fleet_file=str(tmp_path / 'fleet.yaml'), backend='pointmass')
    _, _, world = world_from_parameters(params)
    assert type(world) is World and world.dt == pytest.approx(0.01)
    assert world.ids == [0, 1, 2, 3]
