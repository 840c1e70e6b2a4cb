#!/usr/bin/env python3
"""Start a whole swarm through ROS 2 from one command, watch it, and report.

  scripts/env.sh python scripts/launch_swarm.py --agents 50 --beacons 8 \\
      --method bubble --shape circle_314 --duration 300 --out results/swarm

Starts, in an isolated ROS domain on localhost: the pybullet ``sim_node`` (owner of
``/clock``), the ``mission_node`` and the agents, either one ``agent_node`` process per
robot (default, the faithful deployment) or all agents in one ``composed_node`` process
(``--composed``, for scale). A monitor node in this process records truth and agent
states and prints a live progress line. The run ends at ``--duration`` seconds of sim
time, once the swarm has stayed settled (eq. 4.1) for ``--settle-hold`` seconds after
the last shape change, on Ctrl-C, or when a node crashes (its log tail is printed).
Every child is stopped, no orphans are left.

Writes into --out: ``metrics.json`` (the keys of scripts/evaluate.py plus
real_time_factor, max_localization_error, consensus_rounds, cpu and memory figures),
``fleet.yaml``, ``record.npz`` (the monitor's 2 Hz record: times, true positions and
velocities, estimated positions, modes, goal ids), ``logs/*.log`` and the figures
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
import os
import pathlib
import resource
import signal
import subprocess
import sys
import threading
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--agents', type=int, default=50)
    p.add_argument('--beacons', type=int, default=None, help='default: 15 %% of the agents')
    p.add_argument('--types', default='', help='composition TYPE:COUNT,... (default 40/40/20 %%)')
    p.add_argument('--method', default='bubble', help='bubble, fractal or forces')
    p.add_argument('--shape', default='circle_314', help='built-in name or shape file')
    p.add_argument('--sequence', default='', help='YAML/JSON shape sequence [{time, shape}]')
    p.add_argument('--duration', type=float, default=300.0, help='sim seconds at most')
    p.add_argument('--half-size', type=float, default=50.0,
                   help='workspace half-width in metres (thesis: 50)')
    p.add_argument('--settle-hold', type=float, default=5.0)
    p.add_argument('--seed', type=int, default=0)
    p.add_argument('--composed', action='store_true', help='all agents in one process')
    p.add_argument('--decentralized', action='store_true',
                   help='agents partition the announced shape themselves')
    p.add_argument('--gui', action='store_true', help='pybullet GUI (needs a display)')
    p.add_argument('--rtf', type=float, default=0.0,
                   help='target real-time factor of the sim (0: as fast as possible)')
    p.add_argument('--remove', action='append', default=[],
                   help='remove robots mid-run, e.g. --remove 60:3,17 (sim time:ids)')
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


def validate(args: argparse.Namespace):
    """Check everything before starting anything; return (shape, counts, beacons, fleet)."""
    from swarm_mission.partition import partition, PartitionError
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
    beacons = args.beacons if args.beacons is not None else max(3, round(0.15 * args.agents))
    args.local_ids = parse_agent_ids(args.local_agents, args.agents)
    split = args.agents_only or len(args.local_ids) < args.agents
    if split and args.domain is None:
        raise LaunchError('a swarm split over hosts (--local-agents, --agents-only) needs '
                          'the same --domain on every host; add e.g. --domain 42')
    if args.agents_only and not args.local_ids:
        raise LaunchError('--agents-only with --local-agents none starts nothing; '
                          'name the agents of this host, e.g. --local-agents 4-7')
    if args.agents_only and args.remove:
        raise LaunchError('--remove acts from the host that runs the sim; '
                          'drop it from the --agents-only command')
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
        types = load_robot_types()
        radii = {t: r.coverage_radius for t, r in types.items()}
        if args.method != 'forces':
            partition(shape, counts, radii, args.method, seed=args.seed)
        args.last_switch = 0.0
        if args.sequence:
            from swarm_mission.mission import load_sequence
            for step in load_sequence(args.sequence):
                args.last_switch = max(args.last_switch, step.time)
                if args.method != 'forces':
                    partition(step.shape, counts, radii, args.method, seed=args.seed)
        fleet = random_fleet(counts, beacons, np.random.default_rng(args.seed),
                             half_size=args.half_size, obstacles=list(shape.obstacles))
    except (ShapeError, PartitionError, RobotTypeError, ValueError) as exc:
        raise LaunchError(str(exc)) from exc
    return shape, counts, beacons, fleet


class Children:
    """Child processes, each in its own process group, with logs in out/logs."""

    def __init__(self, log_dir: pathlib.Path, env: dict[str, str]) -> None:
        self.log_dir = log_dir
        self.env = env
        self.procs: dict[str, subprocess.Popen] = {}
        self.expected_exit: set[str] = set()

    def start(self, name: str, args: list[str]) -> None:
        log = open(self.log_dir / f'{name}.log', 'w', encoding='utf-8')  # noqa: SIM115
        self.procs[name] = subprocess.Popen(
            [sys.executable, *args], stdout=log, stderr=subprocess.STDOUT, env=self.env,
            cwd=str(ROOT), start_new_session=True)

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

    def rss_bytes(self) -> int:
        """Current resident memory of all children."""
        total = 0
        for proc in self.procs.values():
            try:
                for line in pathlib.Path(f'/proc/{proc.pid}/status').read_text().splitlines():
                    if line.startswith('VmRSS:'):
                        total += int(line.split()[1]) * 1024
            except (OSError, ValueError, IndexError):
                pass
        return total

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
                  'partition_locally': args.decentralized, 'type_counts': type_counts}
        if len(local) < args.agents:
            params['agent_ids'] = sorted(local)
        children.start('agents', ['-m', 'swarm_agent.composed_node', *ros_args(params)])
    elif not args.composed:
        for r in fleet:
            if r.id not in local:
                continue
            children.start(f'agent_{r.id}', ['-m', 'swarm_agent.agent_node', *ros_args({
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
    def interrupt(signum, frame):
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, interrupt)
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


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    out = pathlib.Path(args.out).resolve()
    try:
        shape, counts, beacons, fleet = validate(args)
    except LaunchError as exc:
        print(f'launch_swarm.py: {exc}', file=sys.stderr)
        return 2
    from swarm_sim.fleet import save_fleet

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
    removals = sorted((float(s.split(':')[0]), [int(i) for i in s.split(':')[1].split(',')])
                      for s in args.remove)

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import Int32MultiArray

    from swarm_sim.monitor_node import MonitorNode

    rclpy.init()
    monitor = MonitorNode(ids, parameter_overrides=[
        rclpy.parameter.Parameter('use_sim_time', value=True)])
    kill_pub = monitor.create_publisher(Int32MultiArray, '/swarm/kill', 10)
    executor = SingleThreadedExecutor()
    executor.add_node(monitor)
    spin_thread = threading.Thread(target=executor.spin, daemon=True)
    spin_thread.start()

    sim_params = {'fleet_file': str(fleet_file), 'shape': args.shape,
                  'real_time_factor': float(args.rtf), 'record_dir': str(out),
                  'gui': args.gui, 'seed': args.seed, 'half_size': args.half_size}
    children.start('sim', ['-m', 'swarm_sim.sim_node', *ros_args(sim_params)])
    mission_params = {'shape': args.shape, 'method': args.method,
                      'fleet_file': str(fleet_file), 'seed': args.seed,
                      'decentralized': args.decentralized, 'use_sim_time': True}
    if args.sequence:
        mission_params['sequence_file'] = str(pathlib.Path(args.sequence).resolve())
    children.start('mission', ['-m', 'swarm_mission.mission_node', *ros_args(mission_params)])
    start_agents(children, args, fleet, fleet_file, counts)

    mode = 'composed' if args.composed else 'per-process'
    print(f'launch_swarm: {args.agents} agents ({mode}), {beacons} beacons, {args.method} '
          f'on {args.shape}, domain {domain}, logs in {out / "logs"}', flush=True)
    if len(args.local_ids) < args.agents:
        print(f'launch_swarm: agents {args.local_agents} start here, the others on hosts '
              f'{_peers()}', flush=True)
    wall0 = time.monotonic()
    peak_rss = 0
    outcome = 'duration'
    settled_since = None
    last_change_t = 0.0
    last_goal_version = 0
    crashed = None
    removed = 0
    last_print = 0.0
    try:
        while True:
            time.sleep(0.5)
            status = monitor.live_status()
            peak_rss = max(peak_rss, children.rss_bytes())
            crashed = children.crashed()
            if crashed:
                outcome = f'crash of {crashed}'
                print(f'\nlaunch_swarm: {crashed} exited with code '
                      f'{children.procs[crashed].returncode}; last log lines:\n'
                      f'{children.tail(crashed)}', file=sys.stderr)
                break
            t = status['t']
            while removals and removals[0][0] <= t:
                _, victims = removals.pop(0)
                kill_pub.publish(Int32MultiArray(data=victims))
                for v in victims:
                    children.kill(f'agent_{v}')
                removed += len(victims)
                print(f'\nlaunch_swarm: t={t:.1f} s removed agents {victims}', flush=True)
                last_change_t = t
            if status['goal_version'] != last_goal_version:
                last_goal_version, last_change_t = status['goal_version'], t
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
            if status['settled'] >= args.agents - removed and not removals and \
                    t > args.last_switch and t - last_change_t > args.settle_hold:
                settled_since = t if settled_since is None else settled_since
                if t - settled_since >= args.settle_hold:
                    outcome = 'settled'
                    break
            else:
                settled_since = None
    except KeyboardInterrupt:
        outcome = 'interrupted'
    finally:
        wall = time.monotonic() - wall0
        cpu = children.cpu_seconds()
        # Who listens to ground truth? Only the monitor may (agents never see truth).
        truth_readers = sorted({f'{i.node_namespace.rstrip("/")}/{i.node_name}'
                                for i in monitor.get_subscriptions_info_by_topic(
                                    '/swarm/truth')})
        children.stop_all()
        executor.shutdown()
        monitor_record = monitor.snapshot()
        monitor_record['agent_ids'] = np.array(monitor.agent_ids)
        monitor_shapes = list(monitor.shapes)
        monitor_goals = list(monitor.goals)
        rounds = len(monitor.rounds_seen)
        with monitor.lock:
            heard = [a for a, st in zip(monitor.agent_ids, monitor.states) if st is not None]
        goal_versions = monitor.goal_version
        monitor.destroy_node()
        rclpy.try_shutdown()
    print()
    from swarm_sim.report import run_report, write_metrics

    robots = sorted(fleet, key=lambda r: r.id)
    # The 2 Hz record of truth and belief, for plots and post-mortems of one agent.
    np.savez_compressed(out / 'record.npz', **monitor_record)
    shapes = [s for _, s in monitor_shapes] or [shape]
    metrics = run_report(out, monitor_record, [r.type for r in robots],
                         [r.is_beacon for r in robots], shapes, monitor_goals, extra={
                             'mode': mode, 'outcome': outcome, 'wall_seconds': wall,
                             'cpu_seconds_children': cpu,
                             'cpu_cores_used': cpu / wall if wall > 0 else 0.0,
                             'peak_rss_bytes': peak_rss, 'consensus_rounds': rounds,
                             'launcher_max_rss_bytes':
                                 resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
                             'seed': args.seed, 'truth_subscribers': truth_readers,
                             'goal_versions': goal_versions, 'agents_heard': heard})
    scenario = {k: v for k, v in vars(args).items()}
    scenario.update(beacons=beacons, domain=domain)
    write_metrics(out, [metrics], scenario)
    print(f'launch_swarm: {outcome}; settling {metrics.get("settling_time")} s, '
          f'rtf {metrics.get("real_time_factor", 0):.2f}, displacement '
          f'{metrics.get("total_displacement", float("nan")):.0f} m, eps_t '
          f'{metrics.get("epsilon_t", float("nan")):.2f}, eps_g '
          f'{metrics.get("epsilon_g", float("nan")):.2f}; results in {out}')
    return 1 if crashed else 0


if __name__ == '__main__':
    sys.exit(main())
