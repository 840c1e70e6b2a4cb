"""swarm.launch.py's arguments (swarm_bringup.launch_arguments): checked as the launcher
checks a run, turned into the launch plan; no launch_ros needed."""

from __future__ import annotations

import pathlib

import pytest

from swarm_bringup.launch_arguments import ARGUMENTS, plan_from_arguments
from swarm_bringup.scenario import LaunchError
from swarm_common.fleet import load_fleet

ROOT = pathlib.Path(__file__).resolve().parents[3]
CONFIG = ROOT / 'ros2_ws' / 'src' / 'swarm_bringup' / 'config'
SMALL = {'shape': str(ROOT / 'tests' / 'data' / 'square_8m.json'), 'half_size': '15'}


def test_issue_arguments_are_declared_with_descriptions():
    names = {name for name, _, _ in ARGUMENTS}
    assert {'agents', 'beacons', 'types', 'shape', 'method', 'mode', 'params_file', 'seed',
            'record', 'viz', 'fleet_file'} <= names
    assert all(text for _, _, text in ARGUMENTS)


def test_fleet_generated_from_counts_when_no_file(tmp_path):
    plan, fleet_file = plan_from_arguments({**SMALL, 'agents': '8', 'beacons': '3',
                                            'out': str(tmp_path)})
    fleet = load_fleet(fleet_file)
    assert fleet_file == tmp_path / 'fleet.yaml'
    assert len(fleet) == 8 and sum(r.is_beacon for r in fleet) == 3
    assert [s.process for s in plan] == ['sim', 'mission', 'mission_radio',
                                        'agents']   # composed default
    sim, mission, radio, agents = plan
    assert radio.parameters['fleet_file'] == str(fleet_file)
    assert sim.parameters['truth_subscribers'] == 0      # no monitor holds the clock
    assert sim.parameters['real_time_factor'] == 1.0 and sim.parameters['record_dir'] == ''
    assert sim.parameters['marker_rate_hz'] == 0.0
    assert agents.parameters['fleet_file'] == str(fleet_file)
    assert agents.parameters['type_counts'] == '1:3,2:3,3:2'
    assert mission.parameters['fleet_file'] == str(fleet_file)
    # A respawned mission node resumes this run's state; another launch into the same
    # folder is another run and starts afresh.
    assert mission.parameters['state_file'] == str(tmp_path / 'mission_state.json')
    again, _ = plan_from_arguments({**SMALL, 'agents': '8', 'beacons': '3',
                                    'out': str(tmp_path)})
    assert len(mission.parameters['run_id']) == 32
    assert again[1].parameters['run_id'] != mission.parameters['run_id']


def test_shipped_fleet_and_params_file_per_robot(tmp_path):
    plan, fleet_file = plan_from_arguments({
        'fleet_file': str(CONFIG / 'fleet.yaml'), 'params_file': str(CONFIG / 'params.yaml'),
        'mode': 'per_robot', 'record': 'true', 'viz': 'true', 'out': str(tmp_path)})
    assert fleet_file == CONFIG / 'fleet.yaml'
    assert [s.process for s in plan][:4] == ['recorder', 'sim', 'mission', 'mission_radio']
    assert [s.process for s in plan][4:] == [f'agent_{k}' for k in range(8)]
    assert all(s.params_files == (str(CONFIG / 'params.yaml'),) for s in plan)
    recorder, sim = plan[:2]
    # record:=true: every topic into out/run.mcap, and the sim waits for the recorder.
    assert recorder.parameters == {'output': str(tmp_path / 'run.mcap'),
                                   'use_sim_time': True}
    assert (recorder.package, recorder.executable) == ('swarm_bringup', 'recorder_node')
    assert sim.parameters['truth_subscribers'] == 1
    assert sim.parameters['record_dir'] == str(tmp_path)
    assert sim.parameters['marker_rate_hz'] == 1.0


@pytest.mark.parametrize(('given', 'message'), [
    ({'mode': 'swarm'}, "mode:='swarm': use mode:=composed or mode:=per_robot"),
    ({'agents': 'six'}, "agents:='six' is not an integer; write e.g. agents:=8"),
    ({'record': 'yes'}, "record:='yes': write record:=true or record:=false"),
    ({'method': 'foo'}, "unknown method 'foo'; use bubble, fractal or forces"),
    ({'agents': '8', 'beacons': '9'}, 'beacons:=9 exceeds agents:=8; use at most 8'),
    ({'agents': '4', 'types': '1:2,2:1'}, 'types:=1:2,2:1 sums to 3, not agents:=4'),
    ({'fleet': 'x'}, 'unknown launch argument fleet; the arguments are agents, '),
    ({'params_file': '/nonexistent.yaml'}, 'params_file:=/nonexistent.yaml: no such file'),
    ({'fleet_file': '/nonexistent.yaml'}, 'fleet_file:=/nonexistent.yaml: cannot read'),
])
def test_bad_arguments_are_refused_in_one_line(tmp_path, given, message):
    with pytest.raises(LaunchError) as err:
        plan_from_arguments({**SMALL, 'out': str(tmp_path), **given})
    assert str(err.value).startswith(message)
    assert '\n' not in str(err.value)


@pytest.mark.parametrize('mode', ['composed', 'per_robot'])
def test_the_swarm_key_file_reaches_every_agent_and_a_bad_one_is_refused(tmp_path, mode):
    from swarm_agent.frame_auth import new_key_file_text

    keys = tmp_path / 'keys.yaml'
    keys.write_text(new_key_file_text())
    plan, _ = plan_from_arguments({**SMALL, 'agents': '4', 'beacons': '3', 'mode': mode,
                                   'swarm_key_file': str(keys), 'out': str(tmp_path)})
    agents = [s for s in plan if s.package == 'swarm_agent']
    assert agents and all(s.parameters['swarm_key_file'] == str(keys) for s in agents)
    assert all('swarm_key_file' not in s.parameters for s in plan if s not in agents)
    bad = tmp_path / 'bad_keys.yaml'
    bad.write_text('keys: {1: tooshort}\n')
    with pytest.raises(LaunchError) as err:
        plan_from_arguments({**SMALL, 'swarm_key_file': str(bad), 'out': str(tmp_path)})
    assert str(err.value).startswith('--swarm-key-file: ') and str(bad) in str(err.value)
    assert '\n' not in str(err.value)
