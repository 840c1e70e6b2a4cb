"""Fault-injection study of the headless swarm (issue 10): what survives which fault.

Runs the headless evaluator (``swarm_sim.headless``, the same brains, radio medium and
mission as the ROS system; scenarios built by ``swarm_eval.scenario``) under these
faults, each over ``--seeds`` seeds:

  loss_P        radio packet loss P % (0, 10, 20, 30, 50) from the start
  kill_P        P % (10, 30) of the agents killed at random times in the fault window
  beacons_one   one beacon removed at the fault time
  beacons_half  half of the beacons removed at the fault time
  range_R       radio range cut from 25 m to R m at the fault time (down to a partition)
  obstacle      a radio-opaque wall sweeping through the formation (links cut, not bodies)
  rogue_KIND    a transmitter without the key from t = 0 (``swarm_sim.rogue``): forged
                adverts (metric 1), forged cost rows, replays, a flood at 10x the rate

Radio frames are authenticated (the default, as on the robots); ``--no-auth`` runs the
cases without, to show what the rogues do then.

and reports per trial: the frames the receivers rejected, by kind
(``frame_auth.REJECTIONS``), coverage (``fraction_inside``, share of the final goals claimed by
a living agent, share with an agent of their type truly within ``GOAL_TOLERANCE_M``,
epsilon_t/epsilon_g), agreement of the
surviving agents (``assignment_agreement`` over the run and after the fault, at the end,
``duplicate_goal_claims_final`` and ``_peak``), recovery time (settling time, eq. 4.1 with
its hold window, minus the last fault time), collisions (``min_separation_ratio`` over every
simulation step of the run and after the fault, ``contacts``), and DSDV
health sampled every 2 s from the brains' route tables: the largest finite hop count
seen (count-to-infinity would push it to the network size or beyond), next-hop loops,
finite routes to dead agents, and the true link graph's connected components.

Writes into --out: ``faults.json`` (config, every trial, per-case means), ``faults.md``
(markdown table) and ``faults.png`` (bars per case).

Example (default: 20 agents, 4 beacons, circle_314, +/-25 m, 2 seeds, about 5 min on
2 cores and 10 more for the rogue cases; ``ros2 run swarm_eval fault_study`` takes the
same arguments):
  scripts/env.sh python scripts/fault_study.py --out results/faults
  scripts/env.sh python scripts/fault_study.py --out /tmp/faults --quick
"""

from __future__ import annotations

import argparse
import concurrent.futures as futures
import pathlib
import sys
from typing import Any

from swarm_common.robot_types import RobotTypeError
from swarm_common.shapes import ShapeError
from swarm_eval.fault_cases import (
    build_swarm,
    configure_fault,
    fault_cases,
    override,
    QUICK_CASES,
    RANGES,
    select_cases,
)
from swarm_eval.fault_probes import (
    coverage_columns,
    judge,
    min_beacons_heard,
    RouteMonitor,
    stale_routes_to_dead,
)
from swarm_eval.fault_report import markdown_table, plot, summarise, write_json
from swarm_eval.fault_ros import ROS_CASES, run_ros_study
from swarm_mission.partition import PartitionError
from swarm_sim.headless import ScenarioError


def run_case(case: dict, config: dict, seed: int) -> dict[str, Any]:
    """Run one (case, seed) trial and return its row of the study."""
    swarm = build_swarm(case, config, seed)
    first, last = configure_fault(swarm, case, config, seed)
    monitor = RouteMonitor(swarm, first)
    record = swarm.run(progress=monitor)
    monitor.sample(float(record.times[-1]))
    m = record.metrics
    beacons_alive = int((swarm.is_beacon & swarm.alive).sum())
    row: dict[str, Any] = {
        'case': case['name'], 'kind': case['kind'], 'value': case['value'], 'seed': seed,
        **coverage_columns(record, m, first, last, (record.times, record.min_separation)),
        'fraction_inside': m['fraction_inside'],
        'epsilon_t': m['epsilon_t'], 'epsilon_g': m['epsilon_g'],
        'assignment_agreement': m['assignment_agreement'],
        'duplicate_goal_claims_final': m['duplicate_goal_claims_final'],
        'duplicate_goal_claims_peak': m['duplicate_goal_claims_peak'],
        'min_separation_ratio': m['min_separation_ratio'], 'contacts': m['contacts'],
        'max_hops_seen': monitor.max_hops,
        'count_to_infinity': bool(monitor.max_hops_vs_size > 0),
        'routing_loops': monitor.loops,
        'stale_routes_to_dead': stale_routes_to_dead(swarm),
        'max_components_after_fault': monitor.max_components_after,
        'final_components': monitor.components_timeline[-1][1],
        'beacons_alive': beacons_alive, 'min_beacons_heard': min_beacons_heard(swarm),
        'final_modes_normal': m['final_modes_normal'],
        'rms_localization_error': m['rms_localization_error'],
        'auth': m['auth'], 'frames_rejected': m['frames_rejected'],
        'medium': m['medium'], 'events': record.events,
        'duration': m['duration'], 'wall_seconds': m['wall_seconds'],
    }
    return judge(row)



def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--out', required=True, help='results directory')
    parser.add_argument('--agents', type=int, default=None, help='swarm size (default 20)')
    parser.add_argument('--beacons', type=int, default=None, help='beacon count (default 4)')
    parser.add_argument('--seeds', type=int, default=None, help='seeds per case (default 2)')
    parser.add_argument('--seed', type=int, default=0, help='first seed')
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--shape', default=None,
                        help='shape (default circle_314; with --ros tests/data/square_8m.json)')
    parser.add_argument('--shape-scale', type=float, default=None)
    parser.add_argument('--half-size', type=float, default=None,
                        help='workspace half size of the random deployment [m]')
    parser.add_argument('--method', choices=('bubble', 'fractal'), default='bubble')
    parser.add_argument('--fault-time', type=float, default=None,
                        help='time of the fault (kills: start of the window) [s]')
    parser.add_argument('--fault-window', type=float, default=30.0,
                        help='kills happen at random times in this window [s]')
    parser.add_argument('--duration', type=float, default=None, help='max simulated s')
    parser.add_argument('--observe', type=float, default=None,
                        help='never stop before this long after the last fault [s] '
                        '(default 90, quick 20)')
    parser.add_argument('--ranges', type=float, nargs='+', default=None,
                        help='reduced radio ranges [m] (default 12 8 5 3)')
    parser.add_argument('--cases', default='', help='comma-separated subset of case names')
    parser.add_argument('--no-auth', dest='auth', action='store_false',
                        help='unauthenticated radio frames (headless only; to show what '
                        'the rogue cases do without authentication)')
    parser.add_argument('--quick', action='store_true',
                        help='tiny swarm and short trials (a test, seconds)')
    parser.add_argument('--ros', action='store_true',
                        help='run the cases through the full ROS system (launch_swarm, '
                        'composed agents, one run at a time; default 12 agents, 4 beacons, '
                        'the 8 m square in +/-15 m, cases ' + ','.join(ROS_CASES) + ')')
    return parser.parse_args(argv)


def study_config(args: argparse.Namespace) -> dict[str, Any]:
    """Defaults of the full study, or of --quick, overridden by explicit arguments."""
    if args.quick:
        base = {'agents': 6, 'beacons': 4, 'seeds': 1, 'shape_scale': 0.6, 'half_size': 10.0,
                'fault_time': 40.0, 'duration': 150.0, 'ranges': (2.0,), 'wall_speed': 2.0,
                'observe': 20.0}
    else:
        base = {'agents': 20, 'beacons': 4, 'seeds': 2, 'shape_scale': 1.0,
                'half_size': 25.0, 'fault_time': 120.0, 'duration': 360.0, 'ranges': RANGES,
                'wall_speed': 1.0, 'observe': 90.0}
    override(base, args, ('agents', 'beacons', 'seeds', 'shape_scale', 'half_size',
                           'fault_time', 'duration', 'observe'))
    base.update(shape=args.shape or 'circle_314', method=args.method,
                fault_window=args.fault_window, seed=args.seed, workers=args.workers,
                quick=args.quick, auth=args.auth)
    if args.quick:
        base['fault_window'] = min(base['fault_window'], 10.0)
    return base


def main(argv: list[str] | None = None) -> int:
    """``fault_study``: run the cases (headless, or --ros), write faults.*."""
    args = parse_args(argv)
    if args.ros:
        if not args.auth:
            print('fault_study.py: --no-auth is for the headless study (launch_swarm runs '
                  'the agents with authenticated radio frames)', file=sys.stderr)
            return 2
        return run_ros_study(args, argv)
    config = study_config(args)
    cases = select_cases(fault_cases(config['ranges']), args.cases,
                         set(QUICK_CASES) if args.quick else None)
    if cases is None:
        return 2
    try:
        if config['seeds'] < 1 or config['workers'] < 1:
            raise ScenarioError('--seeds and --workers must be at least 1')
        if config['fault_time'] >= config['duration']:
            raise ScenarioError('--fault-time must be before the end of --duration')
        build_swarm(cases[0], config, config['seed'])
    except (ShapeError, ScenarioError, RobotTypeError, PartitionError) as exc:
        print(f'fault_study.py: {exc}', file=sys.stderr)
        return 2
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = [config['seed'] + k for k in range(config['seeds'])]
    jobs = [(case, seed) for case in cases for seed in seeds]
    rows: list[dict] = []
    from tqdm import tqdm

    if config['workers'] == 1:
        for case, seed in tqdm(jobs, unit='trial', desc='faults'):
            rows.append(run_case(case, config, seed))
    else:
        with futures.ProcessPoolExecutor(max_workers=config['workers']) as pool:
            pending = [pool.submit(run_case, case, config, seed) for case, seed in jobs]
            for job in tqdm(futures.as_completed(pending), total=len(pending), unit='trial',
                            desc='faults'):
                rows.append(job.result())
    order = {c['name']: k for k, c in enumerate(cases)}
    rows.sort(key=lambda r: (order[r['case']], r['seed']))
    summary = summarise(rows, cases)
    payload = {'config': config, 'command': ' '.join(['scripts/fault_study.py', *(
        argv if argv is not None else sys.argv[1:])]), 'cases': summary, 'trials': rows}
    write_json(out / 'faults.json', payload)
    (out / 'faults.md').write_text(markdown_table(summary), encoding='utf-8')
    plot(out / 'faults.png', summary)
    print(markdown_table(summary))
    print(f'fault study: {len(rows)} trials -> {out}')
    return 0



if __name__ == '__main__':
    sys.exit(main())
