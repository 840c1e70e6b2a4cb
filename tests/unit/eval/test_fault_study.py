"""swarm_eval.fault_study (scripts/fault_study.py, issue 10) runs end to end on a tiny swarm
and checks its probes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from swarm_agent.dsdv import RouteEntry
from swarm_common.shapes import load_shape
from swarm_eval import fault_cases, fault_probes, fault_report, fault_ros, fault_study
from swarm_sim.headless import HeadlessSwarm, Scenario

ROW_KEYS = {'case', 'seed', 'fraction_inside', 'goals_claimed', 'goals_reached',
            'epsilon_t', 'epsilon_g',
            'assignment_agreement', 'agreement_after_fault', 'final_agreement',
            'duplicate_goal_claims_final', 'duplicate_goal_claims_peak', 'settling_time',
            'recovery_time', 'min_separation_ratio', 'contacts',
            'min_separation_after_fault', 'max_hops_seen', 'count_to_infinity',
            'routing_loops', 'stale_routes_to_dead', 'max_components_after_fault',
            'beacons_alive', 'min_beacons_heard', 'passed', 'target_applies'}


def test_quick_study_writes_table_plot_and_json(tmp_path, capsys):
    out = tmp_path / 'faults'
    assert fault_study.main(['--out', str(out), '--quick', '--workers', '1',
                             '--cases', 'loss_0,kill_30']) == 0
    assert (out / 'faults.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    data = json.loads((out / 'faults.json').read_text())
    assert set(data['cases']) == {'loss_0', 'kill_30'}
    assert data['config']['agents'] == 6 and data['config']['quick']
    for row in data['trials']:
        assert ROW_KEYS <= set(row)
        # DSDV never counts to infinity: finite hop counts stay below the swarm size
        assert not row['count_to_infinity'] and row['max_hops_seen'] < row['agents']
        assert row['routing_loops'] == 0
    lossless = next(r for r in data['trials'] if r['case'] == 'loss_0')
    assert lossless['fraction_inside'] == 1.0 and lossless['goals_claimed'] == 1.0
    assert lossless['duplicate_goal_claims_final'] == 0 and lossless['settled']
    killed = next(r for r in data['trials'] if r['case'] == 'kill_30')
    assert killed['agents_alive'] == 4 and killed['fault_time'] >= 40.0
    assert killed['stale_routes_to_dead'] == 0  # broken links invalidated the routes
    table = (out / 'faults.md').read_text()
    assert table.startswith('| Case |') and '| loss_0 |' in table and '| kill_30 |' in table
    assert 'fault study: 2 trials' in capsys.readouterr().out


def test_fault_cases_cover_the_issue():
    names = [c['name'] for c in fault_cases.fault_cases()]
    assert names[:5] == ['loss_0', 'loss_10', 'loss_20', 'loss_30', 'loss_50']
    assert {'kill_10', 'kill_30', 'beacons_one', 'beacons_half', 'obstacle'} <= set(names)
    assert [n for n in names if n.startswith('range_')] == ['range_12', 'range_8', 'range_5',
                                                            'range_3']


def _swarm(**kwargs) -> HeadlessSwarm:
    return HeadlessSwarm(Scenario(shape=load_shape('circle_314', scale=0.3),
                                  type_counts={1: 3}, n_beacons=3, half_size=6.0,
                                  duration_s=4.0, **kwargs))


def test_events_hook_runs_at_its_time_and_prevents_an_early_stop():
    calls = []
    swarm = _swarm(events=[(3.0, lambda sw, t: calls.append(t))])
    swarm.scenario.settle_hold_s = 0.0
    record = swarm.run()
    assert calls == [pytest.approx(3.0)]
    assert record.times[-1] >= 3.0


def test_loop_and_stale_route_probes():
    swarm = _swarm()
    a, b, c = (brain.router for brain in swarm.brains)
    # a -> b -> a for destination c: a next-hop loop
    a.set_route(RouteEntry(c.id, b.id, 2, 10))
    b.set_route(RouteEntry(c.id, a.id, 2, 10))
    assert fault_probes.count_routing_loops(swarm) == 2
    swarm.alive[2] = False
    swarm.brains[2] = None
    assert fault_probes.stale_routes_to_dead(swarm) == 2
    assert fault_probes.count_routing_loops(swarm) == 2


def test_critical_range_is_the_longest_spanning_tree_edge():
    points = np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 0.0], [5.0, 2.0]])
    assert fault_probes.critical_range(points) == pytest.approx(4.0)
    assert fault_probes.critical_range(points[:1]) == 0.0


@pytest.mark.parametrize('args', [['--seeds', '0'], ['--cases', 'nonsense'],
                                  ['--fault-time', '500', '--duration', '100']])
def test_bad_arguments_rejected(tmp_path, capsys, args):
    assert fault_study.main(['--out', str(tmp_path), '--quick', *args]) == 2
    assert 'fault_study.py:' in capsys.readouterr().err


def test_count_loops_follows_next_hops():
    assert fault_probes.count_loops({0: {2: 1}, 1: {2: 2}, 2: {}}) == 0
    assert fault_probes.count_loops({0: {2: 1}, 1: {2: 0}}) == 2


def test_the_fault_plan_becomes_launcher_flags(tmp_path):
    config = fault_ros.ros_config(fault_study.parse_args(['--out', '-', '--ros']))
    cases = {c['name']: c for c in fault_cases.fault_cases(config['ranges'])}
    argv, plan = fault_ros.ros_launch_argv(cases['obstacle'], config, 0, tmp_path)
    assert argv[argv.index('--set-sim') + 1] == '80:radio_wall_speed_mps=1'
    assert plan['last'] == 80.0 + 30.0   # the wall crosses +/-15 m at 1 m/s
    assert argv[argv.index('--min-duration') + 1] == '170'
    argv, plan = fault_ros.ros_launch_argv(cases['kill_30'], config, 0, tmp_path)
    removed = [argv[k + 1] for k, a in enumerate(argv) if a == '--remove']
    assert len(removed) == 4 and all(80.0 <= float(r.split(':')[0]) <= 110.0
                                      for r in removed)
    argv, _ = fault_ros.ros_launch_argv(cases['loss_20'], config, 0, tmp_path)
    assert argv[argv.index('--set-sim') + 1] == '0:loss=0.2' and '--min-duration' not in argv


def _synthetic_ros_run(run_dir):
    """4 robots on the 8 m square (0-2 beacons); beacon 2 removed at 3 s, range 3 m at 2 s."""
    from swarm_common.fleet import RobotSpec, save_fleet

    (run_dir / 'logs').mkdir(parents=True)
    (run_dir / 'logs' / 'sim.log').write_text('[INFO] fine\n')
    (run_dir / 'logs' / 'agents.log').write_text(
        'Traceback (most recent call last):\n  ...\nRuntimeError: boom\n')
    xy = np.array([[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]])
    save_fleet(run_dir / 'fleet.yaml', [RobotSpec(i, 1, i < 3, *map(float, xy[i]))
                                          for i in range(4)])
    times = np.arange(10) * 0.5
    alive = np.ones((10, 4), bool)
    alive[6:, 2] = False
    hops = np.full((2, 4, 4), 255)
    nxt = np.full((2, 4, 4), -1)
    hops[0, 0, 3], nxt[0, 0, 3], hops[0, 1, 3], nxt[0, 1, 3] = 2, 1, 2, 0   # a loop 0-1-0
    hops[1, 0, 2], nxt[1, 0, 2] = 3, 1          # a route to dead 2, 3 hops among 3 alive
    np.savez(run_dir / 'record.npz', times=times, positions=np.repeat(xy[None], 10, 0),
             velocities=np.zeros((10, 4, 2)), estimates=np.repeat(xy[None], 10, 0),
             modes=np.zeros((10, 4), int), alive=alive,
             goal_ids=np.tile([0, 0, 1, 1], (10, 1)), digests=np.full((10, 4), 7),
             rounds=np.ones((10, 4), int), agent_ids=np.arange(4),
             route_times=np.array([1.0, 4.5]), route_next=nxt, route_hops=hops,
             route_stamp=np.array([[1.0] * 4, [4.5] * 4]),
             goal_id=np.array([0, 1, 2]), goal_type=np.array([1, 1, 1]),
             goal_xy=xy[[0, 1, 3]])
    metrics = {'fraction_inside': 1.0, 'epsilon_t': 0.1, 'epsilon_g': 0.05,
               'assignment_agreement': 1.0, 'duplicate_goal_claims_final': 1,
               'duplicate_goal_claims_peak': 1, 'min_separation_ratio': 4.0, 'contacts': 0,
               'settled': True, 'settling_time': 0.0, 'outcome': 'settled', 'duration': 4.5,
               'sim_settings': [{'time': 2.0, 'sent_at': 2.0, 'name': 'radio_range_m',
                                 'value': 3.0, 'ok': True, 'reason': ''}]}
    (run_dir / 'metrics.json').write_text(json.dumps({'trials': [metrics]}))


def test_a_ros_run_becomes_a_row_of_the_table(tmp_path):
    run_dir = tmp_path / 'range_3_s0'
    _synthetic_ros_run(run_dir)
    config = fault_ros.ros_config(fault_study.parse_args(['--out', '-', '--ros']))
    case = {'name': 'range_3', 'kind': 'range', 'value': 3.0}
    plan = {'first': 2.0, 'last': 3.0, 'removals': [(3.0, [2])], 'settings': []}
    row = fault_ros.ros_row(case, config, 0, run_dir, plan, 1, 12.0)
    assert ROW_KEYS <= set(row)
    assert row['crashed'] == [] and row['tracebacks'] == ['agents'] and not row['passed']
    assert row['agents'] == 4 and row['agents_alive'] == 3 and row['beacons_alive'] == 2
    assert row['settled'] and row['recovery_time'] == 0.0
    assert row['goals_claimed'] == pytest.approx(2 / 3)   # goal 2 unclaimed
    assert row['routing_loops'] == 2 and row['max_hops_seen'] == 3
    assert row['count_to_infinity']             # 3 hops among 3 living agents
    assert row['stale_routes_to_dead'] == 1
    # 4 m apart with a 3 m range after t = 2 s: no links, every agent alone
    assert row['max_components_after_fault'] == 4 and row['final_components'] == 3
    assert row['min_beacons_heard'] == 0 and not row['target_applies']
    summary = fault_report.summarise([row], [case])
    table = fault_report.markdown_table(summary, crashes=True)
    assert '| range_3 |' in table and '| crashed |' in table.splitlines()[0] + '|'
    assert table.splitlines()[2].endswith('| 0/1 | 0/1 |')
    metrics = json.loads((run_dir / 'metrics.json').read_text())
    metrics['trials'][0]['outcome'] = 'crash of agents'
    (run_dir / 'metrics.json').write_text(json.dumps(metrics))
    row = fault_ros.ros_row(case, config, 0, run_dir, plan, 1, 12.0)
    assert row['crashed'] == ['agents']
    table = fault_report.markdown_table(fault_report.summarise([row], [case]), crashes=True)
    assert table.splitlines()[2].endswith('| 1/1 | 0/1 |')


def test_a_ros_run_without_results_is_a_crash(tmp_path):
    case = {'name': 'loss_0', 'kind': 'loss', 'value': 0.0}
    row = fault_ros.ros_row(case, {}, 0, tmp_path, {'first': 0.0, 'last': 0.0}, None, 5.0)
    assert row['crashed'] == ['launcher'] and not row['passed'] and 'no results' in row['error']
    summary = fault_report.summarise([row], [case])
    assert summary['loss_0']['crashed'] == 1 and summary['loss_0']['passed'] == 0


def test_the_observation_window_does_not_restart_the_settled_hold():
    """Recovery is measured from the fault: the observation window after it keeps the run
    going (min_duration_s) without being a change. As a scheduled event it ended the
    settled streak, so no recovery could be shorter than the window."""
    config = fault_study.study_config(fault_study.parse_args(['--quick', '--out', 'x']))
    case = next(c for c in fault_cases.fault_cases(config['ranges'])
                if c['name'] == 'beacons_one')
    swarm = fault_cases.build_swarm(case, config, 0)
    first, last = fault_cases.configure_fault(swarm, case, config, 0)
    assert swarm.scenario.min_duration_s == pytest.approx(last + config['observe'])
    assert all(t <= last for t, _ in swarm.scenario.events)


def test_runtime_settings_change_the_medium_as_sim_node_does():
    """swarm_sim.medium.apply_setting: a shorter range and a sweeping wall cut the link of
    two agents 4 m apart; loss is the packet loss; an unknown name is refused."""
    from swarm_sim.medium import apply_setting, MediumConfig, RadioMedium

    medium = RadioMedium(MediumConfig(), np.random.default_rng(0), [])
    ids, xy = [0, 1], np.array([[-2.0, 0.0], [2.0, 0.0]])
    medium.update_positions(ids, xy)
    assert list(medium.neighbours(0)) == [1]
    apply_setting(medium, 'radio_range_m', 3.0, 0.0, 10.0)
    medium.update_positions(ids, xy)
    assert list(medium.neighbours(0)) == []
    apply_setting(medium, 'radio_range_m', 25.0, 0.0, 10.0)
    apply_setting(medium, 'radio_wall_speed_mps', 1.0, 5.0, 10.0)   # x = 0 at t = 15 s
    assert medium.move_wall(15.0) == pytest.approx(0.0)
    medium.update_positions(ids, xy)
    assert list(medium.neighbours(0)) == []
    apply_setting(medium, 'loss', 0.3, 15.0, 10.0)
    assert medium.config.loss == pytest.approx(0.3)
    with pytest.raises(ValueError, match='unknown medium setting'):
        apply_setting(medium, 'gravity', 1.0, 0.0, 10.0)


def test_rogue_cases_put_the_same_rogue_on_the_headless_and_the_ros_radio(tmp_path, capsys):
    """A rogue case is the setting ``rogue`` from t = 0 and one non-beacon agent removed
    at the fault time: headless, the scenario gets the rogue class (sealing bad tags when
    the swarm authenticates); through ROS, the launcher's --set-sim, which its own parser
    accepts. rogue_none is the reference without a rogue. --no-auth is headless only."""
    from swarm_bringup.scenario import parse_set_sim
    from swarm_sim.rogue import ForgedCostRows, ROGUE_KINDS

    assert set(fault_cases.ROGUE_CASES) <= set(fault_cases.QUICK_CASES)
    assert {'rogue_none', 'rogue_adverts', 'rogue_replay'} <= set(fault_cases.ROS_CASES)
    cases = {c['name']: c for c in fault_cases.fault_cases()}
    assert [cases[f'rogue_{k}']['kind'] for k in ('none', *ROGUE_KINDS)] == ['rogue'] * 5
    for auth, flags in ((True, []), (False, ['--no-auth'])):
        config = fault_study.study_config(fault_study.parse_args(['--quick', '--out', 'x',
                                                                  *flags]))
        swarm = fault_cases.build_swarm(cases['rogue_costs'], config, 0)
        assert swarm.scenario.auth is auth
        t = config['fault_time']
        assert fault_cases.configure_fault(swarm, cases['rogue_costs'], config, 0) == (t, t)
        (rogue,) = swarm.scenario.rogues
        assert isinstance(rogue, ForgedCostRows) and rogue.trailer is auth
        assert rogue.start_s == 0.0 and not swarm.scenario.events
        ((when, (victim,)),) = swarm.scenario.removals
        assert when == t and not swarm.is_beacon[swarm.index[victim]]
        assert swarm.scenario.min_duration_s == t + config['observe']
    swarm = fault_cases.build_swarm(cases['rogue_none'], config, 0)
    fault_cases.configure_fault(swarm, cases['rogue_none'], config, 0)
    assert swarm.scenario.rogues == () and swarm.scenario.removals == [(t, [victim])]
    config = fault_ros.ros_config(fault_study.parse_args(['--out', '-', '--ros']))
    argv, plan = fault_ros.ros_launch_argv(cases['rogue_replay'], config, 0, tmp_path)
    assert argv[argv.index('--set-sim') + 1] == '0:rogue=3'
    assert parse_set_sim('0:rogue=3') == (0.0, 'rogue', 3.0)
    with pytest.raises(Exception, match='1 adverts, 2 costs'):
        parse_set_sim('0:rogue=7')
    assert fault_study.main(['--out', str(tmp_path), '--ros', '--no-auth']) == 2
    assert '--no-auth is for the headless study' in capsys.readouterr().err


def test_frames_rejected_by_kind_reach_the_table(tmp_path):
    """Headless rows carry the metrics' counts; ROS rows the sum of every agent's last
    status line (counts since the agent started)."""
    logs = tmp_path / 'logs'
    logs.mkdir()
    line = ('[INFO] [1.5] [agent_{a}]: mode NORMAL at (0.26, 0.13); goal 4 (v1, 2 rows); '
            "router {{'sent': 3}}; rejected frames {r}; radio lag max 0.17 s\n")
    logs.joinpath('agents.log').write_text(
        line.format(a=1, r="{'auth_bad_tag': 5}") + line.format(a=2, r='{}')
        + line.format(a=1, r="{'auth_bad_tag': 9, 'auth_replay': 2}")
        + line.format(a=3, r="{'auth_replay': 4}"))
    assert fault_ros.rejected_from_logs(tmp_path) == {'auth_bad_tag': 9, 'auth_replay': 6}
    assert fault_ros.rejected_from_logs(tmp_path / 'none') is None
    case = {'name': 'rogue_flood', 'kind': 'rogue', 'value': 'flood'}
    rows = [{'case': 'rogue_flood', 'passed': True, 'target_applies': True, 'settled': True,
             'frames_rejected': counts} for counts in ({'auth_bad_tag': 10},
                                                       {'auth_bad_tag': 20, 'auth_replay': 3})]
    summary = fault_report.summarise(rows, [case])
    assert summary['rogue_flood']['frames_rejected'] == {'auth_bad_tag': 15.0,
                                                         'auth_replay': 1.5}
    assert '| rejected frames |' in fault_report.markdown_table(summary).splitlines()[0]
    assert '| bad_tag 15, replay 2 | 2/2 |' in fault_report.markdown_table(summary)


def test_a_restart_case_restarts_agents_with_nothing_lost(tmp_path, capsys):
    """restart_30: 2 of the 6 agents' processes crash and come back one by one in the
    fault window (their brains rebuilt, bodies where they were). The swarm ends as the
    clean run does: settled, every agent inside, every goal claimed once; the restarted
    agents' fresh DSDV numbers (dsdv.boot_sequence) leave no stale route. Through ROS the
    case is refused in one line (tests/e2e/test_restarts.py restarts processes there)."""
    assert 'restart_30' in fault_cases.QUICK_CASES
    assert 'restart_30' not in fault_cases.ROS_CASES
    out = tmp_path / 'faults'
    assert fault_study.main(['--out', str(out), '--quick', '--workers', '1',
                             '--cases', 'restart_30']) == 0
    (row,) = json.loads((out / 'faults.json').read_text())['trials']
    assert row['settled'] and row['passed']
    assert row['fraction_inside'] == 1.0 and row['goals_claimed'] == 1.0
    assert row['agents_alive'] == 6 and row['duplicate_goal_claims_final'] == 0
    assert row['routing_loops'] == 0 and not row['count_to_infinity']
    assert fault_study.main(['--out', str(tmp_path / 'ros'), '--ros',
                             '--cases', 'restart_30']) == 2
    assert 'restart_30 run headless only' in capsys.readouterr().err
