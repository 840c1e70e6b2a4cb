"""swarm_eval.method_study (scripts/method_study.py): the worst-method marks of Table 4.4."""

from __future__ import annotations

from swarm_eval import method_study


def _worst(means: dict, key: str) -> str:
    return max(means, key=lambda m: method_study._badness(means[m], key))


def test_a_method_that_never_settles_is_the_worst_in_settling_time():
    means = {'bubble': {'settling_time': 144.0, 'settled_fraction': 1.0},
             'fractal': {'settling_time': 138.0, 'settled_fraction': 1.0},
             'forces': {'settled_fraction': 0.0}}
    assert _worst(means, 'settling_time') == 'forces'
    # Settling some trials is still worse than settling all of them, however fast.
    means['forces'] = {'settling_time': 60.0, 'settled_fraction': 0.5}
    assert _worst(means, 'settling_time') == 'forces'
    means['forces'] = {'settling_time': 60.0, 'settled_fraction': 1.0}
    assert _worst(means, 'settling_time') == 'bubble'


def test_other_metrics_mark_the_largest_mean():
    means = {'bubble': {'epsilon_t': 0.5}, 'fractal': {'epsilon_t': 0.9}, 'forces': {}}
    assert _worst(means, 'epsilon_t') == 'fractal'


def test_dynamic_table_marks_the_variant_that_adapts_best():
    table = method_study.dynamic_table({
        'move:15@200+60': {'bubble': [1.1, 1.3], 'bubble, scratch': [2.0], 'forces': [1.9]},
        'rotate:90@200+60': {'bubble': [1.5], 'bubble, scratch': [1.7], 'forces': [1.2]}})
    rows = [line for line in table if line.startswith('| move') or line.startswith('| rot')]
    assert rows == ['| move:15@200+60 | 1.20 (best) | 2.00 | 1.90 |',
                    '| rotate:90@200+60 | 1.50 | 1.70 | 1.20 (best) |']
