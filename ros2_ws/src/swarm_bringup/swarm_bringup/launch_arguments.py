"""The arguments of ``launch/swarm.launch.py``, checked, turned into the launch plan.

The launch file only declares ``ARGUMENTS`` and renders ``plan_from_arguments`` through
launch_ros, so everything it decides is here and tested without launch_ros. A run is
checked as ``scripts/launch_swarm.py`` checks it (swarm_bringup.scenario.validate: the
method, the counts, the shape partitioned as mission_node will); a fleet is generated
from the counts when no fleet file is given and written to ``out``. Bad input raises
``LaunchError`` with one line naming the argument and the fix. Pure: no ROS import.
"""

from __future__ import annotations

from collections.abc import Mapping
import pathlib
import re
import tempfile

from swarm_bringup.launch_plan import (
    BAG_NAME,
    checked_namespace,
    counts_of,
    mission_state,
    NamespaceError,
    NodeSpec,
    swarm_plan,
    SwarmRun,
    type_counts_text,
)
from swarm_bringup.scenario import LaunchError, parse_args, validate

MODES = ('composed', 'per_robot')

# (name, default, description) of every launch argument.
ARGUMENTS: tuple[tuple[str, str, str], ...] = (
    ('agents', '8', 'number of robots when no fleet_file is given'),
    ('beacons', '', 'position beacons among them (default: 15 % of the agents, at least 3)'),
    ('types', '', 'composition TYPE:COUNT,... (default: 40/40/20 % of types 1/2/3)'),
    ('fleet_file', '', 'fleet YAML (robots: id, type, beacon, x, y, yaw); default: '
                       'generated from agents, beacons, types and seed'),
    ('shape', 'circle_314', 'built-in shape name or shape file'),
    ('method', 'bubble', 'partition method: bubble, fractal or forces'),
    ('mode', 'composed', 'composed (all agents in one process) or per_robot'),
    ('params_file', '', 'parameters file read by every node (e.g. config/params.yaml)'),
    ('swarm_key_file', '', "the swarm's radio key file, read by every agent (default: the "
                           'development key)'),
    ('seed', '0', 'seed of the fleet, the partition and the noise'),
    ('rtf', '1.0', 'target real-time factor of the simulator (0: as fast as possible)'),
    ('half_size', '50.0', 'workspace half width in metres (thesis: 50)'),
    ('decentralized', 'false', 'agents partition the announced shape themselves'),
    ('record', 'false', "record every topic into out/run.mcap (recorder_node) and write the "
                        "simulator's record (truth.csv, medium.json) into out"),
    ('out', '', 'folder for the generated fleet and the record (default: a new temp folder)'),
    ('viz', 'false', 'publish swarm/markers for RViz'),
    ('namespace', '', 'namespace of every node (e.g. /swarm_a): swarms in different '
                      'namespaces share a ROS domain without crosstalk; /clock and /tf are '
                      'remapped into it'),
)


def _integer(values: Mapping[str, str], name: str, example: str) -> int:
    try:
        return int(values[name])
    except ValueError:
        raise LaunchError(f'{name}:={values[name]!r} is not an integer; write e.g. '
                          f'{name}:={example}') from None


def _number(values: Mapping[str, str], name: str, example: str) -> float:
    try:
        return float(values[name])
    except ValueError:
        raise LaunchError(f'{name}:={values[name]!r} is not a number; write e.g. '
                          f'{name}:={example}') from None


def _flag(values: Mapping[str, str], name: str) -> bool:
    text = values[name].strip().lower()
    if text not in ('true', 'false'):
        raise LaunchError(f'{name}:={values[name]!r}: write {name}:=true or {name}:=false')
    return text == 'true'


def plan_from_arguments(given: Mapping[str, str]) -> tuple[list[NodeSpec], pathlib.Path]:
    """The launch plan of the launch arguments ``given`` (defaults for the others) and the
    fleet file it uses. Raises LaunchError naming a bad argument."""
    from swarm_common.fleet import load_fleet, save_fleet

    unknown = sorted(set(given) - {name for name, _, _ in ARGUMENTS})
    if unknown:
        raise LaunchError(f'unknown launch argument {unknown[0]}; the arguments are '
                          + ', '.join(name for name, _, _ in ARGUMENTS))
    values = {name: str(given.get(name, default)) for name, default, _ in ARGUMENTS}
    if values['mode'] not in MODES:
        raise LaunchError(f"mode:={values['mode']!r}: use mode:=composed or mode:=per_robot")
    seed = _integer(values, 'seed', '0')
    half_size = _number(values, 'half_size', '50.0')
    rtf = _number(values, 'rtf', '1.0')
    if not rtf >= 0.0:
        raise LaunchError(f'rtf:={rtf:g}: the real-time factor is >= 0 (0: as fast as possible)')
    decentralized, record, viz = (_flag(values, name)
                                  for name in ('decentralized', 'record', 'viz'))
    try:
        namespace = checked_namespace(values['namespace'])
    except NamespaceError as exc:
        raise LaunchError(f'namespace:={values["namespace"]!r}: {exc}') from None
    params_file = values['params_file']
    if params_file and not pathlib.Path(params_file).is_file():
        raise LaunchError(f'params_file:={params_file}: no such file; give a parameters YAML '
                          'such as config/params.yaml of swarm_bringup')
    out = pathlib.Path(values['out'] or tempfile.mkdtemp(prefix='swarm_launch_')).resolve()
    fleet = None
    if values['fleet_file']:
        try:
            fleet = load_fleet(values['fleet_file'])
        except ValueError as exc:
            raise LaunchError(f"fleet_file:={values['fleet_file']}: {exc}") from None
        counts = counts_of(fleet)
        argv = ['--agents', str(len(fleet)),
                '--beacons', str(sum(r.is_beacon for r in fleet)),
                '--types', type_counts_text(counts)]
    else:
        argv = ['--agents', str(_integer(values, 'agents', '8')), '--types', values['types']]
        if values['beacons']:
            argv += ['--beacons', str(_integer(values, 'beacons', '3'))]
    argv += ['--shape', values['shape'], '--method', values['method'], '--seed', str(seed),
             '--half-size', str(half_size), '--out', str(out),
             '--swarm-key-file', values['swarm_key_file']]
    args = parse_args(argv)
    try:
        _, counts, _, generated = validate(args)
    except LaunchError as exc:
        # The checks are the launcher's: name the launch arguments, not its flags.
        raise LaunchError(re.sub(r'--([a-z_-]+) ', lambda m: m[1].replace('-', '_') + ':=',
                                 str(exc))) from None
    out.mkdir(parents=True, exist_ok=True)
    if fleet is None:
        fleet = generated
        fleet_file = out / 'fleet.yaml'
        save_fleet(fleet_file, fleet)
    else:
        fleet_file = pathlib.Path(values['fleet_file']).resolve()
    run = SwarmRun(fleet_file=str(fleet_file), shape=values['shape'],
                   method=values['method'], seed=seed,
                   composed=values['mode'] == 'composed',
                   decentralized=decentralized, real_time_factor=rtf,
                   record_dir=str(out) if record else '', half_size=half_size, markers=viz,
                   bag=str(out / BAG_NAME) if record else '',
                   params_files=(str(pathlib.Path(params_file).resolve()),)
                   if params_file else (), namespace=namespace,
                   swarm_key_file=args.swarm_key_file, **mission_state(out))
    return swarm_plan(run, fleet, counts), fleet_file
