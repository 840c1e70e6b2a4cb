#!/usr/bin/env python3
"""Start a whole swarm through ROS 2 from one command, watch it, and report.

  scripts/env.sh python scripts/launch_swarm.py --agents 50 --beacons 8 \\
      --method bubble --shape circle_314 --duration 300 --out results/swarm

Starts, in an isolated ROS domain on localhost: the pybullet ``sim_node`` (owner of
``/clock``), the ``mission_node`` and the agents, either one ``agent_node`` process per
robot (default, the faithful deployment; forked from one process that has imported
``agent_node``, ``swarm_agent.prefork``) or all agents in one ``composed_node`` process
(``--composed``, for scale). A monitor node in this process records truth and agent
states and prints a live progress line. The run ends at ``--duration`` seconds of sim
time, once the swarm has stayed settled (eq. 4.1) for ``--settle-hold`` seconds after
the last shape change, on Ctrl-C, or when a node crashes (its log tail is printed).
Every child is stopped, no orphans are left.

Faults at given sim times: ``--remove T:IDS`` removes robots (``/swarm/kill``),
``--radio-off T:IDS`` and ``--radio-on T:IDS`` silence and restore their radios,
``--move-obstacle T:K:DX,DY`` moves obstacle K of the shape (``/swarm/move_obstacle``);
each is sent at the first 0.5 s (wall) poll after sim time T, so up to half a wall
second times the real-time factor late; ``metrics.json`` lists each under ``faults``
with the sim time it was sent (``sent_at``).
``--set-sim T:NAME=VALUE`` sets a run-time parameter of the sim node with a parameter
client (``loss``, ``radio_range_m``, ``radio_wall_speed_mps``: packet loss, a range cut,
a radio-opaque wall sweeping the workspace); ``--min-duration`` keeps the run going
(no early stop when settled) to observe the swarm after them.

Writes into --out: ``metrics.json`` (the keys of scripts/evaluate.py plus
real_time_factor, max_localization_error, consensus_rounds, cpu and memory figures),
``fleet.yaml``, ``record.npz`` (the monitor's 2 Hz record: times, true positions and
velocities, estimated positions, modes, goal ids, assignment digests and rounds; the
final goals; separation_times/separation_min: the smallest separation ratio of the sim's
physics steps up to each truth time, from the sim's ``separation.json``; every agent's
DSDV route table sampled every 2 s of sim time: route_times,
route_next (next hop, -1: none), route_hops (255: broken or none), route_stamp),
``logs/*.log`` and the figures
``trajectories.png``, ``mesh.png``, ``localization_error.png`` and ``modes.png``.

One swarm over several hosts: run the same command on every host with the same
``--domain`` and ``--seed`` (so the same fleet), each with the agent ids it runs in
``--local-agents``; one host runs the world (sim, mission, monitor: it writes the
metrics), the others add ``--agents-only`` and run until Ctrl-C. Discovery stays on
localhost except for the addresses in ROS_STATIC_PEERS (ROS 2 Jazzy), so give each host
the others' addresses there.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import resource
import signal
import subprocess
import sys
import threading
import time
from typing import NoReturn

import numpy as np

from swarm_agent.prefork import die_with_parent, ForkedProcess, ForkServer

ROOT = pathlib.Path(__file__).resolve().parent.parent
PSS_PERIOD_S = 10.0    # wall seconds between samples of the children's memory (PSS)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
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
    p.add_argument('--local-agents', default='',
                   help='agent ids started here, e.g. 0-3 or 0,2,5-7 or none (default: all);'
                        ' the others join from hosts listed in ROS_STATIC_PEERS')
    p.add_argument('--agents-only', action='store_true',
                   help='start only the --local-agents, for the world running on another '
                        'host (no sim, mission or metrics); runs until Ctrl-C')
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
    from swarm_mission.mission import Mission, MissionConfig
    from swarm_mission.partition import PartitionError
    from swarm_mission.robot_types import (
        default_type_counts,
        load_robot_types,
        parse_type_counts,
        RobotTypeError,
    )
    from swarm_mission.shapes import load_shape, ShapeError
    from swarm_sim.fleet import random_fleet

    if args.method not in ('bubble', 'fractal', 'forces'):
        raise LaunchError(f'unknown method {args.method!r}; use bubble, fractal or forces')
    if args.agents < 1:
        raise LaunchError(f'--agents must be at least 1, got {args.agents}')
    if not 0.0 < args.control_rate < float('inf'):
        raise LaunchError(f'--control-rate must be a positive rate in Hz, got '
                          f'{args.control_rate:g}; the thesis inner loop runs at 50')
    beacons = args.beacons if args.beacons is not None else max(3, round(0.15 * args.agents))
    args.local_ids = parse_agent_ids(args.local_agents, args.agents)
    split = args.agents_only or len(args.local_ids) < args.agents
    if split and args.domain is None:
        raise LaunchError('a swarm split over hosts (--local-agents, --agents-only) needs '
                          'the same --domain on every host; add e.g. --domain 42')
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
    for flag, topic, specs in (('--remove', '/swarm/kill', args.remove),
                               ('--radio-off', '/swarm/radio_off', args.radio_off),
                               ('--radio-on', '/swarm/radio_on', args.radio_on)):
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
        counts = parse_type_counts(args.types) if args.types else \
            default_type_counts(args.agents)
        if sum(counts.values()) != args.agents:
            raise LaunchError(f'--types sums to {sum(counts.values())}, --agents is '
                              f'{args.agents}')
        shape = load_shape(args.shape)
        args.obstacle_moves = sorted(parse_move_obstacle(spec, len(shape.obstacles))
                                     for spec in args.move_obstacle)
        types = load_robot_types()
        radii = {t: r.coverage_radius for t, r in types.items()}
        fleet = random_fleet(counts, beacons, np.random.default_rng(args.seed),
                             half_size=args.half_size, obstacles=list(shape.obstacles))

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


class Children:
    """Child processes, each in its own process group, with logs in out/logs."""

    def __init__(self, log_dir: pathlib.Path, env: dict[str, str]) -> None:
        self.log_dir = log_dir
        self.env = env
        self.procs: dict[str, subprocess.Popen | ForkedProcess] = {}
        self.expected_exit: set[str] = set()
        self._forks: ForkServer | None = None

    def start(self, name: str, args: list[str]) -> None:
        log = open(self.log_dir / f'{name}.log', 'w', encoding='utf-8')  # noqa: SIM115
        self.procs[name] = subprocess.Popen(
            [sys.executable, *args], stdout=log, stderr=subprocess.STDOUT, env=self.env,
            cwd=str(ROOT), start_new_session=True, preexec_fn=die_with_parent)

    def fork(self, name: str, module: str, args: list[str]) -> None:
        """Like ``start`` for ``python -m module args``, forked from a server that has
        imported the module once (swarm_agent.prefork: 50 agents came up in 30 s of
        imports on two cores when each was exec'd)."""
        if self._forks is None:
            self._forks = ForkServer([module])
        self.procs[name] = self._forks.start(name, module, args,
                                             str(self.log_dir / f'{name}.log'), self.env,
                                             str(ROOT))

    def kill(self, name: str) -> None:
        proc = self.procs.get(name)
        if proc is not None and proc.poll() is None:
            self.expected_exit.add(name)
            os.killpg(proc.pid, signal.SIGKILL)

    def crashed(self) -> str | None:
        for name, proc in self.procs.items():
            if proc.poll() is not None and name not in self.expected_exit:
                return name
        return None

    def tail(self, name: str, lines: int = 15) -> str:
        text = (self.log_dir / f'{name}.log').read_text(encoding='utf-8', errors='replace')
        return '\n'.join(text.splitlines()[-lines:])

    def cpu_seconds(self) -> float:
        """CPU time of all children (user + system), from /proc, while they run."""
        total = 0.0
        tick = os.sysconf('SC_CLK_TCK')
        for proc in self.procs.values():
            try:
                fields = pathlib.Path(f'/proc/{proc.pid}/stat').read_text().split(')')[1].split()
                total += (int(fields[11]) + int(fields[12])) / tick
            except (OSError, IndexError, ValueError):
                pass
        return total

    def pss_bytes(self) -> int:
        """Current proportional set size of all children: resident memory with each page
        shared by k processes counted 1/k times in each (forked agents share their
        modules: 2.3 GB for 50 agents whose resident sizes add up to 6.3 GB). Reading it
        makes the kernel walk every page table (about 0.4 s for 50 agents under load),
        so it is sampled rarely. Falls back to the resident size without smaps_rollup."""
        total = 0
        for proc in self.procs.values():
            try:
                text = pathlib.Path(f'/proc/{proc.pid}/smaps_rollup').read_text()
                total += next(int(line.split()[1]) * 1024 for line in text.splitlines()
                              if line.startswith('Pss:'))
            except (OSError, ValueError, IndexError, StopIteration):
                total += self._rss_of(proc.pid)
        return total

    @staticmethod
    def _rss_of(pid: int) -> int:
        try:
            for line in pathlib.Path(f'/proc/{pid}/status').read_text().splitlines():
                if line.startswith('VmRSS:'):
                    return int(line.split()[1]) * 1024
        except (OSError, ValueError, IndexError):
            pass
        return 0

    def rss_bytes(self) -> int:
        """Current resident memory of all children (shared pages counted in each)."""
        return sum(self._rss_of(proc.pid) for proc in self.procs.values())

    def stop_all(self, grace: float = 5.0) -> None:
        for name, proc in self.procs.items():
            if proc.poll() is None:
                self.expected_exit.add(name)
                try:
                    os.killpg(proc.pid, signal.SIGINT)
                except ProcessLookupError:
                    pass
        deadline = time.monotonic() + grace
        for proc in self.procs.values():
            try:
                proc.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                try:
                    os.killpg(proc.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                proc.wait(timeout=5)


def ros_args(params: dict, ns: str | None = None, node: str | None = None) -> list[str]:
    args = ['--ros-args']
    if ns:
        args += ['-r', f'__ns:={ns}']
    if node:
        args += ['-r', f'__node:={node}']
    for key, value in params.items():
        if isinstance(value, bool):
            value = 'true' if value else 'false'
        elif isinstance(value, (list, tuple)):
            value = '[' + ','.join(str(v) for v in value) + ']'
        args += ['-p', f'{key}:={value}']
    return args


def start_agents(children: Children, args: argparse.Namespace, fleet, fleet_file: pathlib.Path,
                 counts: dict[int, int]) -> None:
    """Start the agents of ``args.local_ids``: one composed process or one per agent."""
    type_counts = ','.join(f'{t}:{c}' for t, c in sorted(counts.items()))
    local = set(args.local_ids)
    if args.composed and local:
        params = {'fleet_file': str(fleet_file), 'method': args.method, 'seed': args.seed,
                  'control_rate_hz': args.control_rate, 'use_sim_time': True,
                  'partition_locally': args.decentralized, 'type_counts': type_counts,
                  'sensor_batch': True}   # the world sends one batch per step (sim_params)
        if len(local) < args.agents:
            params['agent_ids'] = sorted(local)
        children.start('agents', ['-m', 'swarm_agent.composed_node', *ros_args(params)])
    elif not args.composed:
        for r in fleet:
            if r.id not in local:
                continue
            children.fork(f'agent_{r.id}', 'swarm_agent.agent_node', [*ros_args({
                'agent_id': r.id, 'agent_type': r.type, 'is_beacon': r.is_beacon,
                'initial_x': r.x, 'initial_y': r.y, 'method': args.method,
                'seed': args.seed + r.id, 'control_rate_hz': args.control_rate,
                'partition_locally': args.decentralized, 'type_counts': type_counts,
                'use_sim_time': True}, ns=f'/agent_{r.id}', node='agent')])


def _peers() -> str:
    peers = os.environ.get('ROS_STATIC_PEERS', '').strip()
    return f'in ROS_STATIC_PEERS ({peers})' if peers else \
        'in ROS_STATIC_PEERS, which is not set: only this machine can join'


def run_agents_only(children: Children, args: argparse.Namespace, fleet,
                    fleet_file: pathlib.Path, counts: dict[int, int], domain: int) -> int:
    """Run this host's agents for a world on another host until Ctrl-C (or SIGTERM)."""
    crashed = None
    try:
        start_agents(children, args, fleet, fleet_file, counts)
        mode = 'composed' if args.composed else 'per-process'
        print(f'launch_swarm: agents {args.local_agents or "all"} of {args.agents} ({mode}) '
              f'for the sim on hosts {_peers()}, domain {domain}, logs in '
              f'{children.log_dir}; Ctrl-C stops them', flush=True)
        while crashed is None:
            time.sleep(0.5)
            crashed = children.crashed()
    except KeyboardInterrupt:
        pass
    finally:
        children.stop_all()
    if crashed:
        print(f'launch_swarm: {crashed} exited with code {children.procs[crashed].returncode};'
              f' last log lines:\n{children.tail(crashed)}', file=sys.stderr)
        return 1
    print('launch_swarm: agents stopped', flush=True)
    return 0


ROUTE_PERIOD_S = 2.0   # sim seconds between samples of the agents' route tables
NO_ROUTE_HOPS = 255    # swarm_msgs/RouteEntry.INFINITE_HOPS


class RouteRecorder:
    """Keeps each agent's latest DSDV table (``/agent_K/routes``) and samples them all."""

    def __init__(self, node, ids: list[int]) -> None:
        from rclpy.qos import QoSProfile

        from swarm_agent.agent_node import lean_subscription
        from swarm_agent.conversions import stamp_seconds
        from swarm_mission import qos
        from swarm_msgs.msg import RouteTable

        self._seconds = stamp_seconds   # imported here: the launcher loads ROS lazily
        self.ids = list(ids)
        self.index = {a: k for k, a in enumerate(self.ids)}
        self.lock = threading.Lock()
        n = len(self.ids)
        self.next = np.full((n, n), -1, dtype=np.int32)
        self.hops = np.full((n, n), NO_ROUTE_HOPS, dtype=np.int32)
        self.stamp = np.full(n, np.nan)
        self.samples: dict[str, list] = {'route_times': [], 'route_next': [],
                                         'route_hops': [], 'route_stamp': []}
        for a in self.ids:
            lean_subscription(node, RouteTable, f'/agent_{a}/routes', self._on_routes,
                              QoSProfile(**qos.STATE))

    def _on_routes(self, msg) -> None:
        k = self.index.get(int(msg.owner))
        if k is None:
            return
        with self.lock:
            self.next[k] = -1
            self.hops[k] = NO_ROUTE_HOPS
            for r in msg.routes:
                j = self.index.get(int(r.destination))
                if j is not None:
                    self.next[k, j] = int(r.next_hop)
                    self.hops[k, j] = int(r.hop_count)
            self.stamp[k] = self._seconds(msg.header.stamp)

    def sample(self, t: float) -> None:
        with self.lock:
            for key, value in (('route_times', t), ('route_next', self.next.copy()),
                               ('route_hops', self.hops.copy()),
                               ('route_stamp', self.stamp.copy())):
                self.samples[key].append(value)

    def arrays(self) -> dict[str, np.ndarray]:
        n = len(self.ids)
        empty = {'route_times': (0,), 'route_next': (0, n, n), 'route_hops': (0, n, n),
                 'route_stamp': (0, n)}
        with self.lock:
            return {k: np.asarray(v) if v else np.zeros(empty[k])
                    for k, v in self.samples.items()}


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    # SIGTERM (a supervisor, a timeout) stops the run like Ctrl-C: children stopped,
    # metrics written.
    signal.signal(signal.SIGTERM, _interrupt)
    out = pathlib.Path(args.out).resolve()
    try:
        shape, counts, beacons, fleet = validate(args)
    except LaunchError as exc:
        print(f'launch_swarm.py: {exc}', file=sys.stderr)
        return 2
    from swarm_sim.fleet import save_fleet
    from swarm_sim.shm import clean_stale_segments

    # Stale Fast DDS shared memory of killed processes hangs new participants forever
    # (swarm_sim.shm); clear it before starting anything.
    stale = clean_stale_segments()
    if stale:
        print(f'launch_swarm: removed {len(stale)} stale Fast DDS shared-memory files '
              'of killed processes from /dev/shm', flush=True)
    (out / 'logs').mkdir(parents=True, exist_ok=True)
    fleet_file = out / 'fleet.yaml'
    save_fleet(fleet_file, fleet)
    domain = args.domain if args.domain is not None else 1 + (os.getpid() % 100)
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONUNBUFFERED='1')
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    children = Children(out / 'logs', env)
    if args.agents_only:
        return run_agents_only(children, args, fleet, fleet_file, counts, domain)
    ids = [r.id for r in sorted(fleet, key=lambda r: r.id)]
    robot_faults = list(args.robot_faults)        # (t, ids, topic), by time
    obstacle_moves = list(args.obstacle_moves)    # (t, [k, dx, dy]), by time

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import Float64MultiArray, Int32MultiArray

    from swarm_sim.monitor_node import MonitorNode

    rclpy.init()
    monitor = MonitorNode(ids, settle_hold_s=args.settle_hold, parameter_overrides=[
        rclpy.parameter.Parameter('use_sim_time', value=True)])
    fault_pubs = {topic: monitor.create_publisher(Int32MultiArray, topic, 10)
                  for topic in ('/swarm/kill', '/swarm/radio_off', '/swarm/radio_on')}
    move_pub = monitor.create_publisher(Float64MultiArray, '/swarm/move_obstacle', 10)
    routes = RouteRecorder(monitor, ids)
    settings = list(args.sim_settings)
    sim_params_client = None
    if settings:
        from rclpy.parameter_client import AsyncParameterClient
        sim_params_client = AsyncParameterClient(monitor, 'sim')
    pending_sets: list[tuple[dict, object]] = []
    applied_settings: list[dict] = []
    fault_log: list[dict] = []                    # what was injected, and when
    next_route_sample = 0.0
    executor = SingleThreadedExecutor()
    executor.add_node(monitor)
    spin_thread = threading.Thread(target=executor.spin, daemon=True)
    spin_thread.start()

    sim_params = {'fleet_file': str(fleet_file), 'shape': args.shape,
                  'real_time_factor': float(args.rtf), 'record_dir': str(out),
                  'gui': args.gui, 'seed': args.seed, 'half_size': args.half_size,
                  'marker_rate_hz': 1.0 if args.markers else 0.0,
                  # Composed agents take every robot's imu, ranges and radio deliveries
                  # in one message per step (swarm_msgs/SensorBatch).
                  'sensor_batch': bool(args.composed),
                  'truth_subscribers': 1}   # the monitor records from t = 0
    children.start('sim', ['-m', 'swarm_sim.sim_node', *ros_args(sim_params)])
    mission_params = {'shape': args.shape, 'method': args.method,
                      'fleet_file': str(fleet_file), 'seed': args.seed,
                      'remesh': args.remesh, 'decentralized': args.decentralized,
                      'use_sim_time': True}
    if args.morph:
        mission_params['morph'] = args.morph
    if args.sequence:
        mission_params['sequence_file'] = str(pathlib.Path(args.sequence).resolve())
    children.start('mission', ['-m', 'swarm_mission.mission_node', *ros_args(mission_params)])
    mode = 'composed' if args.composed else 'per-process'
    wall0 = time.monotonic()
    peak_rss = peak_pss = 0
    pss_due = 0.0
    outcome = 'not settled'
    crashed = None
    last_print = 0.0
    started = None  # (wall seconds, sim seconds) when every agent had been heard
    t = 0.0
    try:
        # Inside the try: a SIGTERM while the agents start stops the run like one later.
        start_agents(children, args, fleet, fleet_file, counts)
        print(f'launch_swarm: {args.agents} agents ({mode}), {beacons} beacons, '
              f'{args.method} on {args.shape}, domain {domain}, logs in {out / "logs"}',
              flush=True)
        if len(args.local_ids) < args.agents:
            print(f'launch_swarm: agents {args.local_agents} start here, the others on '
                  f'hosts {_peers()}', flush=True)
        while True:
            time.sleep(0.5)
            status = monitor.live_status()
            peak_rss = max(peak_rss, children.rss_bytes())
            if time.monotonic() >= pss_due:
                pss_due = time.monotonic() + PSS_PERIOD_S
                peak_pss = max(peak_pss, children.pss_bytes())
            crashed = children.crashed()
            if crashed:
                outcome = f'crash of {crashed}'
                print(f'\nlaunch_swarm: {crashed} exited with code '
                      f'{children.procs[crashed].returncode}; last log lines:\n'
                      f'{children.tail(crashed)}', file=sys.stderr)
                break
            t = status['t']
            changed = False     # a change below ends the settled streak read in ``status``
            if started is None and status['agents_heard'] >= args.agents:
                started = (time.monotonic() - wall0, t)
            while robot_faults and robot_faults[0][0] <= t:
                when, victims, topic = robot_faults.pop(0)
                fault_pubs[topic].publish(Int32MultiArray(data=victims))
                if topic == '/swarm/kill':
                    for v in victims:
                        children.kill(f'agent_{v}')
                what = {'/swarm/kill': 'removed agents', '/swarm/radio_off': 'radio off for',
                        '/swarm/radio_on': 'radio back on for'}[topic]
                print(f'\nlaunch_swarm: t={t:.1f} s {what} {victims}', flush=True)
                fault_log.append({'time': when, 'sent_at': t, 'topic': topic,
                                  'agents': victims})
                monitor.change(t)
                changed = True
            while obstacle_moves and obstacle_moves[0][0] <= t:
                when, move = obstacle_moves.pop(0)
                move_pub.publish(Float64MultiArray(data=move))
                fault_log.append({'time': when, 'sent_at': t, 'topic': '/swarm/move_obstacle',
                                  'obstacle': int(move[0]), 'offset': move[1:]})
                print(f'\nlaunch_swarm: t={t:.1f} s obstacle {int(move[0])} moved by '
                      f'({move[1]:g}, {move[2]:g}) m', flush=True)
                monitor.change(t)
                changed = True
            while settings and settings[0][0] <= t and sim_params_client.services_are_ready():
                when, name, value = settings.pop(0)
                entry = {'time': when, 'sent_at': t, 'name': name, 'value': value}
                pending_sets.append((entry, sim_params_client.set_parameters(
                    [rclpy.parameter.Parameter(name, value=value)])))
                monitor.change(t)
                changed = True
            for entry, future in [p for p in pending_sets if p[1].done()]:
                pending_sets.remove((entry, future))
                result = future.result()
                ok = bool(result is not None and result.results and
                          result.results[0].successful)
                entry.update(ok=ok, reason='' if ok or result is None or not result.results
                             else result.results[0].reason)
                applied_settings.append(entry)
                if ok:
                    print(f'\nlaunch_swarm: t={t:.1f} s sim {entry["name"]} = '
                          f'{entry["value"]:g}', flush=True)
                else:
                    print(f'\nlaunch_swarm: t={t:.1f} s the sim refused {entry["name"]} = '
                          f'{entry["value"]:g}: {entry["reason"] or "no answer"}',
                          file=sys.stderr, flush=True)
            if t >= next_route_sample:
                routes.sample(t)
                next_route_sample = t + ROUTE_PERIOD_S
            wall = time.monotonic() - wall0
            rtf = t / wall if wall > 0 else 0.0
            line = (f'\rt={t:7.1f} s  rtf={rtf:4.2f}  heard={status["agents_heard"]:3d}/'
                    f'{args.agents}  settled={status["settled"]:3d}  normal={status["normal"]:3d}'
                    f'  lost={status["lost"]:3d}  home={status["return_home"]:3d}  '
                    f'goals v{status["goal_version"]}')
            if sys.stdout.isatty():
                print(line, end='', flush=True)
            elif time.monotonic() - last_print >= 10.0:
                last_print = time.monotonic()
                print(line.lstrip('\r'), flush=True)
            if t >= args.duration:
                break
            # Settled (eq. 4.1) for the hold window since the last change (the monitor
            # checks every truth message), with nothing left to do.
            if status['settle_held'] and not changed and not robot_faults and \
                    not obstacle_moves and not settings and not pending_sets and \
                    t >= args.min_duration and t > args.last_switch:
                outcome = 'settled'
                break
    except KeyboardInterrupt:
        outcome = 'interrupted'
    finally:
        wall = time.monotonic() - wall0
        cpu = children.cpu_seconds()
        peak_pss = max(peak_pss, children.pss_bytes())   # and once at the end of the run
        # Who listens to ground truth? Only the monitor may (agents never see truth).
        try:
            truth_readers = sorted({f'{i.node_namespace.rstrip("/")}/{i.node_name}'
                                    for i in monitor.get_subscriptions_info_by_topic(
                                        '/swarm/truth')})
        except RuntimeError:    # rclpy.RCLError: Ctrl-C already shut the context down
            truth_readers = []
        children.stop_all()
        executor.shutdown()
        monitor_record = monitor.snapshot()
        monitor_record['agent_ids'] = np.array(monitor.agent_ids)
        monitor_record.update(routes.arrays())
        monitor_shapes = list(monitor.shapes)
        monitor_goals = list(monitor.goals)
        rounds = len(monitor.rounds_seen)
        with monitor.lock:
            heard = [a for a, st in zip(monitor.agent_ids, monitor.states) if st is not None]
        goal_versions = monitor.goal_version
        settling = monitor.settle.result()
        spin_thread.join(timeout=5.0)
    print()
    from swarm_sim.report import run_report, write_metrics

    robots = sorted(fleet, key=lambda r: r.id)
    # The 2 Hz record of truth and belief, for plots and post-mortems of one agent.
    final_goals = monitor_goals or []
    monitor_record.update(
        goal_id=np.array([g.id for g in final_goals], dtype=np.int64),
        goal_type=np.array([g.type for g in final_goals], dtype=np.int64),
        goal_xy=np.array([[g.x, g.y] for g in final_goals], dtype=float).reshape(-1, 2))
    # The sim's closest approach of coverage circles and body contacts over every physics
    # step (sim_node writes it when it closes); without it no separation is reported.
    separation = None
    try:
        separation = json.loads((out / 'separation.json').read_text(encoding='utf-8'))
        series = separation.pop('series')
        monitor_record.update(separation_times=np.array(series['times'], dtype=float),
                              separation_min=np.array(series['min'], dtype=float))
    except (OSError, ValueError, KeyError):
        print('launch_swarm: the sim left no separation.json: no separation metrics',
              file=sys.stderr)
    np.savez_compressed(out / 'record.npz', **monitor_record)
    unapplied = [{'time': w, 'name': n, 'value': v, 'ok': False, 'reason': 'not sent'}
                 for w, n, v in settings] + [
        dict(e, ok=False, reason='no answer') for e, _ in pending_sets]
    sim_settings = applied_settings + unapplied
    shapes = [s for _, s in monitor_shapes] or [shape]
    metrics = run_report(out, monitor_record, [r.type for r in robots],
                         [r.is_beacon for r in robots], shapes, monitor_goals,
                         shape_times=[t for t, _ in monitor_shapes] or None,
                         settling=settling, separation=separation,
                         settle_hold_s=args.settle_hold, extra={
                             'mode': mode, 'outcome': outcome, 'wall_seconds': wall,
                             'cpu_seconds_children': cpu,
                             'cpu_cores_used': cpu / wall if wall > 0 else 0.0,
                             # Start-up (processes, discovery, first commands) apart from
                             # the running swarm: the same swarm's real-time factor once
                             # every agent had been heard.
                             'startup_wall_seconds': started and started[0],
                             'steady_real_time_factor':
                                 (t - started[1]) / (wall - started[0])
                                 if started and wall - started[0] > 1.0 else None,
                             'peak_rss_bytes': peak_rss, 'peak_pss_bytes': peak_pss,
                             'consensus_rounds': rounds,
                             'launcher_max_rss_bytes':
                                 resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
                             'seed': args.seed, 'truth_subscribers': truth_readers,
                             'goal_versions': goal_versions, 'agents_heard': heard,
                             'sim_settings': sim_settings, 'faults': fault_log})
    scenario = {k: v for k, v in vars(args).items()}
    scenario.update(beacons=beacons, domain=domain)
    write_metrics(out, [metrics], scenario)
    print(f'launch_swarm: {outcome}; settling {metrics.get("settling_time")} s, '
          f'rtf {metrics.get("real_time_factor", 0):.2f}, displacement '
          f'{metrics.get("total_displacement", float("nan")):.0f} m, eps_t '
          f'{metrics.get("epsilon_t", float("nan")):.2f}, eps_g '
          f'{metrics.get("epsilon_g", float("nan")):.2f}; results in {out}')
    failed = [e for e in sim_settings if not e['ok']]
    if failed and outcome != 'interrupted':
        print('launch_swarm: --set-sim not applied: ' + '; '.join(
            f'{e["name"]}={e["value"]:g} at {e["time"]:g} s ({e["reason"]})' for e in failed),
            file=sys.stderr)
    exit_without_ros_teardown(1 if crashed or (failed and outcome != 'interrupted') else 0)


def exit_without_ros_teardown(code: int) -> NoReturn:
    """End the launcher with ``code`` once every child is stopped and every result is
    written, skipping rclpy's teardown of the monitor node.

    That teardown has blocked forever with every child already stopped, holding the GIL
    (so no Python timer or thread can end it): destroying a publisher of the monitor
    (50 agents, one process per agent; py-spy: in Publisher.destroy) and rclpy's
    shutdown in rcl_logging_fini. All it would still do is release this process's DDS
    participant, which the kernel does at exit; the participant's /dev/shm files are
    removed by the next run's ``clean_stale_segments``.
    """
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == '__main__':
    sys.exit(main())
