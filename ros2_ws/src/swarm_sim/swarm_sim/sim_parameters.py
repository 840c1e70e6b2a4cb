"""sim_node's parameters, generated from one configuration dataclass, and the world they
build.

``SimParameters`` holds every parameter of the simulator, each a ``tunable`` field
(swarm_common.parameters: description, range, whether it may change while the world
runs), with the radio medium's own configuration nested (``medium.latency_s``,
``medium.bandwidth_bps``, ... generated from ``swarm_sim.medium.MediumConfig``). sim_node
declares one ROS parameter per spec of ``SIM_PARAMETERS`` (read-only but for the live
ones, which its on-set callback applies: ``loss``, ``radio_range_m``,
``radio_wall_speed_mps``, ``rogue``, ``real_time_factor``); ``world_from_parameters`` checks the
values against their specs and builds the world. No YAML mirrors the defaults: ``ros2
param dump /sim`` lists them, ``ros2 param describe`` explains each.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from swarm_common.fleet import load_fleet, place_fleet, PLACEMENT_STD_M, RobotSpec
from swarm_common.parameters import configured, spec_table, tunable
from swarm_common.robot_types import load_robot_types, RobotType
from swarm_common.shapes import load_shape
from swarm_sim.medium import MediumConfig, RadioMedium
from swarm_sim.mission_mesh import MediumWithMission, MISSION_RADIO_STREAM, RelayedListener
from swarm_sim.physics import make_backend
from swarm_sim.rogue import check_rogue
from swarm_sim.world_model import World, WorldConfig

MAX_RATE_HZ = 10_000.0
MAX_S = 86_400.0   # a day, the longest wait or timeout that makes sense


@dataclass
class SimParameters:
    """Every parameter of sim_node (module docstring); ranges are inclusive."""

    fleet_file: str = tunable('', 'Fleet YAML: robots with id, type, beacon, x, y, yaw')
    placement_std_m: float = tunable(
        PLACEMENT_STD_M, "Robots spawn this far (m per axis, Gaussian, seeded) from their "
        "fleet positions, the agents' deployment prior", low=0.0, high=10.0)
    shape: str = tunable('', 'Shape spec whose obstacles populate the world (built-in or '
                             'file)')
    backend: str = tunable('auto', 'Physics: pybullet, pointmass, or auto (pybullet if '
                                   'available)')
    physics_rate_hz: float = tunable(100.0, 'Physics steps per simulated second',
                                     low=1.0, high=MAX_RATE_HZ)
    real_time_factor: float = tunable(1.0, 'Target sim/wall speed ratio; 0 runs as fast '
                                           'as possible (settable at run time)',
                                      low=0.0, high=1000.0, live=True)
    clock_rate_hz: float = tunable(50.0, 'Wall-clock rate of /clock updates and stepping '
                                         'batches', low=1.0, high=1000.0)
    imu_rate_hz: float = tunable(10.0, 'IMU samples per simulated second',
                                 low=0.1, high=MAX_RATE_HZ)
    gps_rate_hz: float = tunable(1.0, 'Beacon GPS fixes per simulated second',
                                 low=0.01, high=MAX_RATE_HZ)
    gps_std: float = tunable(2.0, 'GPS noise per axis (m), thesis 4.2', low=0.0, high=100.0)
    range_rate_hz: float = tunable(1.0, 'TOA ranging rate per simulated second',
                                   low=0.01, high=MAX_RATE_HZ)
    radio_rate_hz: float = tunable(20.0, 'Radio delivery batches per simulated second, per '
                                         'robot; 0: every delivery at once',
                                   low=0.0, high=MAX_RATE_HZ)
    proximity_rate_hz: float = tunable(10.0, 'Proximity scans per simulated second; 0: no '
                                             'sensor', low=0.0, high=MAX_RATE_HZ)
    proximity_range_m: float = tunable(3.0, 'Proximity sensor range (m): neighbours within '
                                            'it are seen', low=0.01, high=1000.0)
    proximity_std: float = tunable(0.02, 'Proximity offset noise per axis (m)',
                                   low=0.0, high=10.0)
    sensor_batch: bool = tunable(False, 'Publish imu, ranges, proximity and radio '
                                        'deliveries of every robot in one '
                                        'swarm/sensor_batch per step and take force '
                                        'commands from swarm/cmd_batch (composed agents) '
                                        'instead of the per-robot topics')
    truth_rate_hz: float = tunable(2.0, 'Ground-truth publication rate (sim time)',
                                   low=0.01, high=MAX_RATE_HZ)
    marker_rate_hz: float = tunable(1.0, 'RViz marker rate on swarm/markers (sim time); 0: '
                                         'none', low=0.0, high=MAX_RATE_HZ)
    command_timeout_s: float = tunable(0.5, 'Force commands older than this are dropped to '
                                            'zero (s)', low=0.001, high=MAX_S)
    max_agent_lag_s: float = tunable(0.2, 'Sim time the world may run ahead of the slowest '
                                          'agent (s); 0: off', low=0.0, high=MAX_S)
    truth_subscribers: int = tunable(0, 'Hold the clock at 0 until this many swarm/truth '
                                        "subscribers (e.g. the launcher's monitor) have "
                                        'matched, for at most wait_for_agents_s',
                                     low=0, high=1000)
    wait_for_agents_s: float = tunable(60.0, "Wall seconds to wait for every robot's first "
                                             'command', low=0.0, high=MAX_S)
    agent_stall_s: float = tunable(10.0, 'Wall seconds after which a silent agent is not '
                                         'waited for', low=0.0, high=MAX_S)
    max_force: float = tunable(50.0, 'Force commands are clamped to this magnitude (N)',
                               low=0.001, high=1e6)
    loss: float = tunable(0.0, 'Radio packet loss probability (settable at run time)',
                          low=0.0, high=1.0, live=True)
    radio_range_m: float = tunable(25.0, 'Radio range in metres, thesis 4.1 (settable at '
                                         'run time)', low=0.01, high=1e6, live=True)
    radio_wall_speed_mps: float = tunable(0.0, 'Speed of a radio-opaque wall sweeping the '
                                               'workspace along +x from when set; 0: none '
                                               '(settable at run time)',
                                          low=0.0, high=1000.0, live=True)
    rogue: float = tunable(0.0, 'A rogue transmitter without the swarm key from when set '
                                '(swarm_sim.rogue): 0 none, 1 forged adverts, 2 forged cost '
                                'rows, 3 replays, 4 a flood at 10x the frame rate (settable '
                                'at run time)', low=0.0, high=4.0, live=True)
    rogue_trailer: bool = tunable(True, "The rogue's frames end with an authentication "
                                        'trailer (a tag it cannot compute): the agents '
                                        'authenticate (their auth parameter)')
    mission_radio: bool = tunable(True, "The mission computer's radio at the shape's "
                                        'centroid: the route adverts it hears go out on '
                                        'mission/radio/rx (swarm_sim.mission_mesh)')
    half_size: float = tunable(50.0, 'Workspace half width (m)', low=0.1, high=1e5)
    terrain: str = tunable('rough', 'pybullet terrain: rough or flat')
    seed: int = tunable(0, 'Seed of the noise generators and the terrain',
                        low=0, high=2**31 - 1)
    record_dir: str = tunable('', 'Folder for the run record (truth.csv, medium.json, '
                                  'separation.json); empty: none')
    gui: bool = tunable(False, 'pybullet GUI (needs a display)')
    # The radio medium's other settings (its range and loss are radio_range_m and loss).
    medium: MediumConfig = field(default_factory=MediumConfig)


# name -> ParamSpec, dotted for the medium's (``medium.latency_s``)
SIM_PARAMETERS = spec_table(SimParameters)


def check_parameters(p: dict) -> SimParameters:
    """The configuration of the values ``p`` (by parameter name); ParameterError (a
    ValueError) names the first one out of its type or range and the fix."""
    return configured(SimParameters(), {name: p[name] for name in SIM_PARAMETERS})


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
    config = check_parameters(p)
    if not p['fleet_file']:
        raise ValueError('parameter fleet_file is not set: give a fleet YAML with robots '
                         '(id, type, beacon, x, y), e.g. -p fleet_file:=fleet.yaml')
    fleet = load_fleet(p['fleet_file'])
    types = load_robot_types()
    shape = load_shape(p['shape']) if p['shape'] else None
    obstacles = list(shape.obstacles) if shape is not None else []
    # Where the robots really stand: near the fleet file's positions, which are all the
    # agents know (swarm_common.fleet.place_fleet, the same draw as headless).
    fleet = place_fleet(fleet, p['placement_std_m'], p['seed'],
                        radii=[types[r.type].coverage_radius for r in fleet],
                        obstacles=obstacles, half_size=p['half_size'])
    rng = np.random.default_rng(p['seed'])
    backend = make_backend(p['backend'], fleet, types, obstacles, p['half_size'],
                           p['terrain'], p['seed'], p['gui'], p['physics_rate_hz'])
    medium = RadioMedium(dataclasses.replace(config.medium, loss=p['loss'],
                                             range_m=p['radio_range_m']), rng, obstacles)
    if p['mission_radio'] and shape is not None:
        # Stands where the headless evaluator puts it; its draws have their own stream.
        medium = MediumWithMission(
            medium, RelayedListener(), shape.region.centroid.coords[0],
            np.random.default_rng([MISSION_RADIO_STREAM, p['seed']]), obstacles)
    world = World(fleet, types, backend, world_config(p), rng, obstacles, medium)
    world.rogue_trailer = bool(p['rogue_trailer'])
    world.set_rogue(check_rogue(p['rogue']))
    return fleet, types, world
