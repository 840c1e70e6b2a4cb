"""Each node declares its parameters in one place; its YAML in config/ must agree.

A default that differs between the node and its YAML file means `ros2 run` and
`ros2 launch` users get different systems. Importing the node modules needs rclpy, so
this test skips without ROS.
"""

from __future__ import annotations

import importlib
import pathlib

import pytest
import yaml

pytest.importorskip('rclpy')

SRC = pathlib.Path(__file__).resolve().parents[2] / 'ros2_ws' / 'src'
NODES = [
    ('swarm_agent', 'agent_node', 'agent.yaml'),
    ('swarm_mission', 'mission_node', 'mission.yaml'),
]


@pytest.mark.parametrize(('package', 'module', 'config'), NODES)
def test_yaml_defaults_equal_the_declared_ones(package, module, config):
    declared = importlib.import_module(f'{package}.{module}').PARAMETERS
    document = yaml.safe_load((SRC / package / 'config' / config).read_text())
    (section,) = document.values()
    values = section['ros__parameters']
    unknown = sorted(set(values) - set(declared))
    assert not unknown, f'{config} sets parameters {module} does not declare: {unknown}'
    for name, value in values.items():
        default = declared[name][0]
        assert type(value) is type(default) and value == default, (
            f'{config}: {name} = {value!r} but {module} declares {default!r}')
