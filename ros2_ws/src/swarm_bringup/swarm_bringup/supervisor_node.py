"""Start a whole swarm through ROS 2 from one command, watch it, and report.

  scripts/env.sh python scripts/launch_swarm.py --agents 50 --beacons 8 \\
      --method bubble --shape circle_314 --duration 300 --out results/swarm
  ros2 run swarm_bringup launch_swarm --agents 8 --beacons 3 --out results/swarm

Starts, in an isolated ROS domain on localhost, the processes of the run's launch plan
(swarm_bringup.launch_plan, the source ``swarm.launch.py`` renders too): the pybullet
``sim_node`` (owner of ``/clock``), the ``mission_node`` and the agents, either one
``agent_node`` process per robot (default, the faithful deployment; forked from one
process that has imported ``agent_node``, ``swarm_agent.prefork``) or all agents in one
``composed_node`` process (``--composed``, for scale). A monitor node in this process
records truth and agent states and prints a live progress line. The run ends at
``--duration`` seconds of sim time, once the swarm has stayed settled (eq. 4.1) for
``--settle-hold`` seconds after the last shape change, on Ctrl-C, or when a node crashes
(its log tail is printed). Every child is stopped, no orphans are left.

Faults at given sim times: ``--remove T:IDS`` removes robots (``swarm/kill``),
``--radio-off T:IDS`` and ``--radio-on T:IDS`` silence and restore their radios,
``--move-obstacle T:K:DX,DY`` moves obstacle K of the shape (``swarm/move_obstacle``);
each is sent at the first 0.5 s (wall) poll after sim time T, so up to half a wall
second times the real-time factor late; ``metrics.json`` lists each under ``faults``
with the sim time it was sent (``sent_at``).
``--set-sim T:NAME=VALUE`` sets a run-time parameter of the sim node with a parameter
client (``loss``, ``radio_range_m``, ``radio_wall_speed_mps``: packet loss, a range cut,
a radio-opaque wall sweeping the workspace); ``--min-duration`` keeps the run going
(no early stop when settled) to observe the swarm after them.

Writes into --out: ``metrics.json`` (the keys of scripts/evaluate.py plus
real_time_factor, max_localization_error, consensus_rounds, cpu and memory figures),
``fleet.yaml``, ``run.mcap`` (an MCAP bag of every topic, written by ``recorder_node``
as the run goes, flushed every second; ``--no-record`` leaves it out; docs/recording.md
says how to open it), ``record.npz`` (the monitor's 2 Hz record: times, true positions
and velocities, estimated positions, modes, goal ids, assignment digests and rounds; the
final goals; separation_times/separation_min: the smallest separation ratio of the sim's
physics steps up to each truth time, from the sim's ``separation.json``; every agent's
DSDV route table sampled every 2 s of sim time: route_times,
route_next (next hop, -1: none), route_hops (255: broken or none), route_stamp; the
monitor's record and the route samples are written as the run goes into
``monitor.jsonl`` and ``routes.jsonl``, ``swarm_sim.run_record.RecordLog`` files that a
killed launcher leaves behind), ``logs/*.log`` and the figures
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
import signal
import sys
import threading
import time
from typing import NoReturn, TYPE_CHECKING

import numpy as np

from swarm_bringup.launch_plan import (
    agent_nodes,
    BAG_NAME,
    mission_state,
    scoped,
    SwarmRun,
    world_nodes,
)
from swarm_bringup.launcher import Children
from swarm_bringup.scenario import LaunchError, parse_args, validate

if TYPE_CHECKING:
    from swarm_sim.run_record import RecordLog

PSS_PERIOD_S = 10.0    # wall seconds between samples of the children's memory (PSS)
MONITOR_LOG = 'monitor.jsonl'   # the monitor's record, written as the run goes
ROUTES_LOG = 'routes.jsonl'     # the route table samples, likewise
ROUTE_PERIOD_S = 2.0   # sim seconds between samples of the agents' route tables
ROUTE_DTYPES = {'route_times': 'float64', 'route_next': 'int32', 'route_hops': 'int32',
                'route_stamp': 'float64'}
NO_ROUTE_HOPS = 255    # swarm_msgs/RouteEntry.INFINITE_HOPS
FAULT_WORDS = {'swarm/kill': 'removed agents', 'swarm/radio_off': 'radio off for',
               'swarm/radio_on': 'radio back on for'}


def swarm_run(args: argparse.Namespace, fleet_file: pathlib.Path,
              out: pathlib.Path) -> SwarmRun:
    """The launch plan's view of a validated command line."""
    return SwarmRun(
        fleet_file=str(fleet_file), shape=args.shape, method=args.method, seed=args.seed,
        composed=args.composed, decentralized=args.decentralized,
        control_rate_hz=args.control_rate, real_time_factor=args.rtf, record_dir=str(out),
        gui=args.gui, half_size=args.half_size, markers=args.markers, remesh=args.remesh,
        morph=args.morph,
        sequence_file=str(pathlib.Path(args.sequence).resolve()) if args.sequence else '',
        truth_subscribers=1,   # the monitor records from t = 0
        namespace=args.namespace, swarm_key_file=args.swarm_key_file,
        bag=str(out / BAG_NAME) if args.record and not args.agents_only else '',
        **mission_state(out))


def _peers() -> str:
    peers = os.environ.get('ROS_STATIC_PEERS', '').strip()
    return f'in ROS_STATIC_PEERS ({peers})' if peers else \
        'in ROS_STATIC_PEERS, which is not set: only this machine can join'


def start_agents(children: Children, args: argparse.Namespace, run: SwarmRun, fleet,
                 counts: dict[int, int]) -> None:
    """Start the agents of ``args.local_ids``: one composed process or one per agent."""
    for spec in agent_nodes(run, fleet, counts, args.local_ids):
        _check_stop()
        children.run(spec)


def run_agents_only(children: Children, args: argparse.Namespace, run: SwarmRun, fleet,
                    counts: dict[int, int], domain: int) -> int:
    """Run this host's agents for a world on another host until Ctrl-C (or SIGTERM)."""
    crashed = None
    try:
        start_agents(children, args, run, fleet, counts)
        mode = 'composed' if args.composed else 'per-process'
        print(f'launch_swarm: agents {args.local_agents or "all"} of {args.agents} ({mode}) '
              f'for the sim on hosts {_peers()}, domain {domain}, logs in '
              f'{children.log_dir}; Ctrl-C stops them', flush=True)
        while crashed is None:
            time.sleep(0.5)
            _check_stop()
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


class RouteRecorder:
    """Keeps each agent's latest DSDV table (``agent_K/routes``) and samples them all."""

    def __init__(self, node, ids: list[int], log: RecordLog) -> None:
        from rclpy.qos import QoSProfile

        from swarm_agent.conversions import stamp_seconds
        from swarm_common import qos
        from swarm_common.ros_support import lean_subscription
        from swarm_msgs.msg import RouteTable

        self._seconds = stamp_seconds   # imported here: the launcher loads ROS lazily
        self.ids = list(ids)
        self.index = {a: k for k, a in enumerate(self.ids)}
        self.lock = threading.Lock()
        n = len(self.ids)
        self.next = np.full((n, n), -1, dtype=np.int32)
        self.hops = np.full((n, n), NO_ROUTE_HOPS, dtype=np.int32)
        self.stamp = np.full(n, np.nan)
        self.log = log   # the samples go to its file as the run goes
        for a in self.ids:
            lean_subscription(node, RouteTable, f'agent_{a}/routes', self._on_routes,
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
            self.log.add({'route_times': t, 'route_next': self.next,
                          'route_hops': self.hops, 'route_stamp': self.stamp})

    def arrays(self) -> dict[str, np.ndarray]:
        """Every sample as arrays (the log is closed and read back)."""
        from swarm_bringup.monitor_node import logged_arrays

        n = len(self.ids)
        with self.lock:
            record = logged_arrays(self.log, ROUTE_DTYPES)
        if not len(record['route_times']):
            record = {'route_times': np.zeros(0), 'route_next': np.zeros((0, n, n)),
                      'route_hops': np.zeros((0, n, n)), 'route_stamp': np.zeros((0, n))}
        return record


class Faults:
    """The run's faults and sim settings, each sent at the first poll after its time."""

    def __init__(self, monitor, args: argparse.Namespace, children: Children) -> None:
        from std_msgs.msg import Float64MultiArray, Int32MultiArray

        self._floats, self._ints = Float64MultiArray, Int32MultiArray
        self.monitor = monitor
        self.children = children
        self.robot_faults = list(args.robot_faults)        # (t, ids, topic), by time
        self.obstacle_moves = list(args.obstacle_moves)    # (t, [k, dx, dy]), by time
        self.settings = list(args.sim_settings)            # (t, name, value), by time
        self.pubs = {topic: monitor.create_publisher(Int32MultiArray, topic, 10)
                     for topic in FAULT_WORDS}
        self.move_pub = monitor.create_publisher(Float64MultiArray, 'swarm/move_obstacle',
                                                 10)
        self.client = None
        if self.settings:
            from rclpy.parameter_client import AsyncParameterClient
            self.client = AsyncParameterClient(monitor, 'sim')
        self.pending: list[tuple[dict, object]] = []
        self.applied: list[dict] = []
        self.log: list[dict] = []                          # what was injected, and when

    def idle(self) -> bool:
        """Nothing left to send and no setting awaiting its answer."""
        return not (self.robot_faults or self.obstacle_moves or self.settings or
                    self.pending)

    def step(self, t: float) -> bool:
        """Send what is due at sim time ``t``; True if something changed the swarm."""
        import rclpy

        changed = False
        while self.robot_faults and self.robot_faults[0][0] <= t:
            when, victims, topic = self.robot_faults.pop(0)
            self.pubs[topic].publish(self._ints(data=victims))
            if topic == 'swarm/kill':
                for v in victims:
                    self.children.kill(f'agent_{v}')
            print(f'\nlaunch_swarm: t={t:.1f} s {FAULT_WORDS[topic]} {victims}', flush=True)
            self.log.append({'time': when, 'sent_at': t, 'topic': topic, 'agents': victims})
            self.monitor.change(t)
            changed = True
        while self.obstacle_moves and self.obstacle_moves[0][0] <= t:
            when, move = self.obstacle_moves.pop(0)
            self.move_pub.publish(self._floats(data=move))
            self.log.append({'time': when, 'sent_at': t, 'topic': 'swarm/move_obstacle',
                             'obstacle': int(move[0]), 'offset': move[1:]})
            print(f'\nlaunch_swarm: t={t:.1f} s obstacle {int(move[0])} moved by '
                  f'({move[1]:g}, {move[2]:g}) m', flush=True)
            self.monitor.change(t)
            changed = True
        while self.settings and self.settings[0][0] <= t and self.client.services_are_ready():
            when, name, value = self.settings.pop(0)
            entry = {'time': when, 'sent_at': t, 'name': name, 'value': value}
            self.pending.append((entry, self.client.set_parameters(
                [rclpy.parameter.Parameter(name, value=value)])))
            self.monitor.change(t)
            changed = True
        for entry, future in [p for p in self.pending if p[1].done()]:
            self.pending.remove((entry, future))
            result = future.result()
            ok = bool(result is not None and result.results and result.results[0].successful)
            entry.update(ok=ok, reason='' if ok or result is None or not result.results
                         else result.results[0].reason)
            self.applied.append(entry)
            if ok:
                print(f'\nlaunch_swarm: t={t:.1f} s sim {entry["name"]} = '
                      f'{entry["value"]:g}', flush=True)
            else:
                print(f'\nlaunch_swarm: t={t:.1f} s the sim refused {entry["name"]} = '
                      f'{entry["value"]:g}: {entry["reason"] or "no answer"}',
                      file=sys.stderr, flush=True)
        return changed

    def sim_settings(self) -> list[dict]:
        """Every setting with whether the sim applied it (unsent and unanswered: not)."""
        unapplied = [{'time': w, 'name': n, 'value': v, 'ok': False, 'reason': 'not sent'}
                     for w, n, v in self.settings] + [
            dict(e, ok=False, reason='no answer') for e, _ in self.pending]
        return self.applied + unapplied


# Set by SIGINT or SIGTERM. The KeyboardInterrupt the handler raises can land where
# Python swallows it (measured: inside logging's at-fork handler while a child starts,
# "Exception ignored"), so the run's loops also check this flag.
_STOP = threading.Event()


def _interrupt(signum, frame) -> None:
    _STOP.set()
    raise KeyboardInterrupt


def _check_stop() -> None:
    if _STOP.is_set():
        raise KeyboardInterrupt


_HELD_LOCKS: list = []


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    # SIGTERM (a supervisor, a timeout) stops the run like Ctrl-C: children stopped,
    # metrics written.
    signal.signal(signal.SIGTERM, _interrupt)
    # Started from a background job of a shell without job control (`cmd &` in a script,
    # nohup), a process inherits SIGINT ignored and Python then installs no handler:
    # Ctrl-C / kill -INT would not stop the run (measured: an agents-only launcher
    # ignored SIGINT for good). Stop on it whatever the parent did.
    signal.signal(signal.SIGINT, _interrupt)
    out = pathlib.Path(args.out).resolve()
    try:
        shape, counts, beacons, fleet = validate(args)
    except LaunchError as exc:
        print(f'launch_swarm.py: {exc}', file=sys.stderr)
        return 2
    from swarm_common.fleet import save_fleet
    from swarm_common.shm import clean_stale_segments

    # Stale Fast DDS shared memory of killed processes hangs new participants forever
    # (swarm_common.shm); clear it before starting anything.
    stale = clean_stale_segments()
    if stale:
        print(f'launch_swarm: removed {len(stale)} stale Fast DDS shared-memory files '
              'of killed processes from /dev/shm', flush=True)
    (out / 'logs').mkdir(parents=True, exist_ok=True)
    fleet_file = out / 'fleet.yaml'
    save_fleet(fleet_file, fleet)
    domain = args.domain
    if domain is None:
        from swarm_common.domains import claim_domain, DomainError
        try:
            domain, lock = claim_domain(start=os.getpid())
        except DomainError as exc:
            print(f'launch_swarm.py: {exc}', file=sys.stderr)
            return 2
        _HELD_LOCKS.append(lock)   # the domain stays this run's until the process ends
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONUNBUFFERED='1')
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    children = Children(out / 'logs', env)
    run = swarm_run(args, fleet_file, out)
    if args.agents_only:
        return run_agents_only(children, args, run, fleet, counts, domain)
    try:
        supervise(args, run, children, shape, counts, fleet, beacons, domain, out)
    except KeyboardInterrupt:   # before the run's own handling began (its monitor starting)
        children.stop_all()
        print('launch_swarm: interrupted while starting; nothing was run', file=sys.stderr)
        return 130
    return 0   # not reached: supervise ends the process


def progress_line(t: float, wall: float, status: dict, agents: int) -> str:
    """The live progress line: sim time, real-time factor, agents heard and by mode."""
    rtf = t / wall if wall > 0 else 0.0
    return (f'\rt={t:7.1f} s  rtf={rtf:4.2f}  heard={status["agents_heard"]:3d}/'
            f'{agents}  settled={status["settled"]:3d}  normal={status["normal"]:3d}'
            f'  lost={status["lost"]:3d}  home={status["return_home"]:3d}  '
            f'goals v{status["goal_version"]}')


def supervise(args: argparse.Namespace, run: SwarmRun, children: Children, shape,
              counts: dict[int, int], fleet, beacons: int, domain: int,
              out: pathlib.Path) -> NoReturn:
    """Start the world and the agents, watch the run until it ends, stop every child,
    write the results and end the process (``exit_without_ros_teardown``)."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from swarm_bringup.monitor_node import MonitorNode, RECORD_DTYPES
    from swarm_bringup.results import RunSummary, write_results
    from swarm_sim.run_record import RecordLog

    ids = [r.id for r in sorted(fleet, key=lambda r: r.id)]
    # rclpy's own SIGINT handler would shut the monitor's context down, and a run whose
    # KeyboardInterrupt was swallowed then watched a dead monitor for ever: the
    # launcher handles the signals itself (_interrupt).
    # The monitor and the fault publishers live in the run's namespace, as its nodes.
    scope = scoped(run)
    ros_args = (['--ros-args', '-r', f'__ns:={scope["namespace"]}',
                 *(a for old, new in scope['remappings'] for a in ('-r', f'{old}:={new}'))]
                if scope['namespace'] else [])
    rclpy.init(args=['launch_swarm', *ros_args],
               signal_handler_options=SignalHandlerOptions.NO)
    monitor = MonitorNode(ids, settle_hold_s=args.settle_hold, parameter_overrides=[
        rclpy.parameter.Parameter('use_sim_time', value=True)],
        record_log=RecordLog(out / MONITOR_LOG, {'dtypes': RECORD_DTYPES, 'agent_ids': ids}))
    faults = Faults(monitor, args, children)
    routes = RouteRecorder(monitor, ids, RecordLog(out / ROUTES_LOG, {'dtypes': ROUTE_DTYPES,
                                                                      'agent_ids': ids}))
    next_route_sample = 0.0
    executor = SingleThreadedExecutor()
    executor.add_node(monitor)
    spin_thread = threading.Thread(target=executor.spin, daemon=True)
    spin_thread.start()
    summary = RunSummary(mode='composed' if args.composed else 'per-process')
    wall0 = time.monotonic()
    pss_due = 0.0
    last_print = 0.0
    try:
        # Inside the try: Ctrl-C or SIGTERM while the world and the agents start stops
        # the run like one later (children stopped, results written).
        for spec in world_nodes(run):
            _check_stop()
            children.run(spec)
        start_agents(children, args, run, fleet, counts)
        print(f'launch_swarm: {args.agents} agents ({summary.mode}), {beacons} beacons, '
              f'{args.method} on {args.shape}, domain {domain}, logs in {out / "logs"}',
              flush=True)
        if len(args.local_ids) < args.agents:
            print(f'launch_swarm: agents {args.local_agents} start here, the others on '
                  f'hosts {_peers()}', flush=True)
        while True:
            time.sleep(0.5)
            _check_stop()
            status = monitor.live_status()
            summary.peak_rss = max(summary.peak_rss, children.rss_bytes())
            if time.monotonic() >= pss_due:
                pss_due = time.monotonic() + PSS_PERIOD_S
                summary.peak_pss = max(summary.peak_pss, children.pss_bytes())
            summary.crashed = children.crashed()
            if summary.crashed == 'sim':
                # The simulator owns the clock and is never respawned: the run ends here,
                # with what was recorded so far (docs/restarts.md).
                summary.outcome = 'crash of sim'
                print(f'\nlaunch_swarm: the simulator exited with code '
                      f'{children.procs["sim"].returncode} at t = {summary.t:.1f} s; the run '
                      f'ends with its record so far (log: {children.log_dir / "sim.log"})',
                      file=sys.stderr)
                break
            if summary.crashed:
                summary.outcome = f'crash of {summary.crashed}'
                print(f'\nlaunch_swarm: {summary.crashed} exited with code '
                      f'{children.procs[summary.crashed].returncode}; last log lines:\n'
                      f'{children.tail(summary.crashed)}', file=sys.stderr)
                break
            t = summary.t = status['t']
            if summary.started is None and status['agents_heard'] >= args.agents:
                summary.started = (time.monotonic() - wall0, t)
            # A change ends the settled streak read in ``status``.
            changed = faults.step(t)
            if t >= next_route_sample:
                routes.sample(t)
                next_route_sample = t + ROUTE_PERIOD_S
            line = progress_line(t, time.monotonic() - wall0, status, args.agents)
            if sys.stdout.isatty():
                print(line, end='', flush=True)
            elif time.monotonic() - last_print >= 10.0:
                last_print = time.monotonic()
                print(line.lstrip('\r'), flush=True)
            if t >= args.duration:
                break
            # Settled (eq. 4.1) for the hold window since the last change (the monitor
            # checks every truth message), with nothing left to do.
            if status['settle_held'] and not changed and faults.idle() and \
                    t >= args.min_duration and t > args.last_switch:
                summary.outcome = 'settled'
                break
    except KeyboardInterrupt:
        summary.outcome = 'interrupted'
    finally:
        summary.wall = time.monotonic() - wall0
        summary.cpu = children.cpu_seconds()
        # and once at the end of the run
        summary.peak_pss = max(summary.peak_pss, children.pss_bytes())
        # Who listens to ground truth? Only the observers may: the monitor and the
        # recorder (agents never see truth).
        try:
            summary.truth_readers = sorted({
                f'{i.node_namespace.rstrip("/")}/{i.node_name}'
                for i in monitor.get_subscriptions_info_by_topic(
                    monitor.resolve_topic_name('swarm/truth'))})
        except RuntimeError:    # rclpy.RCLError: Ctrl-C already shut the context down
            summary.truth_readers = []
        children.stop_all()
        executor.shutdown()
        record = monitor.record()
        record['agent_ids'] = np.array(monitor.agent_ids)
        record.update(routes.arrays())
        summary.shapes = list(monitor.shapes)
        summary.goals = list(monitor.goals)
        summary.rounds = len(monitor.rounds_seen)
        with monitor.lock:
            summary.heard = [a for a, st in zip(monitor.agent_ids, monitor.states)
                             if st is not None]
        summary.goal_versions = monitor.goal_version
        summary.settling = monitor.settle.result()
        spin_thread.join(timeout=5.0)
    print()
    summary.sim_settings = faults.sim_settings()
    summary.faults = faults.log
    exit_without_ros_teardown(write_results(out, args, fleet, shape, beacons, domain,
                                            record, summary))


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
