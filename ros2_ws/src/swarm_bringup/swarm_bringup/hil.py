"""Hardware-in-the-loop demo (thesis 5.3, Figs. 5.11-5.20): its options, its processes
and the analysis of a run.

The processes of one shape as launch-plan entries (swarm_bringup.launch_plan.NodeSpec):
the emulated arena (``hil_world_node``), the camera tracker, the XBee bridge, one
``hw_agent_node`` per robot and the mission node. The analysis reads the camera tracks:
total displacement (summed track lengths), settling time (eq. 5.4), arrival time (every
robot at a distinct goal and still, held: the end of a run), the displacement lower bound
(optimal assignment of straight paths to the goals) and each robot's final distance to
its goal, reported next to thesis Tables 5.2-5.6. Pure: no ROS import.
"""

from __future__ import annotations

import argparse
import math
import pathlib

import numpy as np

from swarm_bringup.launch_plan import NodeSpec
from swarm_common.paths import package_file

DESCRIPTION = ('Hardware-in-the-loop run without hardware: the formations of thesis Figs. '
               '5.11-5.20.')
SHAPES = ('hw_trapezoid', 'hw_square', 'hw_pentagon', 'hw_arrow', 'hw_line')
# Thesis Tables 5.2-5.6 (Figs. 5.11-5.20): total displacement [m], settling time [s].
THESIS = {'hw_trapezoid': (1.75, 23.0), 'hw_square': (1.63, 19.0),
          'hw_pentagon': (1.95, 26.0), 'hw_arrow': (2.16, 29.0), 'hw_line': (1.80, 25.0)}
THESIS_TABLE = {'hw_trapezoid': '5.2', 'hw_square': '5.3', 'hw_pentagon': '5.4',
                'hw_arrow': '5.5', 'hw_line': '5.6'}
SPEED_WINDOW = 0.5        # s: camera speed = displacement over this window / window
GRID_HZ = 10.0            # common time grid of the recorded camera tracks
ARRIVE_SIGMAS = 2.0       # arrival tolerance: the agents' parking radius + this many
                          # camera standard deviations (their estimate of where they park)


def bridge_config(name: str) -> pathlib.Path:
    """A file of swarm_bridge's config/ (source tree or installed share folder)."""
    return package_file('swarm_bridge', f'config/{name}')


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=DESCRIPTION)
    p.add_argument('--shape', default='all', help=f'one of {", ".join(SHAPES)} or all')
    p.add_argument('--out', required=True, help='results directory')
    p.add_argument('--duration', type=float, default=90.0,
                   help='seconds at most per shape after the shape is announced')
    p.add_argument('--settle-hold', type=float, default=3.0,
                   help='seconds the swarm must stay arrived (every robot at a distinct '
                        'goal and still) to end a run; also the hold of eq. 5.4')
    p.add_argument('--arrive-tolerance', type=float, default=None,
                   help='m from its goal a robot counts as arrived (default: '
                        "config/hw_agent.yaml's hold_radius + 2 external_pose_std)")
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
    if args.arrive_tolerance is not None and args.arrive_tolerance <= 0:
        p.error(f'--arrive-tolerance {args.arrive_tolerance}: give a distance above 0 m')
    if args.radio_loss is not None and not 0.0 <= args.radio_loss <= 1.0:
        p.error(f'--radio-loss {args.radio_loss}: give a probability between 0 and 1')
    if args.camera not in ('truth', 'sim') and not args.calibration:
        p.error(f'--camera {args.camera}: give --calibration FILE (run camera_calibrate '
                f'--source {args.camera} --out FILE first)')
    return args


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
            goals: list, radii: dict[int, float], hold_s: float = 0.0,
            arrive_tol: float | None = None) -> dict:
    """Metrics of one run: displacement, settling time (eq. 5.4, held ``hold_s`` seconds
    to the end of the run), arrival time (``arrival_from_record``, tolerance
    ``arrive_tol``, default ``arrival_tolerance()``), bounds, goal errors."""
    from swarm_sim.metrics import displacement_lower_bound, path_lengths, settle_from_record

    tol = arrival_tolerance() if arrive_tol is None else arrive_tol

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
    typed = sorted(types.tolist()) == sorted(goal_types.tolist())
    arrival = (arrival_from_record(times, positions, velocities, types, goals, tol, hold_s)
               if typed else {'arrival_time': None})
    return {
        'total_displacement': float(path_lengths(positions).sum()),
        'per_robot_displacement': [float(d) for d in path_lengths(positions)],
        'settling_time': settle_from_record(times, positions, velocities, shape,
                                            hold_s=hold_s)['settling_time'],
        'displacement_lower_bound': displacement_lower_bound(
            positions[0], goal_xy[np.argsort(goal_types, kind='stable')],
            np.sort(types, kind='stable'), shape, radii)
        if typed else math.nan,
        'arrival_time': arrival['arrival_time'],
        'arrival_tolerance': tol,
        'final_arrival_error': arrival_error(final, types, goals) if typed else math.nan,
        'final_goal_error': errors,
        'all_inside': all(inside),
        'final_speed_max': float(np.linalg.norm(velocities[-1], axis=1).max()),
        'duration': float(times[-1]),
    }


def _point(p):
    from shapely.geometry import Point
    return Point(float(p[0]), float(p[1]))


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


def arrival_tolerance() -> float:
    """How close to a goal a robot has arrived: config/hw_agent.yaml's ``hold_radius`` (an
    agent parks when its estimate is that close) plus ``ARRIVE_SIGMAS`` times its
    ``external_pose_std`` (the camera error of that estimate): 0.02 + 2 x 0.01 m."""
    import yaml

    params = yaml.safe_load(bridge_config('hw_agent.yaml').read_text())['/**']['ros__parameters']
    return float(params['hold_radius']) + ARRIVE_SIGMAS * float(params['external_pose_std'])


def arrival_error(points: np.ndarray, types: np.ndarray, goals: list) -> float:
    """The smallest distance d such that every robot (``points`` (N, 2), ``types`` (N,))
    lies within d of a goal of its type, a distinct goal each: per type the bottleneck
    assignment of robots to goals, the largest over the types."""
    from swarm_sim.metrics import bottleneck_value

    goal_xy = np.array([[g.x, g.y] for g in goals], dtype=float).reshape(-1, 2)
    goal_types = np.array([g.type for g in goals])
    worst = 0.0
    for t in np.unique(types):
        mine, theirs = points[types == t], goal_xy[goal_types == t]
        if len(mine) != len(theirs):
            raise ValueError(f'{len(mine)} robots of type {t} but {len(theirs)} goals of it: '
                             'arrival needs one goal per robot')
        cost = np.linalg.norm(mine[:, None, :] - theirs[None, :, :], axis=2)
        worst = max(worst, bottleneck_value(cost))
    return worst


def arrived_now(points: np.ndarray, velocities: np.ndarray, types: np.ndarray, goals: list,
                tol: float) -> bool:
    """Every robot still (slower than eq. 5.4's settling speed) and within ``tol`` of a
    distinct goal of its type (``arrival_error``)."""
    from swarm_sim.metrics import SETTLE_SPEED

    if not np.all(np.hypot(velocities[:, 0], velocities[:, 1]) < SETTLE_SPEED):
        return False     # the cheap test first: while the robots drive it ends here
    return arrival_error(points, types, goals) <= tol


def arrival_from_record(times: np.ndarray, positions: np.ndarray, velocities: np.ndarray,
                        types: np.ndarray, goals: list, tol: float, hold_s: float,
                        since: float | None = None) -> dict:
    """``arrived_now`` replayed over a record (T samples, N robots) with eq. 5.4's hold
    (``swarm_sim.metrics.SettleTracker``): ``arrived`` when it held for ``hold_s`` to the
    end of the record, ``arrival_time`` when that streak began (from ``times[0]``; None
    unless arrived). ``since``: replay only the samples from that time on (the live
    check needs the last hold window, not the whole record)."""
    from swarm_sim.metrics import SettleTracker

    first = 0 if since is None else max(0, int(np.searchsorted(times, since)) - 1)
    tracker = SettleTracker(hold_s, t_start=float(times[0]))
    for k in range(first, len(times)):
        tracker.update(float(times[k]), arrived_now(positions[k], velocities[k], types,
                                                    goals, tol))
    result = tracker.result()
    return {'arrived': result['settled'], 'arrival_time': result['settling_time']}


def record_arrived(tracks: list[list[tuple[float, float, float]]], t0: float, now: float,
                   types: np.ndarray, goals: list, tol: float, hold_s: float) -> bool:
    """The end of a run: arrival held for ``hold_s`` on the record so far, judged on the
    grid and speeds ``analyse`` uses (so the run's metrics then give its arrival time);
    False while a robot's track is empty or more than a second old."""
    if any(not track or now - track[-1][0] > 1.0 for track in tracks):
        return False
    times, positions = resample(tracks, t0, now)
    return arrival_from_record(times, positions, speeds(times, positions), types, goals,
                               tol, hold_s, since=float(times[-1]) - hold_s)['arrived']


class MeshDelays:
    """How long the agents' mesh frames take from one agent's radio to another's, per
    hop: each frame seen on the agents' transmit topic (``sent``) matched by link source,
    kind, sequence number and payload to its copies on the receivers' topics
    (``received``). The agents' own radio lag starts at the medium's delivery stamp and
    misses a medium that falls behind before delivering; this includes it."""

    def __init__(self) -> None:
        self._sent: dict[tuple, float] = {}
        self.delays: list[float] = []

    @staticmethod
    def _key(packet) -> tuple:
        return (packet.source, int(packet.kind), packet.sequence, bytes(packet.payload))

    def sent(self, t: float, packets) -> None:
        """Packets (swarm_agent.packet.Packet) transmitted at ``t`` (s)."""
        for packet in packets:
            self._sent.setdefault(self._key(packet), t)

    def received(self, t: float, packets) -> None:
        """Packets received at ``t``; a packet not seen sent is not counted."""
        for packet in packets:
            t0 = self._sent.get(self._key(packet))
            if t0 is not None:
                self.delays.append(t - t0)

    def summary(self) -> dict:
        """Frames matched, median, 95th percentile and maximum delay (s), frames over 1 s."""
        if not self.delays:
            return {'frames': 0}
        d = np.asarray(self.delays)
        return {'frames': len(d), 'median': float(np.median(d)),
                'p95': float(np.percentile(d, 95)), 'max': float(d.max()),
                'over_1s': int((d > 1.0).sum())}


def sim_calibration(params: dict, path: pathlib.Path) -> pathlib.Path:
    """Calibrate the rendered camera of config/hil.yaml on its corner markers, as a user
    calibrates a real one (camera_calibrate), and write it to ``path``."""
    from swarm_bridge.arena_calibration import calibrate
    from swarm_bridge.camera_render import CameraRenderer, sim_camera_config

    calibrate(CameraRenderer(sim_camera_config(params)).render([])).save(path)
    return path


def count_warnings(path: pathlib.Path) -> int:
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
             '  arrival [s]  outcome']
    for m in results:
        name = m['shape']
        disp, settle = THESIS[name]
        got_d = m.get('total_displacement', math.nan)
        bound = m.get('displacement_lower_bound', math.nan)
        s_text, a_text = (f'{t:6.1f}' if t is not None else '     -'
                          for t in (m.get('settling_time'), m.get('arrival_time')))
        lines.append(f'{name:14s} {THESIS_TABLE[name]:5s}  {got_d:6.2f}       ({disp:.2f}, '
                     f'{bound:.2f})      {s_text}      ({settle:.0f})      {a_text}     '
                     f'{m["outcome"]}')
    return '\n'.join(lines)


# -- the processes of one shape ---------------------------------------------------------
def hil_world_node(port_link: pathlib.Path, args: argparse.Namespace) -> NodeSpec:
    """The emulated robots, their true poses and the mesh (config/hil.yaml; later -p
    win); the world publishes the camera's poses with ``--camera truth`` only."""
    world = {'port_link': str(port_link),
             'camera': 'image' if args.camera == 'sim' else 'truth'}
    if args.camera_noise is not None:
        world['camera_noise_m'] = float(args.camera_noise)
    if args.radio_loss is not None:
        world['radio_loss'] = float(args.radio_loss)
    return NodeSpec('swarm_bridge', 'hil_world_node', 'hil_world', parameters=world,
                    params_files=(str(bridge_config('hil.yaml')),))


def camera_sim_node(world: dict) -> NodeSpec:
    """The rendered overhead camera, a process of its own, with the camera settings of
    the world's parameters ``world`` (config/hil.yaml's hil_world section)."""
    from swarm_bridge.camera_render import SIM_CAMERA_PARAMETERS

    # An empty value is the node's default, and rcl cannot parse '-p name:='.
    return NodeSpec('swarm_bridge', 'camera_sim_node', 'hil_camera',
                    parameters={k: v for k, v in world.items()
                                if (k in SIM_CAMERA_PARAMETERS or k == 'fleet_file')
                                and v != ''})


def camera_tracker_node(calibration: str, poses: list[tuple[float, float, float]],
                        source: str | None = None) -> NodeSpec:
    """The camera tracker on the rendered (``source`` None) or a real camera."""
    tracker: dict = {'calibration_file': calibration,
                     'initial_poses': [v for x, y, yaw in poses
                                       for v in (x, y, math.degrees(yaw))]}
    if source is not None:
        tracker['source'] = source
    else:   # hil_world_node's images are reliable: none lost to the transport under load
        tracker['image_reliable'] = True
    return NodeSpec('swarm_bridge', 'camera_tracker_node', 'camera_tracker',
                    parameters=tracker, params_files=(str(bridge_config('camera.yaml')),),
                    remappings=(('image', '/camera/image_raw'),))


def bridge_node(port: str) -> NodeSpec:
    """The XBee bridge on the coordinator's serial port (or the emulator's pty)."""
    return NodeSpec('swarm_bridge', 'bridge_node', 'bridge', parameters={'port': port})


def hw_agent_nodes(robots: list, poses: list[tuple[float, float, float]],
                   type_counts: str) -> list[NodeSpec]:
    """One hardware agent per robot, ``/agent_K`` (its topics under ``agent_K/``), at
    its initial pose."""
    return [NodeSpec('swarm_agent', 'hw_agent_node', f'agent_{robot.id}',
                     name=f'agent_{robot.id}',
                     params_files=(str(bridge_config('hw_agent.yaml')),), parameters={
                         'agent_id': robot.id, 'agent_type': robot.type,
                         'initial_x': x, 'initial_y': y, 'seed': robot.id,
                         'robot_types_file': str(bridge_config('hw_robot_types.yaml')),
                         'type_counts': type_counts})
            for robot, (x, y, _) in zip(robots, poses)]


def hil_mission_node(shape: str, type_counts: str) -> NodeSpec:
    """The mission node: bubble packing partitioned on the agents, no formation margin."""
    return NodeSpec('swarm_mission', 'mission_node', 'mission', parameters={
        'shape': shape, 'method': 'bubble', 'type_counts': type_counts,
        'decentralized': True, 'formation_margin_m': 0.0})
