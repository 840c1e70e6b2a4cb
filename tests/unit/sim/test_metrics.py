"""The chapter 4 metrics that need more than one frame: the bottleneck bound on the
settling time, the closest approach between record samples, and settling with a hold
window (swarm_sim.metrics)."""

from __future__ import annotations

import itertools
import pathlib

import numpy as np
import pytest
from scipy.spatial.distance import pdist
from shapely.geometry import box

from swarm_common.shapes import load_shape, Shape
from swarm_sim.headless import HeadlessSwarm, Scenario
from swarm_sim.metrics import (
    bottleneck_value,
    least_settling_time,
    optimal_assigned_paths,
    SEPARATION_REACH,
    SeparationTracker,
    SettleTracker,
    trial_metrics,
    V_MAX,
)

SQUARE = pathlib.Path(__file__).resolve().parents[2] / 'data' / 'square_8m.json'


def _brute_bottleneck(cost: np.ndarray) -> float:
    n = len(cost)
    return min(max(cost[i, p[i]] for i in range(n)) for p in itertools.permutations(range(n)))


@pytest.mark.parametrize('seed', range(40))
def test_the_bottleneck_value_equals_brute_force_over_all_permutations(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 8))
    # Half the cases on a coarse integer grid: many ties between costs.
    cost = (rng.integers(0, 6, (n, n)).astype(float) if seed % 2
            else rng.uniform(0.0, 50.0, (n, n)))
    assert bottleneck_value(cost) == _brute_bottleneck(cost)


def test_the_least_settling_time_is_the_bottleneck_not_the_minimum_sum_assignment():
    # Type 1 robots at (0, 0) and (5, 0) end at (0, 0) and (0, 5). The minimum-sum
    # assignment keeps the first in place and sends the second sqrt(50) = 7.07 m; the
    # bottleneck assignment swaps them, 5 m each: no robot need travel more than 5 m.
    # A type 2 pair needs 2 m at most. Least settling: 5 m at 0.5 m/s.
    initial = np.array([[0.0, 0.0], [5.0, 0.0], [20.0, 0.0], [21.0, 0.0]])
    final = np.array([[0.0, 0.0], [0.0, 5.0], [22.0, 0.0], [23.0, 0.0]])
    types = np.array([1, 1, 2, 2])
    shape = Shape('field', box(-1.0, -1.0, 24.0, 6.0))
    radii = {1: 0.15, 2: 0.3}
    assert least_settling_time(initial, final, types, shape, radii) == pytest.approx(10.0)
    assert optimal_assigned_paths(initial, final, types, shape, radii).max() == \
        pytest.approx(np.sqrt(50.0))
    assert V_MAX == 0.5                      # thesis 3.2.4


def test_trial_metrics_report_the_settling_ratio_and_no_separation_without_a_tracker():
    # Three robots on a line at 0, 1, 2 end at 1, 2, 3.5: the robot that ends at 3.5
    # is at least 1.5 m from it, so no run settles before 3 s; settled at 6 s: ratio 2.
    start = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    end = np.array([[1.0, 0.0], [2.0, 0.0], [3.5, 0.0]])
    record = {'times': np.array([0.0, 10.0]), 'positions': np.stack([start, end]),
              'velocities': np.zeros((2, 3, 2)), 'estimates': np.stack([start, end]),
              'alive': np.ones((2, 3), bool), 'modes': np.zeros((2, 3), int),
              'goal_ids': np.array([[-1, -1, -1], [0, 1, 2]]),
              'digests': np.array([[0, 0, 0], [5, 5, 5]])}
    m = trial_metrics(record, [1, 1, 1], [False] * 3, Shape('strip', box(-1, -1, 4, 1)),
                      {1: 0.15}, settling={'settled': True, 'settling_time': 6.0,
                                           'redepartures': 0})
    assert m['displacement_lower_bound'] == pytest.approx(3.5)
    assert m['least_settling_time'] == pytest.approx(1.5 / 0.5)
    assert m['settling_ratio'] == pytest.approx(6.0 / 3.0)
    # No tracker: the record cannot tell whether robots touched between samples.
    assert m['min_separation_ratio'] is None and m['contacts'] is None


def test_a_robot_passing_through_another_between_two_record_samples_is_caught():
    # Two point masses of coverage radius 0.1 m drive head-on at 0.5 m/s each along x
    # and meet at t = 2.25 s. At the 2 Hz samples t = 2.0 and 2.5 s they are 0.25 m
    # apart (1.25 summed radii) on either side: the record never sees them closer than
    # 1.25, yet in between they went through each other.
    radii = np.array([0.1, 0.1])
    every_step, sampled = SeparationTracker(), SeparationTracker()
    dt = 0.02
    for k in range(int(round(4.0 / dt)) + 1):
        t = k * dt
        x = 0.5 * t - 1.125
        pos = np.array([[x, 0.0], [-x, 0.0]])
        every_step.update(pos, radii)
        if k % 25 == 0:                        # 2 Hz
            sampled.update(pos, radii)
    assert sampled.result()['min_separation_ratio'] == pytest.approx(1.25)
    assert sampled.result()['contacts'] == 0
    caught = every_step.result()
    # At 50 Hz the pair is at most 0.01 m from dead centre at some step: ratio <= 0.05.
    assert caught['min_separation_ratio'] <= 0.05
    assert caught['contacts'] == 1               # one overlap, entered once


def test_separation_is_the_least_ratio_over_every_living_pair_within_reach(kernels):
    # The definition, by brute force over all pairs (scipy's pdist), on random crowds of
    # two to sixty robots with some removed: the smallest distance / (r_i + r_j) among
    # living pairs within SEPARATION_REACH of the largest summed radii, and the pairs
    # below 1 counted once when they enter the overlap.
    rng = np.random.default_rng(7)
    for _ in range(200):
        n = int(rng.integers(2, 61))
        radii = rng.uniform(0.1, 0.5, n)
        alive = rng.random(n) > 0.2
        tracker = SeparationTracker()
        entered = 0
        before: set[tuple[int, int]] = set()
        low_all = np.inf
        for _ in range(3):
            pos = rng.uniform(-2.0, 2.0, (n, 2)) * np.sqrt(n)
            tracker.update(pos, radii, alive)
            live = np.flatnonzero(alive)
            reach = 2.0 * radii[live].max() * SEPARATION_REACH if len(live) else 0.0
            now: set[tuple[int, int]] = set()
            if len(live) >= 2:
                i, j = np.triu_indices(len(live), 1)
                d = pdist(pos[live])
                near = d <= reach
                ratio = d[near] / (radii[live][i[near]] + radii[live][j[near]])
                if len(ratio):
                    low_all = min(low_all, float(ratio.min()))
                now = {(int(live[a]), int(live[b]))
                       for a, b, r in zip(i[near], j[near], ratio) if r < 1.0}
            entered += len(now - before)
            before = now
            assert tracker.overlapping_pairs() == sorted(now)
        assert tracker.min_ratio == pytest.approx(low_all, rel=1e-12)
        assert tracker.contacts == entered


def test_contacts_count_each_entry_into_overlap_and_ignore_the_dead():
    radii = np.array([0.5, 0.5, 0.5])
    tracker = SeparationTracker()
    far, near = 5.0, 0.8                         # summed radii 1.0
    for gap in (far, near, near, far, near, far):
        tracker.update(np.array([[0.0, 0.0], [gap, 0.0], [50.0, 0.0]]), radii)
    assert tracker.contacts == 2
    assert tracker.min_ratio == pytest.approx(0.8)
    # A removed robot's wreck is no contact.
    tracker.update(np.array([[0.0, 0.0], [0.1, 0.0], [50.0, 0.0]]), radii,
                   np.array([True, False, True]))
    assert tracker.contacts == 2


def test_settling_needs_the_condition_to_hold_for_the_window_until_the_end():
    def run(pattern, hold=30.0, change_at=None):
        tracker = SettleTracker(hold)
        for t in np.arange(0.0, len(pattern) * 1.0, 1.0):
            if change_at is not None and t == change_at:
                tracker.change(t)
            tracker.update(float(t), pattern[int(t)] == '1')
        return tracker.result()

    # Arrives at 10 s, holds to 59 s: settled at 10 s.
    assert run('0' * 10 + '1' * 50)['settling_time'] == 10.0
    # Arrives at 10 s, leaves at 20 s, back at 25 s and holds: settled at 25, one
    # re-departure.
    r = run('0' * 10 + '1' * 10 + '0' * 5 + '1' * 40)
    assert (r['settled'], r['settling_time'], r['redepartures']) == (True, 25.0, 1)
    # Back at 45 s but the run ends at 59 s, 14 s into the 30 s window: not settled.
    r = run('0' * 10 + '1' * 10 + '0' * 25 + '1' * 15)
    assert (r['settled'], r['settling_time'], r['redepartures']) == (False, None, 1)
    # A commanded change at 20 s moves the robots on: no re-departure.
    r = run('0' * 10 + '1' * 12 + '0' * 8 + '1' * 40, change_at=20.0)
    assert (r['settled'], r['settling_time'], r['redepartures']) == (True, 30.0, 0)


def test_a_simulated_trial_settles_no_sooner_than_the_least_settling_time():
    scenario = Scenario(shape=load_shape(str(SQUARE)), type_counts={1: 3, 2: 2, 3: 1},
                        n_beacons=3, half_size=15.0, seed=0, duration_s=200.0,
                        settle_hold_s=10.0)
    record = HeadlessSwarm(scenario).run()
    m = record.metrics
    assert m['settled'] and m['outcome'] == 'settled'
    assert m['least_settling_time'] > 0.0
    assert m['settling_time'] >= m['least_settling_time']
    assert m['settling_ratio'] >= 1.0
    # The run went on for the hold window after settling, and no longer.
    assert record.times[-1] - m['settling_time'] == pytest.approx(10.0, abs=0.5)
    # The separation came from every control step (50 Hz), not from the record.
    assert m['separation_steps'] >= int(record.times[-1] / scenario.control_dt)


def test_a_trial_that_cannot_settle_in_its_duration_reports_not_settled():
    scenario = Scenario(shape=load_shape(str(SQUARE)), type_counts={1: 3, 2: 2, 3: 1},
                        n_beacons=3, half_size=15.0, seed=0, duration_s=20.0)
    m = HeadlessSwarm(scenario).run().metrics
    assert m['outcome'] == 'not settled' and not m['settled']
    assert m['settling_time'] is None and m['settling_ratio'] is None
    assert m['total_displacement'] > 0.0 and m['duration'] == pytest.approx(20.0)
