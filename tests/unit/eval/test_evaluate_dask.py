"""scripts/evaluate.py --dask: a Dask cluster gives the same trials as local worker processes.

A trial depends only on its seed, so a LocalCluster of two processes and the local
ProcessPool path must produce identical per-trial metrics (wall-clock figures aside).
"""

from __future__ import annotations

import json

import pytest

from swarm_eval import evaluate

pytest.importorskip('dask.distributed',
                    reason='needs dask[distributed] (requirements/python.txt: make bootstrap)')

WALL_CLOCK_KEYS = {'wall_seconds', 'real_time_factor'}
TINY = ['--agents', '6', '--beacons', '3', '--shape', 'circle_314', '--shape-scale', '0.3',
        '--duration', '6', '--trials', '2', '--workers', '2', '--seed', '11']


def _trials(out) -> list[dict]:
    trials = json.loads((out / 'metrics.json').read_text())['trials']
    return [{k: v for k, v in t.items() if k not in WALL_CLOCK_KEYS} for t in trials]


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_local_dask_cluster_matches_the_process_pool(tmp_path):
    assert evaluate.main([*TINY, '--out', str(tmp_path / 'pool')]) == 0
    assert evaluate.main([*TINY, '--dask', 'local', '--out', str(tmp_path / 'dask')]) == 0
    pool, dask = _trials(tmp_path / 'pool'), _trials(tmp_path / 'dask')
    assert [t['seed'] for t in pool] == [t['seed'] for t in dask] == [11, 12]
    assert pool == dask
    assert pool[0] != pool[1]  # the seeds matter: this is not a trivially equal comparison


@pytest.mark.slow
def test_unreachable_scheduler_is_one_line_error(tmp_path, capsys):
    # Port 9 (discard) on localhost: nothing listens, the connection is refused.
    code = evaluate.main([*TINY, '--trials', '1', '--dask', 'tcp://127.0.0.1:9',
                          '--out', str(tmp_path / 'x')])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err.startswith("evaluate.py: cannot use the Dask scheduler 'tcp://127.0.0.1:9'")
    assert len(err.splitlines()) == 1
