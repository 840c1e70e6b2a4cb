"""benchmarks/run_all.py runs end to end in its tiny mode, so the suite cannot rot.

It runs as a child process (as a person runs it); the test's own ROS domain reaches the
executor benchmark through the environment.
"""

from __future__ import annotations

import json
import math
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]
RUN_ALL = ROOT / 'benchmarks' / 'run_all.py'
FIGURES = {
    'dsdv': ('link_break_s', 'cold_start_s', 'routing_bytes_per_s_per_agent', 'wall_s'),
    'trilateration': ('round_s', 'per_agent_s'),
    'partition': ('seconds_median',),
    'cost_rows': ('graph_build_s', 'row_median_s', 'row_worst_first_s', 'all_rows_s'),
    'assignment': ('assign_all_s', 'assign_one_type_s'),
    'medium': ('links_s', 'transmit_deliver_s', 'step_s', 'deliveries'),
}


def _positive(value) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value) and value > 0


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(RUN_ALL), *args], cwd=str(ROOT),
                          capture_output=True, text=True, timeout=110)


@pytest.mark.timeout(120)
def test_tiny_suite_writes_every_section(tmp_path):
    proc = _run('--sizes', '10', '--repeats', '1', '--quick', '--out', str(tmp_path))
    assert proc.returncode == 0, proc.stderr[-2000:]
    data = json.loads((tmp_path / 'benchmarks.json').read_text())
    machine = data['machine']
    assert machine['cpu_count'] >= 1 and machine['python'].startswith('3.')
    assert machine['date'] and machine['git_commit']
    sections = data['sections']
    for name, keys in FIGURES.items():
        rows = sections[name]
        assert rows and all(r['agents'] == 10 for r in rows), name
        for row in rows:
            for key in keys:
                assert _positive(row[key]), (name, key, row[key])
    assert {r['method'] for r in sections['partition']} == {'bubble', 'fractal'}
    world = sections['world']
    assert [r['robots'] for r in world] == [10]
    assert _positive(world[0]['real_time_factor']) and _positive(world[0]['physics_hz'])
    assert world[0]['max_tilt_deg'] < 30.0 and world[0]['min_ground_clearance_m'] > 0.0
    ev = sections['evaluator']
    for key in ('wall_per_trial_s', 'cpu_per_trial_s', 'sim_s_per_trial', 'sim_s_per_wall_s',
                'trials_per_min_one_process', 'trials_per_min_all_cores'):
        assert _positive(ev[key]), key
    command = sections['throughput']['issue_command']   # issue 23's, tiny under --quick
    assert command['trials'] == 2 and command['agents'] == 10
    assert _positive(command['trials_per_min']) and _positive(command['trial_wall_sum_s'])
    assert command['wall_s'] > command['trial_wall_sum_s'] / command['workers']
    large = sections['throughput']['large_swarm']
    assert large['agents'] == 10 and _positive(large['real_time_factor'])
    assert large['sim_s'] == pytest.approx(3.0, abs=0.05)
    executors = sections['executor']['executors']
    assert set(executors) == {'single', 'events'}
    for row in executors.values():
        assert _positive(row['callbacks_per_s']) and _positive(row['cpu_cores'])
    assert sections['executor']['composed_node_default'].endswith('Executor')
    assert 'ros' not in sections  # off unless --ros
    assert data['targets'] and all(t['met'] is None for t in data['targets'])  # --quick
    md = (tmp_path / 'benchmarks.md').read_text()
    assert md.startswith('# Benchmarks') and '| 10 agents |' in md
    assert 'What we chose and why' in md and '## Targets' in md
    assert '## Throughput (issue 23)' in md and "issue 23's command" in md
    # --update re-measures one section and keeps the others; --render rewrites the report
    proc = _run('--sizes', '10', '--repeats', '1', '--quick', '--only', 'medium', '--update',
                '--out', str(tmp_path))
    assert proc.returncode == 0, proc.stderr[-2000:]
    merged = json.loads((tmp_path / 'benchmarks.json').read_text())
    assert set(merged['sections']) == set(sections)
    assert merged['sections']['dsdv'] == sections['dsdv']
    assert [u['sections'] for u in merged['updates']] == [['medium']]
    md = (tmp_path / 'benchmarks.md').read_text()
    assert 'medium: measured on ' in md
    (tmp_path / 'benchmarks.md').unlink()
    assert _run('--render', '--out', str(tmp_path)).returncode == 0
    assert (tmp_path / 'benchmarks.md').read_text() == md


def test_bad_arguments_are_one_line_errors(tmp_path):
    proc = _run('--sizes', '50,abc', '--out', str(tmp_path))
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "run_all: error: --sizes must be integers >= 10 separated by commas, like "
        "50,200,1000 (got '50,abc')"]
    proc = _run('--only', 'medium', '--update', '--out', str(tmp_path))
    assert proc.returncode == 2 and proc.stderr.count('\n') == 1
    assert proc.stderr.startswith('run_all: error: --update needs ')
    assert not (tmp_path / 'benchmarks.json').exists()
