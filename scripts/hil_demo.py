#!/usr/bin/env python3
"""Hardware-in-the-loop run without hardware: the formations of thesis Figs. 5.11-5.20.

  scripts/env.sh python scripts/hil_demo.py --shape all --out results/hil

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
``sim`` renders the arena from above (swarm_bridge.camera_render: covers, floor, corner
markers, light, blur, noise, latency), calibrates on the rendered corner markers and
runs ``camera_tracker_node``, whose poses close the loop; a device (``/dev/videoN``) or
a video file runs the real robots: no emulator, ``bridge_node`` on ``--port``, the tracker
on the camera with ``--calibration`` (written by ``camera_calibrate``). Metrics use the
boards' true poses (/truth/agent_K/pose) when emulated, the tracker's otherwise.

Per shape the run starts when the mission node announces the shape (t = 0) and ends once
every robot has stayed inside the shape and slower than 0.01 m/s (eq. 5.4) for
``--settle-hold`` seconds, or after ``--duration`` seconds. Reported next to thesis
Tables 5.2-5.6: total displacement (summed camera-track lengths), settling time (eq.
5.4), the displacement lower bound (optimal assignment of straight paths to the goals)
and the final distance of each robot to its goal. Writes DIR/hil.json, DIR/<shape>.png
(traces as Figs. 5.11-5.20) and DIR/<shape>/logs/*.log. Children run in an isolated ROS
domain on localhost and are all stopped at the end (launch_swarm.Children).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import sys
import threading
import time

from launch_swarm import Children, ROOT, ros_args
import numpy as np

SHAPES = ('hw_trapezoid', 'hw_square', 'hw_pentagon', 'hw_arrow', 'hw_line')
# Thesis Tables 5.2-5.6 (Figs. 5.11-5.20): total displacement [m], settling time [s].
THESIS = {'hw_trapezoid': (1.75, 23.0), 'hw_square': (1.63, 19.0),
          'hw_pentagon': (1.95, 26.0), 'hw_arrow': (2.16, 29.0), 'hw_line': (1.80, 25.0)}
THESIS_TABLE = {'hw_trapezoid': '5.2', 'hw_square': '5.3', 'hw_pentagon': '5.4',
                'hw_arrow': '5.5', 'hw_line': '5.6'}
BRIDGE = ROOT / 'ros2_ws' / 'src' / 'swarm_bridge'
HIL_CONFIG = BRIDGE / 'config' / 'hil.yaml'
HW_TYPES = BRIDGE / 'config' / 'hw_robot_types.yaml'
HW_AGENT = BRIDGE / 'config' / 'hw_agent.yaml'
CAMERA_CONFIG = BRIDGE / 'config' / 'camera.yaml'
SPEED_WINDOW = 0.5        # s: camera speed = displacement over this window / window
GRID_HZ = 10.0            # common time grid of the recorded camera tracks


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--shape', default='all', help=f'one of {", ".join(SHAPES)} or all')
    p.add_argument('--out', required=True, help='results directory')
    p.add_argument('--duration', type=float, default=90.0,
                   help='seconds at most per shape after the shape is announced')
    p.add_argument('--settle-hold', type=float, default=3.0,
                   help='seconds the swarm must stay settled (eq. 5.4) to end a run')
    p.add_argument('--camera-noise', type=float, default=None,
                   help='camera position noise, m (default: config/hil.yaml)')
    p.add_argument('--radio-loss', type=float, default=None,
                   help="per-receiver frame loss of the agents' mesh, 0..1 "
                        '(default: config/hil.yaml)')
    p.add_argument('--camera', default='truth',
                   help='truth, sim (rendered camera + tracker), or a V4L2 device / video '
                        'file for real robots')
    p.add_argument('--calibration', default=None,
                   help='camera calibration YAML (camera_calibrate) for a real camera')
    p.add_argument('--port', default='/dev/ttyUSB0',
                   help='serial port of the coordinator XBee for real robots')
    p.add_argument('--domain', type=int, default=None, help='first ROS_DOMAIN_ID (default: free)')
    p.add_argument('--no-plot', action='store_true', help='skip the PNG figures')
    args = p.parse_args(argv)
    if args.shape != 'all' and args.shape not in SHAPES:
        p.error(f'--shape {args.shape!r}: use one of {", ".join(SHAPES)} or all')
    if args.duration <= 0 or args.settle_hold < 0:
        p.error('--duration must be positive and --settle-hold non-negative')
    if args.radio_loss is not None and not 0.0 <= args.radio_loss <= 1.0:
        p.error(f'--radio-loss {args.radio_loss}: give a probability between 0 and 1')
    if args.camera not in ('truth', 'sim') and not args.calibration:
        p.error(f'--camera {args.camera}: give --calibration FILE (run camera_calibrate '
                f'--source {args.camera} --out FILE first)')
    return args


# -- analysis (pure) ---------------------------------------------------------------------
def resample(tracks: list[list[tuple[float, float, float]]], t0: float, t1: float,
             hz: float = GRID_HZ) -> tuple[np.ndarray, np.ndarray]:
    """Camera tracks [(t, x, y), ...] per robot onto one grid from t0 to t1 (last value held).

    Returns (times relative to t0, positions (T, N, 2)).
    """
    grid = np.arange(t0, t1 + 1e-9, 1.0 / hz)
    positions = np.zeros((len(grid), len(tracks), 2))
    for i, track in enumerate(tracks):
        arr = np.asarray(track, dtype=float)
        idx = np.clip(np.searchsorted(arr[:, 0], grid, side='right') - 1, 0, len(arr) - 1)
        positions[:, i] = arr[idx, 1:3]
    return grid - t0, positions


def speeds(times: np.ndarray, positions: np.ndarray,
           window: float = SPEED_WINDOW) -> np.ndarray:
    """Backward-difference velocities (T, N, 2) over ``window`` seconds of camera track."""
    lag = max(1, round(window / float(times[1] - times[0]))) if len(times) > 1 else 1
    vel = np.zeros_like(positions)
    if len(times) > lag:
        vel[lag:] = (positions[lag:] - positions[:-lag]) / (times[lag:] - times[:-lag])[:, None,
                                                                                        None]
    return vel


def analyse(times: np.ndarray, positions: np.ndarray, shape, types: np.ndarray,
            goals: list, radii: dict[int, float], hold_s: float = 0.0) -> dict:
    """Metrics of one run: displacement, settling time (eq. 5.4, held ``hold_s`` seconds
    to the end of the run), bounds, goal errors."""
    from swarm_sim.metrics import displacement_lower_bound, path_lengths, settle_from_record

    velocities = speeds(times, positions)
    final = positions[-1]
    goal_xy = np.array([[g.x, g.y] for g in goals])
    goal_types = np.array([g.type for g in goals])
    # each robot's goal: nearest goal of its type to where it ended (assignment shown by
    # the agents' own states in the record; here only distances matter)
    errors = []
    for i, t in enumerate(types):
        mine = goal_xy[goal_types == t]
        errors.append(float(np.min(np.hypot(*(mine - final[i]).T))) if len(mine) else math.nan)
    inside = [bool(shape.region.contains(_point(p))) for p in final]
    return {
        'total_displacement': float(path_lengths(positions).sum()),
        'per_robot_displacement': [float(d) for d in path_lengths(positions)],
        'settling_time': settle_from_record(times, positions, velocities, shape,
                                            hold_s=hold_s)['settling_time'],
        'displacement_lower_bound': displacement_lower_bound(
            positions[0], goal_xy[np.argsort(goal_types, kind='stable')],
            np.sort(types, kind='stable'), shape, radii)
        if sorted(types.tolist()) == sorted(goal_types.tolist()) else math.nan,
        'final_goal_error': errors,
        'all_inside': all(inside),
        'final_speed_max': float(np.linalg.norm(velocities[-1], axis=1).max()),
        'duration': float(times[-1]),
    }


def _point(p):
    from shapely.geometry import Point
    return Point(float(p[0]), float(p[1]))


# -- monitor -------------------------------------------------------------------------------
class Monitor:
    """In-process node recording camera poses, agent states and the shape announcement."""

    def __init__(self, ids: list[int], pose_topic: str = '/agent_{k}/pose') -> None:
        from geometry_msgs.msg import PoseStamped, Twist
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile

        from swarm_mission import qos
        from swarm_msgs.msg import AgentState, FormationShape

        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('hil_monitor', context=self.context)
        self.lock = threading.Lock()
        self.tracks: dict[int, list[tuple[float, float, float]]] = {k: [] for k in ids}
        self.states: dict[int, object] = {}
        self.setpoints: dict[int, list[tuple[float, float, float]]] = {k: [] for k in ids}
        self.shape_time: float | None = None
        for k in ids:
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

    def _on_cmd(self, k: int, msg) -> None:
        with self.lock:
            self.setpoints[k].append((time.monotonic(), msg.linear.x, msg.linear.y))

    def _on_state(self, k: int, msg) -> None:
        with self.lock:
            self.states[k] = msg

    def _on_shape(self, msg) -> None:
        with self.lock:
            if self.shape_time is None:
                self.shape_time = time.monotonic()

    def snapshot(self) -> tuple[dict, dict, float | None]:
        with self.lock:
            return ({k: list(v) for k, v in self.tracks.items()}, dict(self.states),
                    self.shape_time)

    def close(self) -> None:
        import rclpy
        self.executor.shutdown()
        # The spin thread may still be inside its last wait: let it leave before the
        # node and context go, as launch_swarm does (a context torn down under it
        # aborted the process at exit once: "terminate called without an active
        # exception", return code -6, after a settled run).
        self.thread.join(timeout=5.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def record_settled(tracks: list[list[tuple[float, float, float]]], t0: float, now: float,
                   shape, hold_s: float) -> dict | None:
    """Eq. 5.4 with its hold, judged on the record so far exactly as ``analyse`` judges
    the whole run (the same grid, speeds and tracker); None while a robot's track is
    empty or more than a second old (a robot the camera lost is not settled)."""
    from swarm_sim.metrics import settle_from_record

    if any(not track or now - track[-1][0] > 1.0 for track in tracks):
        return None
    times, positions = resample(tracks, t0, now)
    return settle_from_record(times, positions, speeds(times, positions), shape,
                              hold_s=hold_s)


# -- one run -------------------------------------------------------------------------------
def hil_poses() -> tuple[dict, list[tuple[float, float, float]]]:
    """The hil_world parameters of config/hil.yaml and the initial poses in fleet order."""
    import yaml

    from swarm_bridge.fleet import load_fleet
    from swarm_bridge.hil_world_node import initial_poses

    params = yaml.safe_load(HIL_CONFIG.read_text())['hil_world']['ros__parameters']
    robots = load_fleet(params['fleet_file'] or None)
    return params, initial_poses([float(v) for v in params['initial_poses']], len(robots))


def sim_calibration(params: dict, path: pathlib.Path) -> pathlib.Path:
    """Calibrate the rendered camera of config/hil.yaml on its corner markers, as a user
    calibrates a real one (camera_calibrate), and write it to ``path``."""
    from swarm_bridge.arena_calibration import calibrate
    from swarm_bridge.camera_render import CameraRenderer, sim_camera_config

    calibrate(CameraRenderer(sim_camera_config(params)).render([])).save(path)
    return path


def run_shape(name: str, out: pathlib.Path, args: argparse.Namespace, domain: int) -> dict:
    """Run one shape through the ROS processes; return its metrics."""
    from swarm_bridge.fleet import load_fleet
    from swarm_mission.partition import partition
    from swarm_mission.robot_types import load_robot_types
    from swarm_mission.shapes import load_shape

    shape = load_shape(name)
    params, poses = hil_poses()
    robots = load_fleet(params['fleet_file'] or None)
    types = load_robot_types(HW_TYPES)
    radii = {t: r.coverage_radius for t, r in types.items()}
    counts: dict[int, int] = {}
    for r in robots:
        counts[r.type] = counts.get(r.type, 0) + 1
    type_counts = ','.join(f'{t}:{c}' for t, c in sorted(counts.items()))
    goals = partition(shape, counts, radii, 'bubble', seed=0).goals  # what agents compute
    run_dir = out / name
    (run_dir / 'logs').mkdir(parents=True, exist_ok=True)
    link = run_dir / 'coordinator.pty'
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               PYTHONUNBUFFERED='1')
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    children = Children(run_dir / 'logs', env)
    ids = [r.agent_id for r in robots]
    real = args.camera not in ('truth', 'sim')
    monitor = Monitor(ids, '/agent_{k}/pose' if real else '/truth/agent_{k}/pose')
    outcome = 'duration'
    t_end: float | None = None
    t_start = None
    try:
        if not real:
            world = {'port_link': str(link), 'camera': 'image' if args.camera == 'sim'
                     else 'truth'}
            if args.camera_noise is not None:
                world['camera_noise_m'] = float(args.camera_noise)
            if args.radio_loss is not None:
                world['radio_loss'] = float(args.radio_loss)
            # the file first: later -p overrides win
            children.start('hil_world', ['-m', 'swarm_bridge.hil_world_node', '--ros-args',
                                         '--params-file', str(HIL_CONFIG),
                                         *ros_args(world)[1:]])
            _wait(lambda: link.exists(), 20.0, 'the emulated robots (hil_world) never came up',
                  children)
        if args.camera != 'truth':
            tracker = {'calibration_file': args.calibration or str(
                sim_calibration(params, run_dir / 'camera_calibration.yaml')),
                'initial_poses': [v for x, y, yaw in poses
                                  for v in (x, y, math.degrees(yaw))]}
            if real:
                tracker['source'] = args.camera
            children.start('camera_tracker', [
                '-m', 'swarm_bridge.camera_tracker_node', '--ros-args', '--params-file',
                str(CAMERA_CONFIG), *ros_args(tracker)[1:], '-r', 'image:=/camera/image_raw'])
        children.start('bridge', ['-m', 'swarm_bridge.bridge_node',
                                  *ros_args({'port': args.port if real else str(link)})])
        for robot, (x, y, _) in zip(robots, poses):
            agent = ros_args({'agent_id': robot.agent_id, 'agent_type': robot.type,
                              'initial_x': x, 'initial_y': y, 'seed': robot.agent_id,
                              'robot_types_file': str(HW_TYPES), 'type_counts': type_counts},
                             ns=f'/agent_{robot.agent_id}', node='agent')
            children.start(f'agent_{robot.agent_id}', [
                '-m', 'swarm_bridge.hw_agent_node', '--ros-args', '--params-file',
                str(HW_AGENT), *agent[1:]])
        _wait(lambda: len(monitor.snapshot()[1]) == len(ids) and all(
            monitor.snapshot()[0].values()), 60.0, 'agents or camera never came up', children)
        children.start('mission', ['-m', 'swarm_mission.mission_node', *ros_args({
            'shape': name, 'method': 'bubble', 'type_counts': type_counts,
            'decentralized': True, 'formation_margin_m': 0.0})])
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
            judged = record_settled([tracks[k] for k in ids], t_start, now, shape,
                                    args.settle_hold)
            if judged is not None and judged['settled']:
                outcome, t_end = 'settled', now
                break
            if now - last_print >= 5.0:
                last_print = now
                print(f'  t={now - t_start:5.1f} s  not settled and held yet', flush=True)
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
        monitor.close()
        (run_dir / 'tracks.json').write_text(json.dumps(
            {'t_start': t_start, 'poses': tracks, 'cmd_vel': setpoints}))
        link.unlink(missing_ok=True)
    if t_start is None or not all(tracks.values()):
        return {'shape': name, 'outcome': outcome}
    times, positions = resample([tracks[k] for k in ids], t_start, t_end)
    robot_types = np.array([r.type for r in robots])
    metrics = analyse(times, positions, shape, robot_types, goals, radii, args.settle_hold)
    metrics.update(
        shape=name, outcome=outcome, camera=args.camera, thesis_table=THESIS_TABLE[name],
        thesis_total_displacement=THESIS[name][0], thesis_settling_time=THESIS[name][1],
        initial_poses=[list(p) for p in poses],
        final_positions=positions[-1].tolist(),
        goals=[{'id': g.id, 'type': g.type, 'x': g.x, 'y': g.y} for g in goals],
        assigned_goals={k: int(s.assigned_goal) for k, s in sorted(states.items())},
        bridge_log_warnings=_count_warnings(run_dir / 'logs' / 'bridge.log'))
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


def _count_warnings(path: pathlib.Path) -> int:
    try:
        return sum('WARN' in line for line in path.read_text(errors='replace').splitlines())
    except OSError:
        return 0


def plot(path: pathlib.Path, name: str, shape, positions: np.ndarray, goals: list,
         robots: list) -> None:
    """Traces from the initial positions to the goals, as thesis Figs. 5.11-5.20."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 5))
    xs, ys = shape.region.exterior.xy
    ax.plot(xs, ys, 'k-', lw=1.5)
    for g in goals:
        ax.add_patch(plt.Circle((g.x, g.y), g.radius, fill=False, color='k', lw=0.8))
    for i, r in enumerate(robots):
        ax.plot(positions[:, i, 0], positions[:, i, 1], 'b-', lw=1)
        ax.add_patch(plt.Circle(tuple(positions[-1, i]), r.radius, alpha=0.5,
                                color=r.color or 'gray'))
        ax.plot(*positions[0, i], 'o', color=r.color or 'gray', ms=4)
    ax.set_xlim(-1, 1)
    ax.set_ylim(-1, 1)
    ax.set_aspect('equal')
    ax.grid(True, lw=0.3)
    ax.set_title(f'{name}: HIL (emulated robots), 2 x 2 m arena')
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def table(results: list[dict]) -> str:
    """The per-shape comparison with thesis Tables 5.2-5.6."""
    lines = ['shape          table  displacement [m]  (thesis, bound)   settling [s] (thesis)'
             '  outcome']
    for m in results:
        name = m['shape']
        disp, settle = THESIS[name]
        got_d = m.get('total_displacement', math.nan)
        got_s = m.get('settling_time')
        bound = m.get('displacement_lower_bound', math.nan)
        s_text = f'{got_s:6.1f}' if got_s is not None else '     -'
        lines.append(f'{name:14s} {THESIS_TABLE[name]:5s}  {got_d:6.2f}       ({disp:.2f}, '
                     f'{bound:.2f})      {s_text}      ({settle:.0f})     {m["outcome"]}')
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    out = pathlib.Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    shapes = SHAPES if args.shape == 'all' else (args.shape,)
    base = args.domain if args.domain is not None else 101 + (os.getpid() % 60) * 2
    results = []
    for i, name in enumerate(shapes):
        # a domain per shape: a late packet of the previous run can never reach this one
        results.append(run_shape(name, out, args, (base + i) % 233))
        (out / 'hil.json').write_text(json.dumps(
            {'command': ' '.join(['scripts/hil_demo.py', *(argv or sys.argv[1:])]),
             'results': results}, indent=2, default=float))
    print(table(results))
    print(f'hil_demo: results in {out / "hil.json"}')
    return 0 if all(m['outcome'] == 'settled' for m in results) else 1


if __name__ == '__main__':
    sys.exit(main())
