"""sim_node's parameters are generated from its configuration dataclasses
(swarm_sim.sim_parameters.SimParameters, the radio medium's MediumConfig nested): one
source of truth, each with a description and a range, read-only but the four the node
applies at run time."""

from __future__ import annotations

import dataclasses

import pytest

from swarm_common.parameters import ParameterError
from swarm_sim.medium import MediumConfig, RUNTIME_SETTINGS
from swarm_sim.sim_parameters import check_parameters, SIM_PARAMETERS, SimParameters

DEFAULTS = {name: spec.default for name, spec in SIM_PARAMETERS.items()}


def test_every_field_is_a_parameter_with_a_description_and_a_range():
    fields = {f.name for f in dataclasses.fields(SimParameters)} - {'medium'}
    medium = {f'medium.{f.name}' for f in dataclasses.fields(MediumConfig)
              if 'tunable' in f.metadata}
    assert set(SIM_PARAMETERS) == fields | medium
    assert medium == {'medium.line_of_sight', 'medium.latency_s', 'medium.bandwidth_bps',
                      'medium.range_noise_std'}
    for name, spec in SIM_PARAMETERS.items():
        assert spec.description, name
        if type(spec.default) in (int, float):
            assert spec.low is not None and spec.high is not None, name
            assert spec.low <= spec.default <= spec.high, name


def test_only_what_the_node_applies_at_run_time_is_live():
    live = {name for name, spec in SIM_PARAMETERS.items() if spec.live}
    assert live == set(RUNTIME_SETTINGS) | {'real_time_factor'}


def test_defaults_are_the_thesis_scenario():
    config = check_parameters(DEFAULTS)
    assert config == SimParameters()
    assert (config.radio_range_m, config.gps_std, config.loss) == (25.0, 2.0, 0.0)  # 4.1-4.2
    assert config.medium == MediumConfig()


@pytest.mark.parametrize('name, value, says', [
    ('proximity_std', -1.0, 'proximity_std must be in [0.0, 10.0]'),
    ('loss', 1.5, 'loss must be in [0.0, 1.0]'),
    ('medium.latency_s', -0.1, 'medium.latency_s must be in [0.0, 10.0]'),
    ('truth_subscribers', 2.5, 'truth_subscribers must be an integer'),
])
def test_a_bad_value_is_refused_in_one_line_naming_it(name, value, says):
    with pytest.raises(ParameterError) as refused:
        check_parameters({**DEFAULTS, name: value})
    assert says in str(refused.value) and '\n' not in str(refused.value)
