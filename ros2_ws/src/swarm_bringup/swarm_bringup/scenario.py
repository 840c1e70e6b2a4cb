"""The options of a swarm run (``scripts/launch_swarm.py``) and their checks.

``parse_args`` reads the command line; ``validate`` checks everything before anything
starts (the host split, every fault and setting, the fleet, and every shape the run
will form, partitioned as mission_node will) and refuses a bad input with a
``LaunchError``: one line naming the input and the fix. Pure: no ROS import.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

from swarm_bringup.launch_plan import (
    checked_namespace,
    default_beacons,
    fleet_counts,
    generate_fleet,
)

DESCRIPTION = 'Start a whole swarm through ROS 2 from one command, watch it, and report.'


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=DESCRIPTION)
    p.add_argument('--agents', type=int, default=50)
    p.add_argument('--beacons', type=int, default=None, help='default: 15 %% of the agents')
    p.add_argument('--types', default='', help='composition TYPE:COUNT,... (default 40/40/20 %%)')
    p.add_argument('--method', default='bubble', help='bubble, fractal or forces')
    p.add_argument('--shape', default='circle_314', help='built-in name or shape file')
    p.add_argument('--sequence', default='', help='YAML/JSON shape sequence [{time, shape}]')
    p.add_argument('--morph', default='', metavar='KIND:AMOUNT@START+DURATION',
                   help='smooth change of --shape (move m along x or by DX,DY, rotate '
                        'degrees, grow by 1+AMOUNT), e.g. move:15@200+60; not with '
                        '--sequence')
    p.add_argument('--remesh', choices=('incremental', 'scratch'), default='incremental',
                   help='bubble packing on a changed shape: move the goals (incremental) or '
                        'partition anew and re-assign (scratch)')
    p.add_argument('--duration', type=float, default=300.0, help='sim seconds at most')
    p.add_argument('--half-size', type=float, default=50.0,
                   help='workspace half-width in metres (thesis: 50)')
    p.add_argument('--settle-hold', type=float, default=None,
                   help='sim seconds the settled condition (eq. 4.1) must hold, after the '
                        'last change, before the run ends settled (default: '
                        'swarm_sim.metrics.SETTLE_HOLD_S, 30)')
    p.add_argument('--seed', type=int, default=0)
    p.add_argument('--composed', action='store_true', help='all agents in one process')
    p.add_argument('--decentralized', action='store_true',
                   help='agents partition the announced shape themselves')
    p.add_argument('--gui', action='store_true', help='pybullet GUI (needs a display)')
    p.add_argument('--markers', action='store_true',
                   help='publish /swarm/markers for RViz (robots by type and mode, goals, '
                        'shape, obstacles, radio links; off by default: the world then '
                        'listens to every agent state)')
    p.add_argument('--rtf', type=float, default=0.0,
                   help='target real-time factor of the sim (0: as fast as possible)')
    p.add_argument('--remove', action='append', default=[],
                   help='remove robots mid-run, e.g. --remove 60:3,17 (sim time:ids)')
    p.add_argument('--radio-off', action='append', default=[], metavar='T:IDS',
                   help="kill robots' radios mid-run, e.g. --radio-off 60:3,17 (repeatable)")
    p.add_argument('--radio-on', action='append', default=[], metavar='T:IDS',
                   help='bring radios back, e.g. --radio-on 90:3 (repeatable)')
    p.add_argument('--move-obstacle', action='append', default=[], metavar='T:K:DX,DY',
                   help='move obstacle K of the shape by (DX, DY) m at sim time T, e.g. '
                        '--move-obstacle 60:0:5,0 (repeatable)')
    p.add_argument('--set-sim', action='append', default=[], metavar='T:NAME=VALUE',
                   help='set a run-time parameter of the sim node at sim time T, e.g. '
                        '--set-sim 60:loss=0.2, 90:radio_range_m=5 or '
                        '90:radio_wall_speed_mps=1 (repeatable)')
    p.add_argument('--min-duration', type=float, default=0.0,
                   help='sim seconds the run lasts at least, settled or not')
    p.add_argument('--control-rate', type=float, default=50.0, help='agent inner loop Hz')
    p.add_argument('--domain', type=int, default=None, help='ROS_DOMAIN_ID (default: free)')
    p.add_argument('--namespace', default='',
                   help='namespace of every node, e.g. /swarm_a (swarms in different '
                        'namespaces share a domain; /clock and /tf are remapped into it)')
    p.add_argument('--local-agents', default='',
                   help='agent ids started here, e.g. 0-3 or 0,2,5-7 or none (default: all);'
                        ' the others join from hosts listed in ROS_STATIC_PEERS')
    p.add_argument('--agents-only', action='store_true',
                   help='start only the --local-agents, for the world running on another '
                        'host (no sim, mission or metrics); runs until Ctrl-C')
    p.add_argument('--swarm-key-file', default='',
                   help="the swarm's radio key file, read by every agent (make one with "
                        "'python -m swarm_agent.frame_auth > keys.yaml'; default: the "
                        'development key, which every copy of this software holds)')
    p.add_argument('--no-record', dest='record', action='store_false',
                   help='do not record the topics into OUT/run.mcap (recorded by default)')
    p.add_argument('--out', required=True)
    return p.parse_args(argv)


class LaunchError(Exception):
    """Refuse to start: one clear line."""


def parse_agent_ids(spec: str, n_agents: int) -> list[int]:
    """Ids of ``--local-agents``: '' is all, 'none' is none, else e.g. '0-3,6'."""
    if not spec.strip():
        return list(range(n_agents))
    if spec.strip().lower() == 'none':
        return []
    ids: set[int] = set()
    for part in spec.split(','):
        lo, sep, hi = part.strip().partition('-')
        try:
            first, last = int(lo), int(hi if sep else lo)
        except ValueError:
            raise LaunchError(f'--local-agents {spec!r}: {part.strip()!r} is not an id or a '
                              'range; use e.g. 0-3 or 0,2,5-7') from None
        if first > last:
            raise LaunchError(f'--local-agents {spec!r}: range {part.strip()} runs backwards; '
                              f'write {last}-{first}')
        if first < 0 or last >= n_agents:
            raise LaunchError(f'--local-agents {spec!r}: agent ids run 0..{n_agents - 1} '
                              f'with --agents {n_agents}')
        ids.update(range(first, last + 1))
    return sorted(ids)


def _fault_time(flag: str, spec: str, when: str, example: str) -> float:
    try:
        t = float(when)
    except ValueError:
        raise LaunchError(f'{flag} {spec!r}: {when.strip()!r} is not a sim time in seconds; '
                          f'write e.g. {flag} {example}') from None
    if not (np.isfinite(t) and t >= 0.0):
        raise LaunchError(f'{flag} {spec!r}: the time must be a sim time >= 0 s')
    return t


def check_before_end(flag: str, times, duration: float) -> None:
    """Refuse a fault or setting ``flag`` timed at or after the end of the run."""
    late = [t for t in times if t >= duration]
    if late:
        raise LaunchError(f'{flag} at {max(late):g} s comes after the end of the run '
                          f'(--duration {duration:g}); set it earlier or raise --duration')


def parse_robot_fault(flag: str, spec: str, n_agents: int) -> tuple[float, list[int]]:
    """``--remove``/``--radio-off``/``--radio-on`` ``T:IDS`` as (time, ids), checked."""
    when, sep, ids = spec.partition(':')
    if not sep or not ids.strip():
        raise LaunchError(f'{flag} {spec!r}: write TIME:IDS, e.g. {flag} 60:3,17')
    t = _fault_time(flag, spec, when, '60:3,17')
    try:
        robots = [int(i) for i in ids.split(',')]
    except ValueError:
        raise LaunchError(f'{flag} {spec!r}: {ids.strip()!r} is not a list of agent ids; '
                          f'write e.g. {flag} 60:3,17') from None
    bad = [i for i in robots if not 0 <= i < n_agents]
    if bad:
        raise LaunchError(f'{flag} {spec!r}: agent ids run 0..{n_agents - 1} with --agents '
                          f'{n_agents}, not {bad}')
    return t, robots


def parse_move_obstacle(spec: str, n_obstacles: int) -> tuple[float, list[float]]:
    """``--move-obstacle T:K:DX,DY`` as (time, [k, dx, dy]), checked against the shape."""
    parts = spec.split(':')
    if len(parts) != 3:
        raise LaunchError(f'--move-obstacle {spec!r}: write TIME:INDEX:DX,DY, e.g. '
                          '--move-obstacle 60:0:5,0')
    t = _fault_time('--move-obstacle', spec, parts[0], '60:0:5,0')
    try:
        k = int(parts[1])
        dx, dy = (float(v) for v in parts[2].split(','))
    except ValueError:
        raise LaunchError(f'--move-obstacle {spec!r}: write an integer obstacle index and two '
                          'offsets in metres, e.g. --move-obstacle 60:0:5,0') from None
    if not 0 <= k < n_obstacles:
        raise LaunchError(f'--move-obstacle {spec!r}: the shape has {n_obstacles} obstacles'
                          + (f' (indices 0..{n_obstacles - 1})' if n_obstacles else ''))
    if not (np.isfinite(dx) and np.isfinite(dy)):
        raise LaunchError(f'--move-obstacle {spec!r}: offsets must be finite metres')
    return t, [float(k), dx, dy]


def parse_set_sim(spec: str) -> tuple[float, str, float]:
    """``--set-sim T:NAME=VALUE`` as (time, name, value), checked by the medium's rules."""
    from swarm_sim.medium import RUNTIME_SETTINGS

    names = ', '.join(RUNTIME_SETTINGS)
    when, sep, assignment = spec.partition(':')
    name, eq, value = assignment.partition('=')
    if not sep or not eq or not name.strip():
        raise LaunchError(f'--set-sim {spec!r}: write TIME:NAME=VALUE, e.g. '
                          '--set-sim 60:loss=0.2')
    try:
        t = float(when)
    except ValueError:
        raise LaunchError(f'--set-sim {spec!r}: {when.strip()!r} is not a sim time in '
                          'seconds; write e.g. 60:loss=0.2') from None
    if not (np.isfinite(t) and t >= 0.0):
        raise LaunchError(f'--set-sim {spec!r}: the time must be a sim time >= 0 s')
    name = name.strip()
    if name not in RUNTIME_SETTINGS:
        raise LaunchError(f'--set-sim {spec!r}: the sim node has no run-time parameter '
                          f'{name!r}; use one of {names}')
    try:
        number = float(value)
    except ValueError:
        raise LaunchError(f'--set-sim {spec!r}: {value.strip()!r} is not a number') from None
    try:
        number = RUNTIME_SETTINGS[name](number)
    except ValueError as exc:
        raise LaunchError(f'--set-sim {spec!r}: {exc}') from None
    return t, name, number


def validate(args: argparse.Namespace):
    """Check everything before starting anything; return (shape, counts, beacons, fleet)."""
    from swarm_common.robot_types import load_robot_types, RobotTypeError
    from swarm_common.shapes import load_shape, ShapeError
    from swarm_mission.mission import Mission, MissionConfig
    from swarm_mission.partition import PartitionError

    if args.method not in ('bubble', 'fractal', 'forces'):
        raise LaunchError(f'unknown method {args.method!r}; use bubble, fractal or forces')
    if args.agents < 1:
        raise LaunchError(f'--agents must be at least 1, got {args.agents}')
    try:
        args.namespace = checked_namespace(args.namespace)
    except ValueError as exc:
        raise LaunchError(f'--namespace: {exc}') from None
    if not 0.0 < args.control_rate < float('inf'):
        raise LaunchError(f'--control-rate must be a positive rate in Hz, got '
                          f'{args.control_rate:g}; the thesis inner loop runs at 50')
    beacons = args.beacons if args.beacons is not None else default_beacons(args.agents)
    args.local_ids = parse_agent_ids(args.local_agents, args.agents)
    split = args.agents_only or len(args.local_ids) < args.agents
    if split and args.domain is None:
        raise LaunchError('a swarm split over hosts (--local-agents, --agents-only) needs '
                          'the same --domain on every host; add e.g. --domain 42')
    if args.swarm_key_file:
        from swarm_agent.agent_factory import swarm_keyring
        from swarm_agent.frame_auth import FrameAuthError
        try:
            swarm_keyring(args.swarm_key_file)
        except FrameAuthError as exc:
            raise LaunchError(f'--swarm-key-file: {exc}') from None
        args.swarm_key_file = str(pathlib.Path(args.swarm_key_file).resolve())
    if args.agents_only and not args.local_ids:
        raise LaunchError('--agents-only with --local-agents none starts nothing; '
                          'name the agents of this host, e.g. --local-agents 4-7')
    faults = {'--remove': args.remove, '--radio-off': args.radio_off,
              '--radio-on': args.radio_on, '--move-obstacle': args.move_obstacle,
              '--set-sim': args.set_sim}
    if args.agents_only and any(faults.values()):
        flag = next(f for f, v in faults.items() if v)
        raise LaunchError(f'{flag} acts from the host that runs the sim; '
                          'drop it from the --agents-only command')
    args.sim_settings = sorted(parse_set_sim(s) for s in args.set_sim)
    check_before_end('--set-sim', [t for t, _, _ in args.sim_settings], args.duration)
    robot_faults = []
    for flag, topic, specs in (('--remove', 'swarm/kill', args.remove),
                               ('--radio-off', 'swarm/radio_off', args.radio_off),
                               ('--radio-on', 'swarm/radio_on', args.radio_on)):
        parsed = [parse_robot_fault(flag, spec, args.agents) for spec in specs]
        check_before_end(flag, [t for t, _ in parsed], args.duration)
        robot_faults += [(t, ids, topic) for t, ids in parsed]
    args.robot_faults = sorted(robot_faults)
    if args.settle_hold is None:
        from swarm_sim.metrics import SETTLE_HOLD_S
        args.settle_hold = SETTLE_HOLD_S
    if not args.settle_hold >= 0.0:
        raise LaunchError(f'--settle-hold {args.settle_hold:g} must be >= 0 s')
    if not 0.0 <= args.min_duration <= args.duration:
        raise LaunchError(f'--min-duration {args.min_duration:g} must be within 0 and '
                          f'--duration {args.duration:g}')
    if not 0 <= beacons <= args.agents:
        raise LaunchError(f'--beacons {beacons} exceeds --agents {args.agents}; '
                          f'use at most {args.agents}')
    try:
        counts = fleet_counts(args.agents, args.types)
        if sum(counts.values()) != args.agents:
            raise LaunchError(f'--types {args.types} sums to {sum(counts.values())}, not '
                              f'--agents {args.agents}')
        shape = load_shape(args.shape)
        args.obstacle_moves = sorted(parse_move_obstacle(spec, len(shape.obstacles))
                                     for spec in args.move_obstacle)
        types = load_robot_types()
        radii = {t: r.coverage_radius for t, r in types.items()}
        fleet = generate_fleet(counts, beacons, args.seed, args.half_size, shape)

        def plan(candidate) -> None:
            """Partition as mission_node will: a coverable shape whose every goal keeps
            three of the fleet's beacons in radio reach (PartitionError names the fix)."""
            if args.method != 'forces':
                Mission(MissionConfig(method=args.method, seed=args.seed),
                        agent_types={r.id: r.type for r in fleet}, radii=radii,
                        beacons={r.id for r in fleet if r.is_beacon}).set_shape(candidate)

        plan(shape)
        args.last_switch = 0.0
        if args.sequence and args.morph:
            raise LaunchError('give either --sequence or --morph, not both')
        if args.sequence:
            from swarm_mission.mission import load_sequence
            for step in load_sequence(args.sequence):
                args.last_switch = max(args.last_switch, step.time)
                plan(step.shape)
        if args.morph:
            from swarm_mission.mission import parse_morph
            final = parse_morph(args.morph, shape)[-1]
            check_before_end('--morph', [final.time], args.duration)
            args.last_switch = final.time
            plan(final.shape)
    except (ShapeError, PartitionError, RobotTypeError, ValueError) as exc:
        raise LaunchError(str(exc)) from exc
    check_before_end('--move-obstacle', [t for t, _ in args.obstacle_moves], args.duration)
    return shape, counts, beacons, fleet
