"""The launch plan (swarm_bringup.launch_plan): the processes of a run as data, tested
without launch_ros. The launcher and swarm.launch.py both render this plan."""

from __future__ import annotations

import ast
import pathlib

import pytest

from swarm_bringup.launch_plan import (
    agent_nodes,
    checked_namespace,
    default_beacons,
    fleet_counts,
    generate_fleet,
    NamespaceError,
    node_kwargs,
    NodeSpec,
    ros_arguments,
    swarm_plan,
    SwarmRun,
    type_counts_text,
    world_nodes,
)
from swarm_common.fleet import RobotSpec
from swarm_common.shapes import load_shape

ROOT = pathlib.Path(__file__).resolve().parents[3]
BRINGUP = ROOT / 'ros2_ws' / 'src' / 'swarm_bringup'

FLEET = [RobotSpec(0, 1, True, -3.0, 4.0), RobotSpec(1, 1, False, 2.5, -1.0),
         RobotSpec(2, 2, True, 0.0, 0.0), RobotSpec(3, 3, True, 7.0, 7.5)]
COUNTS = {1: 2, 2: 1, 3: 1}


def _run(**kw) -> SwarmRun:
    return SwarmRun(fleet_file='/tmp/run/fleet.yaml', shape='circle_314', seed=5, **kw)


def test_per_robot_plan_names_each_agent_after_its_robot():
    plan = swarm_plan(_run(), FLEET, COUNTS)
    assert [s.process for s in plan] == ['sim', 'mission', 'mission_radio', 'agent_0',
                                        'agent_1', 'agent_2', 'agent_3']
    sim, mission, radio, *agents = plan
    assert (sim.package, sim.executable, sim.name) == ('swarm_sim', 'sim_node', 'sim')
    assert (mission.package, mission.executable, mission.name) == (
        'swarm_mission', 'mission_node', 'mission')
    # The mission learns which agents are alive from its radio, a node of the mesh.
    assert (radio.package, radio.executable, radio.name) == (
        'swarm_agent', 'mission_radio_node', 'mission_radio')
    assert mission.parameters.get('liveness', 'radio') == 'radio'
    assert sim.parameters['sensor_batch'] is False   # per-robot sensor topics
    assert 'max_agent_lag_s' not in sim.parameters    # per-robot keepalives: the default lag
    for robot, spec in zip(FLEET, agents):
        assert (spec.package, spec.executable, spec.module) == (
            'swarm_agent', 'agent_node', 'swarm_agent.agent_node')
        # Its topics are agent_K/... (relative), in the run's namespace: none here.
        assert (spec.name, spec.namespace, spec.fork) == (f'agent_{robot.id}', None, True)
        assert spec.remappings == ()
        p = spec.parameters
        assert (p['agent_id'], p['agent_type'], p['is_beacon']) == (
            robot.id, robot.type, robot.is_beacon)
        assert (p['initial_x'], p['initial_y']) == (robot.x, robot.y)
        assert p['seed'] == 5 + robot.id     # a noise stream per agent
        assert p['type_counts'] == '1:2,2:1,3:1'
        assert p['use_sim_time'] is True and p['control_rate_hz'] == 50.0


def test_composed_plan_is_one_process_that_keeps_its_node_names():
    plan = swarm_plan(_run(composed=True, control_rate_hz=25.0), FLEET, COUNTS)
    assert [s.process for s in plan] == ['sim', 'mission', 'mission_radio', 'agents']
    sim, _, _, agents = plan
    # A name would rename every robot's node of the process (/agent_K/agents_container).
    assert agents.name is None and agents.namespace is None and not agents.fork
    assert agents.executable == 'composed_node'
    # The world sends one sensor batch per step and the agents expect it.
    assert sim.parameters['sensor_batch'] is True and agents.parameters['sensor_batch'] is True
    assert agents.parameters['fleet_file'] == '/tmp/run/fleet.yaml'
    assert agents.parameters['control_rate_hz'] == 25.0
    # The agents answer every step in the batch, so the world never runs more than one
    # control period ahead of them: each tick is at most one period of their inner loop.
    assert sim.parameters['max_agent_lag_s'] == 1.0 / 25.0
    assert 'agent_ids' not in agents.parameters    # the whole fleet


def test_a_host_runs_only_its_agents():
    composed = agent_nodes(_run(composed=True), FLEET, COUNTS, [1, 3])
    assert [s.parameters['agent_ids'] for s in composed] == [[1, 3]]
    per_robot = agent_nodes(_run(), FLEET, COUNTS, [3, 1])
    assert [s.process for s in per_robot] == ['agent_1', 'agent_3']
    assert agent_nodes(_run(), FLEET, COUNTS, []) == []
    assert agent_nodes(_run(composed=True), FLEET, COUNTS, []) == []


def test_world_parameters_follow_the_run():
    sim, mission, _ = world_nodes(_run(markers=True, real_time_factor=2, record_dir='/r',
                                    truth_subscribers=1, morph='move:15@200+60',
                                    sequence_file='/s.yaml', decentralized=True))
    assert sim.parameters == {
        'fleet_file': '/tmp/run/fleet.yaml', 'shape': 'circle_314', 'real_time_factor': 2.0,
        'record_dir': '/r', 'gui': False, 'seed': 5, 'half_size': 50.0,
        'marker_rate_hz': 1.0, 'sensor_batch': False, 'truth_subscribers': 1}
    assert mission.parameters == {
        'shape': 'circle_314', 'method': 'bubble', 'fleet_file': '/tmp/run/fleet.yaml',
        'seed': 5, 'remesh': 'incremental', 'decentralized': True, 'use_sim_time': True,
        'morph': 'move:15@200+60', 'sequence_file': '/s.yaml'}
    _, plain, _ = world_nodes(_run())
    assert 'morph' not in plain.parameters and 'sequence_file' not in plain.parameters


def test_a_run_with_a_bag_starts_the_recorder_first():
    """The recorder comes before the sim, and the sim counts it among the truth
    subscribers it waits for before t = 0 (so the bag holds the run from its start)."""
    plan = swarm_plan(_run(bag='/r/run.mcap', truth_subscribers=1, composed=True,
                           params_files=('/p.yaml',)), FLEET, COUNTS)
    assert [s.process for s in plan] == ['recorder', 'sim', 'mission', 'mission_radio',
                                        'agents']
    recorder, sim = plan[:2]
    assert (recorder.package, recorder.executable, recorder.name) == (
        'swarm_bringup', 'recorder_node', 'recorder')
    assert recorder.module == 'swarm_bringup.recorder_node'
    assert recorder.parameters == {'output': '/r/run.mcap', 'use_sim_time': True}
    assert recorder.params_files == ('/p.yaml',) and not recorder.fork
    assert sim.parameters['truth_subscribers'] == 2          # the monitor and the recorder
    assert ros_arguments(recorder) == [
        '--ros-args', '-r', '__node:=recorder', '--params-file', '/p.yaml',
        '-p', 'output:=/r/run.mcap', '-p', 'use_sim_time:=true']
    # Without a bag: no recorder, and the sim waits for the monitor alone.
    plain = swarm_plan(_run(truth_subscribers=1), FLEET, COUNTS)
    assert 'recorder' not in [s.process for s in plain]
    assert plain[0].parameters['truth_subscribers'] == 1


def test_params_file_reaches_every_process():
    plan = swarm_plan(_run(params_files=('/p.yaml',)), FLEET, COUNTS)
    assert all(s.params_files == ('/p.yaml',) for s in plan)


def test_command_line_rendering():
    spec = NodeSpec('swarm_bridge', 'camera_tracker_node', 'tracker', name='agent',
                    namespace='/agent_2', params_files=('/c.yaml',),
                    parameters={'flag': True, 'off': False, 'xs': [1, 2.5], 'n': 3,
                                'text': 'a b'},
                    remappings=(('image', '/camera/image_raw'),))
    assert ros_arguments(spec) == [
        '--ros-args', '-r', '__ns:=/agent_2', '-r', '__node:=agent',
        '--params-file', '/c.yaml',         # parameters after the file win over it
        '-p', 'flag:=true', '-p', 'off:=false', '-p', 'xs:=[1,2.5]', '-p', 'n:=3',
        '-p', 'text:=a b', '-r', 'image:=/camera/image_raw']
    assert ros_arguments(NodeSpec('swarm_sim', 'sim_node', 'sim')) == ['--ros-args']


def test_launch_ros_rendering():
    spec = swarm_plan(_run(params_files=('/p.yaml',)), FLEET, COUNTS)[3]
    kw = node_kwargs(spec)
    assert kw['package'] == 'swarm_agent' and kw['executable'] == 'agent_node'
    assert kw['name'] == 'agent_0' and 'namespace' not in kw
    assert kw['parameters'] == ['/p.yaml', dict(spec.parameters)]
    assert kw['remappings'] == []
    composed = node_kwargs(swarm_plan(_run(composed=True), FLEET, COUNTS)[3])
    assert 'name' not in composed and 'namespace' not in composed


def test_fleet_generated_from_counts():
    shape = load_shape('circle_314')
    counts = fleet_counts(8)
    assert sum(counts.values()) == 8
    assert fleet_counts(6, '1:4,3:2') == {1: 4, 3: 2}
    beacons = default_beacons(8)
    assert beacons == 3 and default_beacons(50) == 8     # 15 %, at least 3
    fleet = generate_fleet(counts, beacons, 0, 50.0, shape)
    assert [r.id for r in fleet] == list(range(8))
    assert sum(r.is_beacon for r in fleet) == 3
    assert all(max(abs(r.x), abs(r.y)) <= 50.0 for r in fleet)
    assert generate_fleet(counts, beacons, 0, 50.0, shape) == fleet    # seeded
    assert generate_fleet(counts, beacons, 1, 50.0, shape) != fleet


def test_shipped_sample_fleet_is_the_generated_one():
    from swarm_common.fleet import load_fleet

    shipped = load_fleet(BRINGUP / 'config' / 'fleet.yaml')
    assert shipped == generate_fleet(fleet_counts(8), 3, 0, 50.0, load_shape('circle_314'))


def test_launch_file_imports_launch_ros_only_itself():
    """launch_ros is no dependency of the package's modules or of the tests."""
    for path in (BRINGUP / 'swarm_bringup').glob('*.py'):
        tree = ast.parse(path.read_text(encoding='utf-8'))
        names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
        names += [n.module or '' for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
        assert not [m for m in names if m.split('.')[0] in ('launch', 'launch_ros')], path
    launch = (BRINGUP / 'launch' / 'swarm.launch.py').read_text(encoding='utf-8')
    assert 'from launch_ros.actions import Node' in launch


@pytest.mark.parametrize('counts', [{1: 2}, {3: 1, 1: 1, 2: 4}])
def test_type_counts_text_is_sorted_by_type(counts):
    text = type_counts_text(counts)
    assert [int(p.split(':')[0]) for p in text.split(',')] == sorted(counts)
    assert sum(int(p.split(':')[1]) for p in text.split(',')) == sum(counts.values())


def test_the_launcher_plans_from_its_command_line(tmp_path):
    """launch_swarm's flags reach the plan; the monitor (and the recorder of OUT/run.mcap,
    on by default) hold the clock at t = 0; --no-record starts no recorder."""
    from swarm_bringup.scenario import parse_args, validate
    from swarm_bringup.supervisor_node import swarm_run

    args = parse_args(['--agents', '8', '--beacons', '3', '--shape',
                       str(ROOT / 'tests' / 'data' / 'square_8m.json'), '--half-size', '15',
                       '--composed', '--rtf', '2', '--markers', '--control-rate', '25',
                       '--morph', 'move:1@10+5', '--out', str(tmp_path)])
    _, counts, _, fleet = validate(args)
    run = swarm_run(args, tmp_path / 'fleet.yaml', tmp_path)
    recorder, sim, mission, _, agents = swarm_plan(run, fleet, counts)
    assert recorder.parameters['output'] == str(tmp_path / 'run.mcap')
    assert sim.parameters['truth_subscribers'] == 2
    assert sim.parameters['record_dir'] == str(tmp_path)
    assert (sim.parameters['real_time_factor'], sim.parameters['marker_rate_hz']) == (2.0, 1.0)
    assert sim.parameters['half_size'] == 15.0 and sim.parameters['sensor_batch'] is True
    assert mission.parameters['morph'] == 'move:1@10+5'
    assert agents.parameters['control_rate_hz'] == 25.0
    assert agents.parameters['type_counts'] == type_counts_text(counts)
    args = parse_args(['--agents', '8', '--no-record', '--out', str(tmp_path)])
    run = swarm_run(args, tmp_path / 'fleet.yaml', tmp_path)
    assert run.bag == ''
    assert [s.process for s in world_nodes(run)] == ['sim', 'mission', 'mission_radio']
    assert world_nodes(run)[0].parameters['truth_subscribers'] == 1


def test_a_namespace_puts_every_node_of_the_run_in_it():
    """Two swarms share a domain: every process of the plan runs in the run's namespace
    and remaps the ROS-global /clock and /tf into it; the nodes' names stay."""
    for composed in (False, True):
        plan = swarm_plan(_run(namespace='swarm_a', bag='/r/run.mcap', composed=composed),
                          FLEET, COUNTS)
        plain = swarm_plan(_run(bag='/r/run.mcap', composed=composed), FLEET, COUNTS)
        assert [(s.process, s.name) for s in plan] == [(s.process, s.name) for s in plain]
        for spec in plan:
            assert spec.namespace == '/swarm_a', spec.process
            assert spec.remappings == (('/clock', 'clock'), ('/tf', 'tf'),
                                       ('/tf_static', 'tf_static'))
            args = ros_arguments(spec)
            assert args[1:3] == ['-r', '__ns:=/swarm_a']
            assert args[-6:] == ['-r', '/clock:=clock', '-r', '/tf:=tf',
                                 '-r', '/tf_static:=tf_static']
            kw = node_kwargs(spec)
            assert kw['namespace'] == '/swarm_a'
            assert kw['remappings'] == [('/clock', 'clock'), ('/tf', 'tf'),
                                        ('/tf_static', 'tf_static')]


@pytest.mark.parametrize('text, namespace', [('', ''), ('/', ''), ('swarm_a', '/swarm_a'),
                                             ('/lab/swarm_b/', '/lab/swarm_b')])
def test_namespaces_are_made_absolute(text, namespace):
    assert checked_namespace(text) == namespace


@pytest.mark.parametrize('text', ['1swarm', 'swarm-a', '/a//b', 'a b'])
def test_a_bad_namespace_is_refused_with_the_fix(text):
    with pytest.raises(NamespaceError, match='e.g. /swarm_a'):
        checked_namespace(text)
    with pytest.raises(NamespaceError):
        swarm_plan(_run(namespace=text), FLEET, COUNTS)


def test_the_launcher_and_the_launch_file_take_the_namespace(tmp_path):
    from swarm_bringup.launch_arguments import plan_from_arguments
    from swarm_bringup.scenario import LaunchError, parse_args, validate
    from swarm_bringup.supervisor_node import swarm_run

    args = parse_args(['--agents', '4', '--namespace', 'swarm_b', '--out', str(tmp_path)])
    validate(args)
    run = swarm_run(args, tmp_path / 'fleet.yaml', tmp_path)
    assert run.namespace == '/swarm_b'
    plan, _ = plan_from_arguments({'agents': '4', 'namespace': '/swarm_b',
                                   'out': str(tmp_path)})
    assert {s.namespace for s in plan} == {'/swarm_b'}
    with pytest.raises(LaunchError, match='namespace'):
        validate(parse_args(['--agents', '4', '--namespace', 'a-b', '--out', str(tmp_path)]))
    with pytest.raises(LaunchError, match='namespace'):
        plan_from_arguments({'namespace': '9a', 'out': str(tmp_path)})
