"""What a swarm run leaves in its folder: record.npz, metrics.json and the figures.

``write_results`` turns the monitor's record and the launcher's own figures (outcome,
wall and CPU time, memory, faults sent, sim settings applied) into the run's files
through swarm_sim.report, prints the one-line summary and returns the exit code.

A run whose launcher was killed (SIGKILL, power) never wrote record.npz, but its bag
``run.mcap`` (flushed every second) and the sim's ``truth.csv`` hold all but its last
seconds: ``record_from_bag`` rebuilds the monitor's record from the bag, and
``python -m swarm_bringup.results OUT`` writes it as ``OUT/record_from_bag.npz`` (the
reader says in one line when the bag was cut). Pure: no ROS import.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
import json
import pathlib
import re
import resource
import sys

import numpy as np


@dataclass
class RunSummary:
    """The launcher's view of a run, gathered while it runs and when it ends."""

    mode: str
    outcome: str = 'not settled'
    crashed: str | None = None
    t: float = 0.0                                   # sim time of the last poll
    wall: float = 0.0
    cpu: float = 0.0
    started: tuple[float, float] | None = None       # (wall, sim) s: every agent heard
    peak_rss: int = 0
    peak_pss: int = 0
    truth_readers: list[str] = field(default_factory=list)
    shapes: list = field(default_factory=list)       # (sim time, shape) announced
    goals: list = field(default_factory=list)        # the final goals
    rounds: int = 0
    heard: list[int] = field(default_factory=list)
    goal_versions: int = 0
    settling: dict | None = None
    sim_settings: list[dict] = field(default_factory=list)
    faults: list[dict] = field(default_factory=list)


def write_results(out: pathlib.Path, args: argparse.Namespace, fleet, shape, beacons: int,
                  domain: int, record: dict, s: RunSummary) -> int:
    """Write record.npz, metrics.json and the figures; print the summary; the exit code
    (1 after a crash or a sim setting not applied, else 0)."""
    from swarm_sim.report import run_report, write_metrics

    robots = sorted(fleet, key=lambda r: r.id)
    # The 2 Hz record of truth and belief, for plots and post-mortems of one agent.
    final_goals = s.goals or []
    record.update(
        goal_id=np.array([g.id for g in final_goals], dtype=np.int64),
        goal_type=np.array([g.type for g in final_goals], dtype=np.int64),
        goal_xy=np.array([[g.x, g.y] for g in final_goals], dtype=float).reshape(-1, 2))
    # The sim's closest approach of coverage circles and body contacts over every physics
    # step (sim_node writes it when it closes); without it no separation is reported.
    separation = None
    try:
        separation = json.loads((out / 'separation.json').read_text(encoding='utf-8'))
        series = separation.pop('series')
        record.update(separation_times=np.array(series['times'], dtype=float),
                      separation_min=np.array(series['min'], dtype=float))
    except (OSError, ValueError, KeyError):
        if s.crashed != 'sim':   # a killed sim writes nothing at close; already said
            print('launch_swarm: the sim left no separation.json: no separation metrics',
                  file=sys.stderr)
    np.savez_compressed(out / 'record.npz', **record)
    shapes = [sh for _, sh in s.shapes] or [shape]
    wall, started = s.wall, s.started
    metrics = run_report(out, record, [r.type for r in robots],
                         [r.is_beacon for r in robots], shapes, s.goals,
                         shape_times=[t for t, _ in s.shapes] or None,
                         settling=s.settling, separation=separation,
                         settle_hold_s=args.settle_hold, extra={
                             'mode': s.mode, 'outcome': s.outcome, 'wall_seconds': wall,
                             'cpu_seconds_children': s.cpu,
                             'cpu_cores_used': s.cpu / wall if wall > 0 else 0.0,
                             # Start-up (processes, discovery, first commands) apart from
                             # the running swarm: the same swarm's real-time factor once
                             # every agent had been heard.
                             'startup_wall_seconds': started and started[0],
                             'steady_real_time_factor':
                                 (s.t - started[1]) / (wall - started[0])
                                 if started and wall - started[0] > 1.0 else None,
                             'peak_rss_bytes': s.peak_rss, 'peak_pss_bytes': s.peak_pss,
                             'consensus_rounds': s.rounds,
                             'launcher_max_rss_bytes': resource.getrusage(
                                 resource.RUSAGE_SELF).ru_maxrss * 1024,
                             'seed': args.seed, 'truth_subscribers': s.truth_readers,
                             'goal_versions': s.goal_versions, 'agents_heard': s.heard,
                             'sim_settings': s.sim_settings, 'faults': s.faults})
    scenario = {k: v for k, v in vars(args).items()}
    scenario.update(beacons=beacons, domain=domain)
    write_metrics(out, [metrics], scenario)
    print(f'launch_swarm: {s.outcome}; settling {metrics.get("settling_time")} s, '
          f'rtf {metrics.get("real_time_factor", 0):.2f}, displacement '
          f'{metrics.get("total_displacement", float("nan")):.0f} m, eps_t '
          f'{metrics.get("epsilon_t", float("nan")):.2f}, eps_g '
          f'{metrics.get("epsilon_g", float("nan")):.2f}; results in {out}')
    failed = [e for e in s.sim_settings if not e['ok']]
    if failed and s.outcome != 'interrupted':
        print('launch_swarm: --set-sim not applied: ' + '; '.join(
            f'{e["name"]}={e["value"]:g} at {e["time"]:g} s ({e["reason"]})' for e in failed),
            file=sys.stderr)
    return 1 if s.crashed or (failed and s.outcome != 'interrupted') else 0


STATE_TOPIC = re.compile(r'/agent_(\d+)/state$')
TRUTH_TOPIC = re.compile(r'/swarm/truth$')    # under any namespace


def record_from_bag(bag: str | pathlib.Path, agent_ids: list[int],
                    period_s: float = 0.5) -> dict[str, np.ndarray]:
    """The monitor's record (swarm_bringup.monitor_node: ``times``, true ``positions``,
    ``velocities`` and ``alive``, and each agent's latest state at that time:
    ``estimates``, ``modes``, ``goal_ids``, ``digests``, ``rounds``, ``localized``) at
    the truth messages of a bag at least ``period_s`` of sim time apart. A bag cut by a
    kill gives the samples before the cut. On a 12-agent run (180 s) the truth samples
    equal the monitor's record.npz; 0.07 % of the modes and some estimates differ, by
    one state message that reached the recorder and the monitor in another order."""
    from swarm_bringup.bag import read_messages

    index = {a: i for i, a in enumerate(agent_ids)}
    n = len(agent_ids)
    states: list = [None] * n
    rec: dict[str, list] = {k: [] for k in (
        'times', 'positions', 'velocities', 'alive', 'estimates', 'modes', 'goal_ids',
        'digests', 'rounds', 'localized')}
    last = -np.inf
    for topic, _, _, msg in read_messages(bag):
        if STATE_TOPIC.search(topic):
            i = index.get(int(msg.id))
            if i is not None:
                states[i] = msg
            continue
        if not TRUTH_TOPIC.search(topic):
            continue
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        if t - last < period_s - 1e-6:
            continue
        last = t
        pos, vel = np.full((n, 2), np.nan), np.zeros((n, 2))
        alive = np.zeros(n, dtype=bool)
        for a in msg.agents:
            i = index.get(int(a.id))
            if i is not None:
                pos[i], vel[i], alive[i] = a.position, a.velocity, a.alive
        rec['times'].append(t)
        rec['positions'].append(pos)
        rec['velocities'].append(vel)
        rec['alive'].append(alive)
        rec['estimates'].append([s.position if s is not None else (np.nan, np.nan)
                                 for s in states])
        rec['modes'].append([s.mode if s is not None else -1 for s in states])
        rec['goal_ids'].append([s.assigned_goal if s is not None else -1 for s in states])
        rec['digests'].append([s.assignment_digest if s is not None else 0 for s in states])
        rec['rounds'].append([s.assignment_round if s is not None else 0 for s in states])
        rec['localized'].append([bool(s is not None and s.localized) for s in states])
    dtypes = {'alive': bool, 'localized': bool, 'modes': np.int64, 'goal_ids': np.int64,
              'digests': np.int64, 'rounds': np.int64}
    empty = {'times': (0,), 'positions': (0, n, 2), 'velocities': (0, n, 2),
             'estimates': (0, n, 2)}
    return {k: np.asarray(v, dtype=dtypes.get(k, float)) if v else
            np.zeros(empty.get(k, (0, n)), dtype=dtypes.get(k, float))
            for k, v in rec.items()}


def main(argv: list[str] | None = None) -> int:
    """``python -m swarm_bringup.results OUT``: OUT/record_from_bag.npz from OUT/run.mcap
    and OUT/fleet.yaml (a run whose launcher was killed); bad input is one line, exit 2."""
    import logging

    from swarm_common.fleet import load_fleet

    parser = argparse.ArgumentParser(
        description='The record of a killed run rebuilt from its bag.')
    parser.add_argument('out', help='the folder of the run (run.mcap, fleet.yaml)')
    out = pathlib.Path(parser.parse_args(argv).out)
    logging.basicConfig(format='results: %(message)s')
    try:
        ids = sorted(r.id for r in load_fleet(out / 'fleet.yaml'))
        if not (out / 'run.mcap').is_file():
            raise ValueError(f'{out / "run.mcap"}: no such bag (was the run recorded '
                             'with --no-record?)')
        record = record_from_bag(out / 'run.mcap', ids)
    except (OSError, ValueError) as exc:
        print(f'results: {exc}', file=sys.stderr)
        return 2
    np.savez_compressed(out / 'record_from_bag.npz', **record)
    times = record['times']
    print(f'results: {len(times)} samples of {len(ids)} agents'
          + (f' from t={times[0]:.1f} to {times[-1]:.1f} s' if len(times) else '')
          + f' -> {out / "record_from_bag.npz"}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
