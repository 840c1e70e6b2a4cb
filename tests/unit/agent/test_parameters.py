"""Parameters generated from the brain's configuration dataclasses (one source of truth):
every tunable has a description and a range holding its default, values are checked
by type and range, live changes take effect in the running brain's config and
read-only ones are refused."""

from __future__ import annotations

import dataclasses

import pytest

from swarm_agent.agent_factory import make_brain
from swarm_agent.brain_config import BrainConfig
from swarm_agent.dsdv import DsdvConfig
from swarm_agent.forces import ForceParams
from swarm_agent.localization import LocalizationConfig
from swarm_agent.setpoint import SetpointParams
from swarm_common.parameters import configured, ParameterError, set_live, spec_table, specs

NESTED = {'localization': LocalizationConfig, 'dsdv': DsdvConfig,
          'setpoint': SetpointParams, 'forces': ForceParams}
# Fields a node sets under names of its own (agent_node: localization_period_s,
# placement_std_m, agent_id, ...) or that are not scalars.
NOT_GENERATED = {'agent_id', 'agent_type', 'is_beacon', 'method', 'type_radii',
                 'localization.period_s', 'localization.initial_position_std'}


def test_every_scalar_field_of_the_configs_is_a_parameter_once():
    names = [s.name for s in specs(BrainConfig)]
    assert len(names) == len(set(names))
    expected = {f.name for f in dataclasses.fields(BrainConfig) if f.name not in NESTED}
    for prefix, cls in NESTED.items():
        expected |= {f'{prefix}.{f.name}' for f in dataclasses.fields(cls)}
    assert set(names) == expected - NOT_GENERATED


def test_every_default_lies_in_its_range_and_is_described():
    for spec in specs(BrainConfig):
        assert len(spec.description) > 10, spec.name
        assert spec.check(spec.default) == spec.default, spec.name
        if not isinstance(spec.default, bool):
            assert spec.low is not None and spec.high is not None, spec.name


def test_configured_sets_nested_values_on_a_copy():
    base = BrainConfig(agent_id=1, agent_type=1)
    new = configured(base, {'localization.gate': 20.0, 'setpoint.v_max': 0.3,
                            'hold_radius': 0.1, 'dsdv.default_ttl': 8})
    assert (new.localization.gate, new.setpoint.v_max, new.hold_radius,
            new.dsdv.default_ttl) == (20.0, 0.3, 0.1, 8)
    assert (base.localization.gate, base.setpoint.v_max, base.hold_radius) == (13.8, 0.5, 0.3)
    assert new.localization.beacon_variance_inflation == 4.0   # untouched fields kept


@pytest.mark.parametrize('values,match', [
    ({'localization.gate': 5000.0}, r'localization.gate must be in \[1.0, 1000.0\]'),
    ({'localization.gate': 'x'}, 'localization.gate must be a finite number'),
    ({'localization.gate': float('nan')}, 'finite'),
    ({'dsdv.default_ttl': 2.5}, 'dsdv.default_ttl must be an integer'),
    ({'localization.range_updates': 1}, 'true or false'),
    ({'setpoint.vmax': 0.3}, 'unknown parameter setpoint.vmax'),
    ({'hold_radius': 1.0}, 'below resume_radius'),
])
def test_bad_values_are_refused_naming_the_parameter(values, match):
    with pytest.raises(ParameterError, match=match):
        configured(BrainConfig(agent_id=1, agent_type=1), values)


def test_make_brain_applies_settings_where_the_brain_reads_them():
    brain = make_brain(agent_id=2, agent_type=1,
                       settings={'localization.gate': 9.0, 'setpoint.v_max': 0.25})
    assert brain.localizer.config.gate == 9.0
    assert brain.config.setpoint.v_max == 0.25


def test_live_changes_reach_the_running_brain_and_read_only_ones_do_not():
    brain = make_brain(agent_id=2, agent_type=1)
    set_live(brain.config, 'localization.beacon_variance_inflation', 8.0)
    assert brain.localizer.config.beacon_variance_inflation == 8.0
    with pytest.raises(ParameterError, match='read-only'):
        set_live(brain.config, 'localization.accel_noise_std', 0.1)
    with pytest.raises(ParameterError, match='resume_radius'):
        set_live(brain.config, 'hold_radius', 5.0)
    assert brain.config.hold_radius == 0.3


def test_the_table_is_keyed_by_dotted_name():
    table = spec_table(BrainConfig)
    assert table['setpoint.v_max'].live and not table['dsdv.heartbeat_period_s'].live
