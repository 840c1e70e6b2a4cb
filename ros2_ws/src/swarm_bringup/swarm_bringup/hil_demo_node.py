#!/usr/bin/env python3
"""Hardware-in-the-loop run without hardware: the formations of thesis Figs. 5.11-5.20.

  scripts/env.sh python scripts/hil_demo.py --shape all --out results/hil
  ros2 run swarm_bringup hil_demo --shape hw_square --out results/hil

Five emulated robots of thesis Table 5.1 (coverage radii 16/11/11/8/8 cm) in the 2 x 2 m
arena form the shapes hw_trapezoid, hw_square, hw_pentagon, hw_arrow and hw_line through
the real software: one agent process per robot (``hw_agent_node``: agent_node with the
arena's distances; external camera pose instead of the LPS, bubble packing, partitioned
on the agents, consensus over the mesh; config/hw_agent.yaml) whose
velocity setpoints (``cmd_vel``) go through the real ``bridge_node`` as XBee API frames
over a pseudo-terminal to firmware twins (swarm_bridge.emulator: fixed-point mixer of
eqs. 5.1-5.3, stepper timing, watchdog). The boards integrate their half-steps into
poses, which ``hil_world_node`` publishes as the overhead camera (/agent_K/pose). The
agents' mesh frames travel through the simulator's radio medium between those poses
(``swarm_bridge.hil_mesh``: range, line of sight, loss, airtime, latency; ``--radio-loss``).

Camera (``--camera``): ``truth`` (default) publishes the boards' poses as the camera;
``sim`` renders the boards' true poses from above in a process of its own
(``camera_sim_node``, swarm_bridge.camera_render: covers, floor, corner markers, light,
blur, noise, latency), calibrates on the rendered corner markers and runs
``camera_tracker_node``, whose poses close the loop; a device (``/dev/videoN``) or a
video file runs the real robots: no emulator, ``bridge_node`` on ``--port``, the tracker
on the camera with ``--calibration`` (written by ``camera_calibrate``). Metrics use the
boards' true poses (/truth/agent_K/pose) when emulated, the tracker's otherwise.

Per shape the run starts when the mission node announces the shape (t = 0) and ends when
the formation is reached: every robot within ``--arrive-tolerance`` of a distinct goal of
its type (the goals the agents partition the announced shape into) and slower than 0.01
m/s, held for ``--settle-hold`` seconds together with eq. 5.4 (every robot inside the
shape and that slow); or after ``--duration`` seconds. Reported next to thesis Tables
5.2-5.6: total displacement (summed camera-track lengths), settling time (eq. 5.4),
arrival time, the displacement lower bound (optimal assignment of straight paths to the
goals), the final distance of each robot to its goal and the mesh frames' delay from
radio to radio (``MeshDelays``). Writes DIR/hil.json, DIR/<shape>.png
(traces as Figs. 5.11-5.20) and DIR/<shape>/logs/*.log. Children run in an isolated ROS
domain on localhost and are all stopped at the end (swarm_bringup.launcher.Children).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import pathlib
import signal
import sys
import threading
import time

import numpy as np

from swarm_bringup.hil import (
    analyse,
    arrival_tolerance,
    bridge_config,
    bridge_node,
    camera_sim_node,
    camera_tracker_node,
    count_warnings,
    hil_mission_node,
    hil_world_node,
    hw_agent_nodes,
    MeshDelays,
    parse_args,
    plot,
    record_arrived,
    record_settled,
    resample,
    SHAPES,
    sim_calibration,
    table,
    THESIS,
    THESIS_TABLE,
)
from swarm_bringup.launch_plan import counts_of, type_counts_text
from swarm_bringup.launcher import Children
from swarm_common.domains import claim_domain, DomainError

# A shape stamp older than this (or in the future) is not this run's announcement on
# this machine's clock: the monitor's own reception time stands in.
STAMP_AGE_MAX_S = 30.0


class Monitor:
    """In-process node recording camera poses, agent states and the shape announcement."""

    def __init__(self, ids: list[int], pose_topic: str = '/agent_{k}/pose') -> None:
        from geometry_msgs.msg import PoseStamped, Twist
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile

        from swarm_common import qos
        from swarm_msgs.msg import AgentState, FormationShape, RadioPacketArray

        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('hil_monitor', context=self.context)
        self.lock = threading.Lock()
        self.tracks: dict[int, list[tuple[float, float, float]]] = {k: [] for k in ids}
        self.states: dict[int, object] = {}
        self.setpoints: dict[int, list[tuple[float, float, float]]] = {k: [] for k in ids}
        self.shape_time: float | None = None
        self.mesh = MeshDelays()
        self.node.create_subscription(RadioPacketArray, '/radio/tx', self._on_tx,
                                      QoSProfile(**qos.RADIO))
        for k in ids:
            self.node.create_subscription(RadioPacketArray, f'/agent_{k}/radio/rx',
                                          self._on_rx, QoSProfile(**qos.RADIO))
            self.node.create_subscription(
                PoseStamped, pose_topic.format(k=k), lambda m, k=k: self._on_pose(k, m),
                QoSProfile(**qos.SENSOR))
            self.node.create_subscription(
                AgentState, f'/agent_{k}/state', lambda m, k=k: self._on_state(k, m),
                QoSProfile(**qos.STATE))
            self.node.create_subscription(
                Twist, f'/agent_{k}/cmd_vel', lambda m, k=k: self._on_cmd(k, m),
                QoSProfile(**qos.SENSOR))
        self.node.create_subscription(FormationShape, '/swarm/shape', self._on_shape,
                                      QoSProfile(**qos.LATCHED))
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _on_pose(self, k: int, msg) -> None:
        with self.lock:
            self.tracks[k].append((time.monotonic(), msg.pose.position.x, msg.pose.position.y))

    def _on_tx(self, msg) -> None:
        self._on_frames(msg, self.mesh.sent)

    def _on_rx(self, msg) -> None:
        self._on_frames(msg, self.mesh.received)

    def _on_frames(self, msg, record) -> None:
        from swarm_agent.packet import PacketError, unpack_frames

        t = time.monotonic()
        try:
            packets = [p for _, p in unpack_frames(msg.frames)]
        except PacketError:
            return          # the agents log a corrupt batch; here it is not measured
        with self.lock:
            record(t, packets)

    def _on_cmd(self, k: int, msg) -> None:
        with self.lock:
            self.setpoints[k].append((time.monotonic(), msg.linear.x, msg.linear.y))

    def _on_state(self, k: int, msg) -> None:
        with self.lock:
            self.states[k] = msg

    def _on_shape(self, msg) -> None:
        """t = 0 of the run: when the mission set the shape (its stamp, on this machine's
        wall clock), not when this monitor heard it: under load it hears the shape up to
        seconds after the agents, which have started driving by then."""
        now, wall = time.monotonic(), time.time()
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        age = wall - stamp
        with self.lock:
            if self.shape_time is None:
                self.shape_time = now - age if 0.0 <= age < STAMP_AGE_MAX_S else now

    def snapshot(self) -> tuple[dict, dict, float | None]:
        with self.lock:
            return ({k: list(v) for k, v in self.tracks.items()}, dict(self.states),
                    self.shape_time)

    def close(self) -> None:
        import rclpy
        self.executor.shutdown()
        # The spin thread may still be inside its last wait: let it leave before the
        # node and context go, as the swarm supervisor does (a context torn down under it
        # aborted the process at exit once: "terminate called without an active
        # exception", return code -6, after a settled run).
        self.thread.join(timeout=5.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def hil_poses() -> tuple[dict, list[tuple[float, float, float]]]:
    """The hil_world parameters of config/hil.yaml and the initial poses in fleet order."""
    import yaml

    from swarm_common.fleet import initial_poses, load_fleet

    params = yaml.safe_load(bridge_config('hil.yaml').read_text())['hil_world']['ros__parameters']
    robots = load_fleet(params['fleet_file'] or None, hardware=True)
    return params, initial_poses([float(v) for v in params['initial_poses']], robots)


def run_shape(name: str, out: pathlib.Path, args: argparse.Namespace, domain: int) -> dict:
    """Run one shape through the ROS processes; return its metrics."""
    from swarm_common.fleet import load_fleet
    from swarm_common.robot_types import load_robot_types
    from swarm_common.shapes import load_shape
    from swarm_mission.partition import partition

    shape = load_shape(name)
    params, poses = hil_poses()
    robots = load_fleet(params['fleet_file'] or None, hardware=True)
    types = load_robot_types(bridge_config('hw_robot_types.yaml'))
    radii = {t: r.coverage_radius for t, r in types.items()}
    counts = counts_of(robots)
    type_counts = type_counts_text(counts)
    goals = partition(shape, counts, radii, 'bubble', seed=0).goals  # what agents compute
    robot_types = np.array([r.type for r in robots])
    arrive_tol = (arrival_tolerance() if args.arrive_tolerance is None
                  else args.arrive_tolerance)
    run_dir = out / name
    (run_dir / 'logs').mkdir(parents=True, exist_ok=True)
    link = run_dir / 'coordinator.pty'
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               PYTHONUNBUFFERED='1')
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    children = Children(run_dir / 'logs', env)
    ids = [r.id for r in robots]
    real = args.camera not in ('truth', 'sim')
    monitor = Monitor(ids, '/agent_{k}/pose' if real else '/truth/agent_{k}/pose')
    outcome = 'duration'
    t_end: float | None = None
    t_start = None
    try:
        if not real:
            children.run(hil_world_node(link, args))
            _wait(lambda: link.exists(), 20.0, 'the emulated robots (hil_world) never came up',
                  children)
        if args.camera == 'sim':
            children.run(camera_sim_node(params))
        if args.camera != 'truth':
            calibration = args.calibration or str(
                sim_calibration(params, run_dir / 'camera_calibration.yaml'))
            children.run(camera_tracker_node(calibration, poses,
                                             args.camera if real else None))
        children.run(bridge_node(args.port if real else str(link)))
        for spec in hw_agent_nodes(robots, poses, type_counts):
            children.run(spec)
        _wait(lambda: len(monitor.snapshot()[1]) == len(ids) and all(
            monitor.snapshot()[0].values()), 60.0, 'agents or camera never came up', children)
        children.run(hil_mission_node(name, type_counts))
        _wait(lambda: monitor.snapshot()[2] is not None, 30.0,
              'the mission node never announced the shape', children)
        t_start = monitor.snapshot()[2]
        print(f'hil_demo: {name}: shape announced, {len(ids)} robots moving '
              f'(domain {domain}, logs in {run_dir / "logs"})', flush=True)
        last_print = 0.0
        while True:
            time.sleep(0.25)
            crashed = children.crashed()
            if crashed:
                outcome = f'crash of {crashed}'
                print(f'hil_demo: {crashed} exited; last log lines:\n{children.tail(crashed)}',
                      file=sys.stderr)
                break
            now = time.monotonic()
            tracks, _, _ = monitor.snapshot()
            record = [tracks[k] for k in ids]
            if record_arrived(record, t_start, now, robot_types, goals, arrive_tol,
                              args.settle_hold):
                judged = record_settled(record, t_start, now, shape, args.settle_hold)
                if judged is not None and judged['settled']:
                    outcome, t_end = 'arrived', now
                    break
            if now - last_print >= 5.0:
                last_print = now
                print(f'  t={now - t_start:5.1f} s  not arrived and held yet', flush=True)
            if now - t_start >= args.duration:
                break
    except (RuntimeError, KeyboardInterrupt) as exc:
        outcome = 'interrupted' if isinstance(exc, KeyboardInterrupt) else str(exc)
        print(f'hil_demo: {name}: {outcome}', file=sys.stderr)
    finally:
        t_end = time.monotonic() if t_end is None else t_end
        children.stop_all()
        tracks, states, _ = monitor.snapshot()
        with monitor.lock:
            setpoints = {k: list(v) for k, v in monitor.setpoints.items()}
            mesh_delay = monitor.mesh.summary()
        monitor.close()
        (run_dir / 'tracks.json').write_text(json.dumps(
            {'t_start': t_start, 'poses': tracks, 'cmd_vel': setpoints}))
        link.unlink(missing_ok=True)
    if t_start is None or not all(tracks.values()):
        return {'shape': name, 'outcome': outcome}
    times, positions = resample([tracks[k] for k in ids], t_start, t_end)
    metrics = analyse(times, positions, shape, robot_types, goals, radii, args.settle_hold,
                      arrive_tol)
    metrics.update(
        shape=name, outcome=outcome, camera=args.camera, thesis_table=THESIS_TABLE[name],
        thesis_total_displacement=THESIS[name][0], thesis_settling_time=THESIS[name][1],
        initial_poses=[list(p) for p in poses],
        final_positions=positions[-1].tolist(),
        goals=[{'id': g.id, 'type': g.type, 'x': g.x, 'y': g.y} for g in goals],
        assigned_goals={k: int(s.assigned_goal) for k, s in sorted(states.items())},
        bridge_log_warnings=count_warnings(run_dir / 'logs' / 'bridge.log'),
        mesh_delay=mesh_delay)
    if not args.no_plot:
        plot(out / f'{name}.png', name, shape, positions, goals, robots)
    return metrics


def _wait(ready, timeout: float, what: str, children: Children) -> None:
    deadline = time.monotonic() + timeout
    while not ready():
        crashed = children.crashed()
        if crashed:
            raise RuntimeError(f'{crashed} exited while starting:\n{children.tail(crashed)}')
        if time.monotonic() > deadline:
            raise RuntimeError(f'{what} within {timeout:.0f} s')
        time.sleep(0.1)


def main(argv: list[str] | None = None) -> int:
    # Ctrl-C stops the run even when started with SIGINT ignored (supervisor_node.main).
    signal.signal(signal.SIGINT, signal.default_int_handler)
    args = parse_args(argv)
    out = pathlib.Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    shapes = SHAPES if args.shape == 'all' else (args.shape,)
    results, start = [], os.getpid()
    for i, name in enumerate(shapes):
        # A domain per shape, never the previous shape's: none of its late packets reach
        # this one. Given --domain: that one and the next ones.
        lock = contextlib.nullcontext()
        if args.domain is not None:
            domain = (args.domain + i) % 233
        else:
            try:
                domain, lock = claim_domain(start=start)
            except DomainError as exc:
                print(f'hil_demo.py: {exc}', file=sys.stderr)
                return 2
            start = domain + 1
        with lock:
            results.append(run_shape(name, out, args, domain))
        (out / 'hil.json').write_text(json.dumps(
            {'command': ' '.join(['scripts/hil_demo.py', *(argv or sys.argv[1:])]),
             'results': results}, indent=2, default=float))
    print(table(results))
    print(f'hil_demo: results in {out / "hil.json"}')
    return 0 if all(m['outcome'] == 'arrived' for m in results) else 1
