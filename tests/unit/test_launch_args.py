"""scripts/launch_swarm.py refuses a bad multi-host split in one line, before starting."""

from __future__ import annotations

import launch_swarm
from launch_swarm import LaunchError, parse_agent_ids
import pytest

BASE = ['--agents', '8', '--beacons', '3', '--shape', 'tests/data/square_8m.json',
        '--half-size', '15', '--out', '/nonexistent']


def _validate(*extra: str):
    args = launch_swarm.parse_args([*BASE, *extra])
    launch_swarm.validate(args)
    return args


@pytest.mark.parametrize(('spec', 'ids'), [
    ('', list(range(8))), ('none', []), ('0-3', [0, 1, 2, 3]), ('4', [4]),
    ('0, 2,5-7', [0, 2, 5, 6, 7]), ('1-2,2-3', [1, 2, 3])])
def test_agent_id_specs(spec, ids):
    assert parse_agent_ids(spec, 8) == ids


@pytest.mark.parametrize(('spec', 'says'), [
    ('x', "'x' is not an id or a range"), ('3-1', 'write 1-3'), ('0-8', 'ids run 0..7'),
    ('-1', 'not an id or a range'), ('1-', 'not an id or a range')])
def test_bad_agent_id_specs_name_the_fix(spec, says):
    with pytest.raises(LaunchError, match=r'^--local-agents') as err:
        parse_agent_ids(spec, 8)
    assert says in str(err.value)


def test_a_split_swarm_needs_one_domain_for_every_host():
    with pytest.raises(LaunchError, match='--domain'):
        _validate('--local-agents', '0-3')
    with pytest.raises(LaunchError, match='--domain'):
        _validate('--agents-only', '--local-agents', '4-7')
    assert _validate('--local-agents', '0-3', '--domain', '42').local_ids == [0, 1, 2, 3]
    assert _validate('--local-agents', 'none', '--domain', '42').local_ids == []


def test_agents_only_must_start_something_and_cannot_remove():
    with pytest.raises(LaunchError, match='starts nothing'):
        _validate('--agents-only', '--local-agents', 'none', '--domain', '42')
    with pytest.raises(LaunchError, match='--remove'):
        _validate('--agents-only', '--local-agents', '4-7', '--domain', '42',
                  '--remove', '60:5')


def test_main_refuses_in_one_line_without_starting(capsys, tmp_path):
    out = tmp_path / 'run'
    argv = [*BASE[:-1], str(out), '--local-agents', '0-9', '--domain', '42']
    assert launch_swarm.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err == "launch_swarm.py: --local-agents '0-9': agent ids run 0..7 with --agents 8"
    assert not out.exists()
