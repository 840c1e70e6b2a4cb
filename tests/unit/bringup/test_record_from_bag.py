"""swarm_bringup.results.record_from_bag: the monitor's record of a run whose launcher
was killed, rebuilt from its bag up to the last flushed chunk."""

from __future__ import annotations

import logging
import pathlib

from bag_fixtures import cdr, FakeClock
import numpy as np
import pytest

from swarm_bringup.bag import BagError, BagWriter, message_definition
from swarm_bringup.results import main, record_from_bag

pytest.importorskip('ament_index_python')
try:
    message_definition('swarm_msgs/msg/SwarmTruth')
except BagError:
    pytest.skip('swarm_msgs is not installed (make bootstrap)', allow_module_level=True)

TRUTH, STATE = 'swarm_msgs/msg/SwarmTruth', 'swarm_msgs/msg/AgentState'


def header(t: float) -> dict:
    return {'stamp': {'sec': int(t), 'nanosec': int(round((t % 1) * 1e9))},
            'frame_id': 'map'}


def truth(t: float) -> bytes:
    agents = [{'id': a, 'type': 1, 'is_beacon': False, 'alive': a != 9,
               'position': [t + a, -t], 'velocity': [1.0, 0.5 * a], 'yaw': 0.0}
              for a in (4, 9)]
    return cdr(TRUTH, {'header': header(t), 'agents': agents})


def state(t: float, agent: int) -> bytes:
    return cdr(STATE, {'header': header(t), 'id': agent, 'type': 1, 'is_beacon': False,
                       'mode': 1, 'position': [t, 2.0 * agent], 'velocity': [0.0, 0.0],
                       'covariance': [0.0] * 16, 'assigned_goal': agent + 100,
                       'goal_version': 1, 'assignment_round': int(4 * t),
                       'assignment_digest': 0xFFFFFFFF, 'rows_used': 2, 'settled': False,
                       'localized': True})


def test_a_killed_runs_record_is_rebuilt_to_the_last_flush(tmp_path: pathlib.Path, caplog):
    """Truth at 4 Hz and agent 4's state at 4 Hz (agent 9 never reports) for 6 s of sim
    time, one wall second per sim second; the writer dies 0.75 s after its flush at 5 s
    (made by the state of t = 5 s, before that instant's truth): the record holds the
    2 Hz samples of 0..4.5 s, nothing later, nothing made up."""
    clock = FakeClock()
    path = tmp_path / 'run.mcap'
    bag = BagWriter(path, flush_period_s=1.0, clock=clock)
    bag.add_topic('/swarm/truth', TRUTH)
    bag.add_topic('/agent_4/state', STATE)
    for k in range(24):
        t = 0.25 * k
        clock.now = t
        ns = int(t * 1e9)
        bag.write('/agent_4/state', state(t, 4), ns)
        bag.write('/swarm/truth', truth(t), ns)
    # Killed: no close.
    with caplog.at_level(logging.WARNING):
        rec = record_from_bag(path, [4, 9])
    assert any('was cut' in r.getMessage() for r in caplog.records)
    assert rec['times'].tolist() == [0.5 * k for k in range(10)]
    assert rec['positions'].shape == (10, 2, 2)
    assert rec['positions'][4, 1].tolist() == [2.0 + 9, -2.0]
    assert rec['velocities'][4, 1].tolist() == [1.0, 4.5]
    assert rec['alive'][:, 0].all() and not rec['alive'][:, 1].any()
    # Agent 4's state of the same instant (written just before the truth), agent 9: none.
    assert rec['estimates'][4, 0].tolist() == [2.0, 8.0]
    assert np.isnan(rec['estimates'][:, 1]).all()
    assert rec['goal_ids'][:, 0].tolist() == [104] * 10 and (rec['goal_ids'][:, 1] == -1).all()
    assert rec['rounds'][4, 0] == 8 and rec['digests'][0, 0] == 0xFFFFFFFF
    assert rec['modes'].dtype == np.int64 and rec['localized'][:, 0].all()
    bag.close()


def test_the_command_line_writes_the_record_or_says_why_not(tmp_path, capsys):
    assert main([str(tmp_path)]) == 2
    assert capsys.readouterr().err.count('\n') == 1
    (tmp_path / 'fleet.yaml').write_text(
        'robots:\n  - {id: 4, type: 1, beacon: false, x: 0, y: 0, yaw: 0}\n')
    assert main([str(tmp_path)]) == 2
    assert 'no such bag' in capsys.readouterr().err
    with BagWriter(tmp_path / 'run.mcap') as bag:
        bag.add_topic('/swarm/truth', TRUTH)
        for k in range(3):
            bag.write('/swarm/truth', truth(0.5 * k), int(0.5 * k * 1e9))
    assert main([str(tmp_path)]) == 0
    assert 'results: 3 samples of 1 agents from t=0.0 to 1.0 s' in capsys.readouterr().out
    assert np.load(tmp_path / 'record_from_bag.npz')['positions'].shape == (3, 1, 2)
