"""scripts/launch_swarm.py (swarm_bringup.scenario) refuses a bad host split or fault
spec in one line, before starting."""

from __future__ import annotations

import pytest

from swarm_bringup import scenario, supervisor_node
from swarm_bringup.scenario import (
    LaunchError,
    parse_agent_ids,
    parse_move_obstacle,
    parse_robot_fault,
    parse_set_sim,
)

BASE = ['--agents', '8', '--beacons', '3', '--shape', 'tests/data/square_8m.json',
        '--half-size', '15', '--out', '/nonexistent']


def _validate(*extra: str):
    args = scenario.parse_args([*BASE, *extra])
    scenario.validate(args)
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
    assert supervisor_node.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err == "launch_swarm.py: --local-agents '0-9': agent ids run 0..7 with --agents 8"
    assert not out.exists()


@pytest.mark.parametrize(('spec', 'expected'), [
    ('60:loss=0.2', (60.0, 'loss', 0.2)), ('0:loss=0', (0.0, 'loss', 0.0)),
    ('90.5:radio_range_m=5', (90.5, 'radio_range_m', 5.0)),
    (' 90 : radio_wall_speed_mps = 1 ', (90.0, 'radio_wall_speed_mps', 1.0))])
def test_set_sim_specs(spec, expected):
    assert parse_set_sim(spec) == expected


@pytest.mark.parametrize(('spec', 'says'), [
    ('loss=0.2', 'write TIME:NAME=VALUE'), ('60:loss', 'write TIME:NAME=VALUE'),
    ('60:=0.2', 'write TIME:NAME=VALUE'), ('x:loss=0.2', "'x' is not a sim time"),
    ('-5:loss=0.2', 'sim time >= 0'), ('nan:loss=0.2', 'sim time >= 0'),
    ('60:gps_std=3', "no run-time parameter 'gps_std'; use one of loss, radio_range_m"),
    ('60:loss=lots', "'lots' is not a number"), ('60:loss=1.5', 'packet loss must be in'),
    ('60:radio_range_m=0', 'radio range must be a positive'),
    ('60:radio_wall_speed_mps=-1', 'wall speed must be 0')])
def test_bad_set_sim_specs_name_the_flag_and_the_fix(spec, says):
    with pytest.raises(LaunchError, match=r'^--set-sim') as err:
        parse_set_sim(spec)
    assert says in str(err.value)


def test_set_sim_is_sorted_checked_against_the_run_and_only_where_the_sim_runs():
    args = _validate('--set-sim', '90:radio_range_m=3', '--set-sim', '30:loss=0.1',
                     '--duration', '100', '--min-duration', '95')
    assert args.sim_settings == [(30.0, 'loss', 0.1), (90.0, 'radio_range_m', 3.0)]
    with pytest.raises(LaunchError, match='after the end of the run'):
        _validate('--set-sim', '120:loss=0.1', '--duration', '100')
    with pytest.raises(LaunchError, match='--min-duration 200 must be within'):
        _validate('--min-duration', '200', '--duration', '100')
    with pytest.raises(LaunchError, match='--set-sim acts from the host that runs the sim'):
        _validate('--agents-only', '--local-agents', '4-7', '--domain', '42',
                  '--set-sim', '60:loss=0.2')


def test_main_refuses_a_bad_set_sim_in_one_line(capsys, tmp_path):
    out = tmp_path / 'run'
    assert supervisor_node.main([*BASE[:-1], str(out), '--set-sim', '60:range=5']) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("launch_swarm.py: --set-sim '60:range=5': the sim node has no")
    assert '\n' not in err and not out.exists()


def test_robot_and_obstacle_faults_are_parsed_and_ordered():
    args = _validate('--remove', '60:2,5', '--radio-off', '30:1', '--radio-on', '45:1',
                     '--duration', '100')
    assert args.robot_faults == [(30.0, [1], 'swarm/radio_off'),
                                 (45.0, [1], 'swarm/radio_on'),
                                 (60.0, [2, 5], 'swarm/kill')]
    assert parse_robot_fault('--radio-off', ' 10 :3', 8) == (10.0, [3])
    assert parse_move_obstacle('60:1:5,-2.5', 2) == (60.0, [1.0, 5.0, -2.5])


@pytest.mark.parametrize(('flag', 'spec', 'says'), [
    ('--remove', '60', 'write TIME:IDS'), ('--remove', '60:', 'write TIME:IDS'),
    ('--radio-off', 'x:3', "'x' is not a sim time"), ('--radio-on', '-1:3', 'sim time >= 0'),
    ('--radio-off', '60:a,b', 'not a list of agent ids'),
    ('--remove', '60:3,8', 'agent ids run 0..7 with --agents 8, not [8]')])
def test_bad_robot_fault_specs_name_the_flag_and_the_fix(flag, spec, says):
    with pytest.raises(LaunchError, match=f'^{flag}') as err:
        parse_robot_fault(flag, spec, 8)
    assert says in str(err.value)


@pytest.mark.parametrize(('spec', 'says'), [
    ('60:0', 'write TIME:INDEX:DX,DY'), ('60:a:1,1', 'integer obstacle index'),
    ('60:0:1', 'integer obstacle index'), ('60:2:1,1', 'has 2 obstacles (indices 0..1)'),
    ('60:0:nan,1', 'finite metres')])
def test_bad_obstacle_moves_name_the_fix(spec, says):
    with pytest.raises(LaunchError, match='^--move-obstacle') as err:
        parse_move_obstacle(spec, 2)
    assert says in str(err.value)


def test_faults_outside_the_run_or_the_shape_are_refused():
    with pytest.raises(LaunchError, match='after the end of the run'):
        _validate('--radio-off', '120:1', '--duration', '100')
    with pytest.raises(LaunchError, match='the shape has 0 obstacles'):
        _validate('--move-obstacle', '10:0:1,1')   # square_8m has none
    with pytest.raises(LaunchError, match='--radio-off acts from the host that runs the sim'):
        _validate('--agents-only', '--local-agents', '4-7', '--domain', '42',
                  '--radio-off', '60:5')


@pytest.mark.parametrize('rate', ['0', '-5', 'nan', 'inf'])
def test_a_control_rate_that_is_not_a_positive_rate_is_refused(rate):
    with pytest.raises(LaunchError, match='^--control-rate must be a positive rate'):
        _validate('--control-rate', rate)


def test_a_smooth_shape_change_is_checked_against_the_shape_and_the_run():
    args = _validate('--morph', 'rotate:45@20+10', '--duration', '100')
    assert args.last_switch == 28.0   # five shapes, one every 2 s from 20 s
    with pytest.raises(LaunchError, match="unknown shape change 'spin'"):
        _validate('--morph', 'spin:1@20+10')
    with pytest.raises(LaunchError, match='after the end of the run'):
        _validate('--morph', 'move:2@90+30', '--duration', '100')
    with pytest.raises(LaunchError, match='either --sequence or --morph'):
        _validate('--morph', 'move:2@20+10', '--sequence', 'tests/data/none.yaml')


def test_a_shape_too_long_for_the_beacons_is_refused_naming_the_count(capsys, tmp_path):
    """An 8 m x 90 m strip: four beacons cannot keep three within 0.9 x 25 m of every goal
    (swarm_mission.beacon_goals); the line names the fewest beacons that can."""
    strip = tmp_path / 'strip.json'
    strip.write_text('{"outer": [[-4, -45], [4, -45], [4, 45], [-4, 45]]}')
    out = tmp_path / 'run'
    argv = ['--agents', '16', '--beacons', '4', '--types', '2:16', '--shape', str(strip),
            '--out', str(out)]
    assert supervisor_node.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert '\n' not in err
    assert err.startswith('launch_swarm.py: shape strip needs at least 6 beacons for a 25 m '
                          'radio; the fleet has 4: use --beacons 6')
    assert not out.exists()
    argv[3] = '6'
    scenario.validate(scenario.parse_args(argv))


def test_the_script_keeps_the_checks_the_study_scripts_import():
    """scripts/fault_study.py checks its scenarios with launch_swarm.validate."""
    import launch_swarm

    assert launch_swarm.validate is scenario.validate
    assert launch_swarm.parse_args is scenario.parse_args
    assert launch_swarm.LaunchError is LaunchError
