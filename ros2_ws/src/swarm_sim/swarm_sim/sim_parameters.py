"""sim_node's parameters, declared in one place, and the world they build.

Each entry is ``name: (default, description)``; config/sim.yaml repeats the defaults
(tests/unit/test_node_parameters.py checks that they agree).
"""

from __future__ import annotations

import math

import numpy as np

from swarm_common.fleet import load_fleet, place_fleet, PLACEMENT_STD_M, RobotSpec
from swarm_common.robot_types import load_robot_types, RobotType
from swarm_common.shapes import load_shape
from swarm_sim.medium import MediumConfig, RadioMedium
from swarm_sim.physics import make_backend
from swarm_sim.world_model import World, WorldConfig

PARAMETERS = {
    'fleet_file': ('', 'Fleet YAML: robots with id, type, beacon, x, y, yaw'),
    'placement_std_m': (PLACEMENT_STD_M, 'Robots spawn this far (m per axis, Gaussian, '
                                         'seeded) from their fleet positions, the '
                                         "agents' deployment prior"),
    'shape': ('', 'Shape spec whose obstacles populate the world (built-in or file)'),
    'backend': ('auto', 'Physics: pybullet, pointmass, or auto (pybullet if available)'),
    'physics_rate_hz': (100.0, 'Physics steps per simulated second'),
    'real_time_factor': (1.0, 'Target sim/wall speed ratio; 0 runs as fast as possible'),
    'clock_rate_hz': (50.0, 'Wall-clock rate of /clock updates and stepping batches'),
    'imu_rate_hz': (10.0, 'IMU samples per simulated second'),
    'gps_rate_hz': (1.0, 'Beacon GPS fixes per simulated second'),
    'gps_std': (2.0, 'GPS noise per axis (m), thesis 4.2'),
    'range_rate_hz': (1.0, 'TOA ranging rate per simulated second'),
    'radio_rate_hz': (20.0, 'Radio delivery batches per simulated second, per robot'),
    'proximity_rate_hz': (10.0, 'Proximity scans per simulated second; 0: no sensor'),
    'proximity_range_m': (3.0, 'Proximity sensor range (m): neighbours within it are seen'),
    'proximity_std': (0.02, 'Proximity offset noise per axis (m)'),
    'sensor_batch': (False, 'Publish imu, ranges, proximity and radio deliveries of every '
                            'robot in one /swarm/sensor_batch per step and take force '
                            'commands from /swarm/cmd_batch (composed agents) instead of '
                            'the per-robot topics'),
    'truth_rate_hz': (2.0, 'Ground-truth publication rate (sim time)'),
    'marker_rate_hz': (1.0, 'RViz marker rate on /swarm/markers (sim time); 0: none'),
    'command_timeout_s': (0.5, 'Force commands older than this are dropped to zero'),
    'max_agent_lag_s': (0.2, 'Sim time the world may run ahead of the slowest agent; 0: off'),
    'truth_subscribers': (0, 'Hold the clock at 0 until this many /swarm/truth subscribers '
                             "(e.g. the launcher's monitor) have matched, for at most "
                             'wait_for_agents_s'),
    'wait_for_agents_s': (60.0, "Wall seconds to wait for every robot's first command"),
    'agent_stall_s': (10.0, 'Wall seconds after which a silent agent is not waited for'),
    'max_force': (50.0, 'Force commands are clamped to this magnitude (N)'),
    'loss': (0.0, 'Radio packet loss probability (settable at run time)'),
    'radio_range_m': (25.0, 'Radio range in metres, thesis 4.1 (settable at run time)'),
    'radio_wall_speed_mps': (0.0, 'Speed of a radio-opaque wall sweeping the workspace '
                                  'along +x from when set; 0: none (settable at run time)'),
    'half_size': (50.0, 'Workspace half width (m)'),
    'terrain': ('rough', 'pybullet terrain: rough or flat'),
    'seed': (0, 'Seed of the noise generators and the terrain'),
    'record_dir': ('', 'Folder for the run record (truth.csv, medium.json, separation.json); '
                       'empty: none'),
    'gui': (False, 'pybullet GUI (needs a display)'),
}


def check_parameters(p: dict) -> None:
    """ValueError naming the proximity parameter that is out of range, and the fix."""
    for name, ok, wanted, example in (
            ('proximity_rate_hz', p['proximity_rate_hz'] >= 0, '>= 0 Hz (0: no sensor)', 10.0),
            ('proximity_range_m', p['proximity_range_m'] > 0, 'above 0 m', 3.0),
            ('proximity_std', p['proximity_std'] >= 0, '>= 0 m', 0.02)):
        if not (math.isfinite(p[name]) and ok):
            raise ValueError(f'parameter {name} must be a finite number {wanted}, got '
                             f'{p[name]}: set it in config/sim.yaml or with --ros-args '
                             f'-p {name}:={example}')


def world_config(p: dict) -> WorldConfig:
    """The world model's rates and limits from the node's parameters."""
    def period(rate: str) -> float:
        return 1.0 / p[rate] if p[rate] > 0 else 0.0
    return WorldConfig(
        physics_dt=1.0 / p['physics_rate_hz'], radio_period_s=period('radio_rate_hz'),
        imu_period_s=period('imu_rate_hz'), range_period_s=period('range_rate_hz'),
        gps_period_s=period('gps_rate_hz'), gps_std=p['gps_std'],
        proximity_period_s=period('proximity_rate_hz'),
        proximity_range_m=p['proximity_range_m'], proximity_std=p['proximity_std'],
        record_period_s=period('truth_rate_hz'), command_timeout_s=p['command_timeout_s'],
        max_force=p['max_force'], half_size=p['half_size'])


def world_from_parameters(p: dict) -> tuple[list[RobotSpec], dict[int, RobotType], World]:
    """(placed fleet, robot types, world) of sim_node's parameters ``p``; ValueError
    (FleetError, ShapeError, WorldError) naming a bad one."""
    check_parameters(p)
    if not p['fleet_file']:
        raise ValueError('parameter fleet_file is not set: give a fleet YAML with robots '
                         '(id, type, beacon, x, y), e.g. -p fleet_file:=fleet.yaml')
    fleet = load_fleet(p['fleet_file'])
    types = load_robot_types()
    obstacles = list(load_shape(p['shape']).obstacles) if p['shape'] else []
    # Where the robots really stand: near the fleet file's positions, which are all the
    # agents know (swarm_common.fleet.place_fleet, the same draw as headless).
    fleet = place_fleet(fleet, p['placement_std_m'], p['seed'],
                        radii=[types[r.type].coverage_radius for r in fleet],
                        obstacles=obstacles, half_size=p['half_size'])
    rng = np.random.default_rng(p['seed'])
    backend = make_backend(p['backend'], fleet, types, obstacles, p['half_size'],
                           p['terrain'], p['seed'], p['gui'], p['physics_rate_hz'])
    medium = RadioMedium(MediumConfig(loss=p['loss'], range_m=p['radio_range_m']), rng,
                         obstacles)
    return fleet, types, World(fleet, types, backend, world_config(p), rng, obstacles, medium)
