"""scripts/fault_study.py (issue 10) runs end to end on a tiny swarm and checks its probes."""

from __future__ import annotations

import json

import fault_study
import numpy as np
import pytest

from swarm_agent.dsdv import RouteEntry
from swarm_mission.shapes import load_shape
from swarm_sim.headless import HeadlessSwarm, Scenario

ROW_KEYS = {'case', 'seed', 'fraction_inside', 'goals_claimed', 'goals_reached',
            'epsilon_t', 'epsilon_g',
            'assignment_agreement', 'agreement_after_fault', 'final_agreement',
            'duplicate_goal_claims', 'settling_time', 'recovery_time', 'min_separation_ratio',
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
    assert lossless['duplicate_goal_claims'] == 0 and lossless['settled']
    killed = next(r for r in data['trials'] if r['case'] == 'kill_30')
    assert killed['agents_alive'] == 4 and killed['fault_time'] >= 40.0
    assert killed['stale_routes_to_dead'] == 0  # broken links invalidated the routes
    table = (out / 'faults.md').read_text()
    assert table.startswith('| Case |') and '| loss_0 |' in table and '| kill_30 |' in table
    assert 'fault study: 2 trials' in capsys.readouterr().out


def test_fault_cases_cover_the_issue():
    names = [c['name'] for c in fault_study.fault_cases()]
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
    a.table[c.id] = RouteEntry(c.id, b.id, 2, 10)
    b.table[c.id] = RouteEntry(c.id, a.id, 2, 10)
    assert fault_study.count_routing_loops(swarm) == 2
    swarm.alive[2] = False
    swarm.brains[2] = None
    assert fault_study.stale_routes_to_dead(swarm) == 2
    assert fault_study.count_routing_loops(swarm) == 2


def test_critical_range_is_the_longest_spanning_tree_edge():
    points = np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 0.0], [5.0, 2.0]])
    assert fault_study.critical_range(points) == pytest.approx(4.0)
    assert fault_study.critical_range(points[:1]) == 0.0


@pytest.mark.parametrize('args', [['--seeds', '0'], ['--cases', 'nonsense'],
                                  ['--fault-time', '500', '--duration', '100']])
def test_bad_arguments_rejected(tmp_path, capsys, args):
    assert fault_study.main(['--out', str(tmp_path), '--quick', *args]) == 2
    assert 'fault_study.py:' in capsys.readouterr().err
