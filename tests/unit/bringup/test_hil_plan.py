"""The hardware-in-the-loop demo's processes as launch-plan entries (swarm_bringup.hil)."""

from __future__ import annotations

import argparse
import math

from swarm_bringup import hil
from swarm_bringup.launch_plan import ros_arguments
from swarm_common.fleet import load_fleet


def _args(**kw) -> argparse.Namespace:
    return hil.parse_args(['--out', '/tmp/hil', *[f'--{k.replace("_", "-")}={v}'
                                                   for k, v in kw.items()]])


def test_world_node_settings_override_the_config_file(tmp_path):
    spec = hil.hil_world_node(tmp_path / 'coordinator.pty', _args(radio_loss=0.2))
    assert spec.params_files == (str(hil.bridge_config('hil.yaml')),)
    assert hil.bridge_config('hil.yaml').is_file()
    args = ros_arguments(spec)
    assert args[:3] == ['--ros-args', '--params-file', str(hil.bridge_config('hil.yaml'))]
    assert args[3:] == ['-p', f'port_link:={tmp_path / "coordinator.pty"}', '-p',
                        'camera:=truth', '-p', 'radio_loss:=0.2']
    assert hil.hil_world_node(tmp_path, _args(camera='sim')).parameters['camera'] == 'image'


def test_the_rendered_camera_is_a_process_of_its_own_with_the_worlds_camera_settings():
    world = {'port_link': '/tmp/pty', 'camera': 'image', 'camera_rate_hz': 10.0,
             'camera_latency_s': 0.05, 'camera_blur_px': 0.9, 'fleet_file': '',
             'radio_loss': 0.0}
    spec = hil.camera_sim_node(world)
    assert (spec.executable, spec.process) == ('camera_sim_node', 'hil_camera')
    assert spec.parameters == {'camera_rate_hz': 10.0, 'camera_latency_s': 0.05,
                               'camera_blur_px': 0.9}
    assert hil.camera_sim_node({'fleet_file': '/f.yaml'}).parameters == {'fleet_file': '/f.yaml'}


def test_agents_tracker_bridge_and_mission():
    robots = load_fleet(None)
    poses = [(0.1 * k, -0.5, math.pi / 2) for k in range(len(robots))]
    agents = hil.hw_agent_nodes(robots, poses, '1:1,2:2,3:2')
    assert [(s.executable, s.name, s.namespace) for s in agents] == [
        ('hw_agent_node', f'agent_{r.id}', None) for r in robots]
    assert agents[1].parameters['initial_x'] == 0.1
    assert agents[1].parameters['robot_types_file'] == str(
        hil.bridge_config('hw_robot_types.yaml'))
    tracker = hil.camera_tracker_node('/cal.yaml', poses[:1])
    assert tracker.parameters['initial_poses'] == [0.0, -0.5, 90.0]
    assert 'source' not in tracker.parameters
    assert tracker.remappings == (('image', '/camera/image_raw'),)
    assert hil.camera_tracker_node('/cal.yaml', [], '/dev/video0').parameters['source'] == \
        '/dev/video0'
    assert hil.bridge_node('/dev/ttyUSB0').parameters == {'port': '/dev/ttyUSB0'}
    mission = hil.hil_mission_node('hw_square', '1:5')
    assert mission.parameters['decentralized'] is True
    assert mission.parameters['formation_margin_m'] == 0.0
