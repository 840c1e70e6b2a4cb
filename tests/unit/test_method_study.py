"""scripts/method_study.py: the worst-method marks of thesis Table 4.4."""

from __future__ import annotations

import method_study


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
