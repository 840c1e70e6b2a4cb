"""swarm_bringup/config/params.yaml sets only parameters its nodes declare, at their
defaults (the file says so): a misspelt or stale name would be ignored silently by ROS,
and a value that differs would make `ros2 launch` users run another system than
`launch_swarm.py` users. Importing the node modules needs rclpy."""

from __future__ import annotations

import pathlib

import pytest
import yaml

pytest.importorskip('rclpy')

from swarm_agent.agent_node import BRAIN_PARAMETERS  # noqa: E402
from swarm_agent.agent_node import PARAMETERS as AGENT  # noqa: E402
from swarm_mission.mission_node import PARAMETERS as MISSION  # noqa: E402
from swarm_sim.sim_parameters import SIM_PARAMETERS  # noqa: E402

PARAMS = (pathlib.Path(__file__).resolve().parents[3] / 'ros2_ws' / 'src' / 'swarm_bringup'
          / 'config' / 'params.yaml')


def _flat(values: dict, prefix: str = '') -> dict:
    """Nested YAML keys as ROS's dotted parameter names."""
    out = {}
    for key, value in values.items():
        if isinstance(value, dict):
            out.update(_flat(value, f'{prefix}{key}.'))
        else:
            out[prefix + key] = value
    return out


def test_params_file_sets_declared_parameters_at_their_defaults():
    sections = yaml.safe_load(PARAMS.read_text(encoding='utf-8'))
    declared = {
        '/**/sim': {n: s.default for n, s in SIM_PARAMETERS.items()},
        '/**/mission': {n: d for n, (d, _) in MISSION.items()},
        '/**': {**{n: d for n, (d, _) in AGENT.items()},
                **{n: s.default for n, s in BRAIN_PARAMETERS.items()}},
    }
    assert set(sections) == set(declared)
    for node, section in sections.items():
        values = _flat(section['ros__parameters'])
        assert values, node
        for name, value in values.items():
            assert name in declared[node], f'{node}: {name} is no parameter of the node'
            default = declared[node][name]
            assert type(value) is type(default) and value == default, (node, name, value)
