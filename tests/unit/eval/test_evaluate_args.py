"""swarm_eval.evaluate (scripts/evaluate.py): --morph and --remesh reach the scenario; bad
values are one line."""

from __future__ import annotations

import pytest

from swarm_eval import evaluate
from swarm_eval.scenario import build_scenario, ScenarioSpec


def test_morph_becomes_the_scenarios_shape_sequence():
    args = evaluate.parse_args(['--shape', 'thesis_shape_1', '--morph', 'rotate:90@200+60',
                                '--remesh', 'scratch', '--out', 'unused'])
    scenario = build_scenario(ScenarioSpec.from_namespace(args), 3)
    assert len(scenario.sequence) == 30 and scenario.sequence[0].time == 200.0
    assert scenario.remesh == 'scratch' and scenario.seed == 3


@pytest.mark.parametrize(('extra', 'says'), [
    (['--morph', 'fly:3@0+10'], "unknown shape change 'fly'"),
    (['--morph', 'move:3@0+10', '--sequence', 'seq.yaml'], 'either --sequence or --morph'),
    (['--remove', '30:2,9'], "--remove '30:2,9': agent ids run 0..5 with --agents 6, not [9]"),
    (['--remove', 'soon:2'], "'soon' is not a sim time in seconds"),
    (['--remove', '700:2'], '--remove at 700 s comes after the end of the run'),
])
def test_bad_shape_changes_exit_2_with_one_line(tmp_path, capsys, extra, says):
    (tmp_path / 'seq.yaml').write_text('sequence: [{time: 0, shape: circle_314}]\n')
    extra = [str(tmp_path / e) if e == 'seq.yaml' else e for e in extra]
    assert evaluate.main(['--agents', '6', '--beacons', '3', *extra,
                          '--out', str(tmp_path / 'out')]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and len(err.splitlines()) == 1
    assert not (tmp_path / 'out').exists()


def test_the_thesis_beacon_share_is_the_default():
    """15 % of the agents are beacons (thesis chapter 4: 8 of 50), never fewer than the
    three a trilateration needs."""
    assert build_scenario(ScenarioSpec(agents=50), 0).n_beacons == 8
    assert build_scenario(ScenarioSpec(agents=10, shape_scale=0.5), 0).n_beacons == 3
