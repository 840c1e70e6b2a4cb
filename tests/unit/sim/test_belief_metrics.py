"""Agreement of the assignment consensus from a record of agent beliefs (swarm_sim.metrics)."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_sim.metrics import belief_metrics


def _record(digests, rounds, modes=None):
    digests = np.array(digests)
    samples, n = digests.shape
    return {'estimates': np.zeros((samples, n, 2)), 'positions': np.zeros((samples, n, 2)),
            'alive': np.ones((samples, n), dtype=bool),
            'modes': np.zeros((samples, n), dtype=int) if modes is None else np.array(modes),
            'digests': digests, 'rounds': np.array(rounds),
            'goal_ids': np.tile(np.arange(n), (samples, 1))}


def test_a_state_sampled_before_its_agent_closed_the_round_is_not_a_disagreement():
    # Three agents of one type. At the second sample agent 2 still reports round 1
    # (digest 11) while the others are in round 2 (digest 22): sample by sample that is
    # one agent in three disagreeing, round by round nobody disagrees.
    rec = _record(digests=[[11, 11, 11], [22, 22, 11], [22, 22, 22]],
                  rounds=[[1, 1, 1], [2, 2, 1], [2, 2, 2]])
    m = belief_metrics(rec, types=np.array([1, 1, 1]), is_beacon=np.zeros(3, dtype=bool))
    assert m['assignment_agreement'] == pytest.approx((1 + 2 / 3 + 1) / 3)
    assert m['round_agreement'] == 1.0


def test_agents_that_used_other_rows_in_the_same_round_disagree_per_type():
    # Round 5: agents 0 and 1 (type 1) agree, agent 2 (type 1) used other rows; agent 3 is
    # alone in its type; agent 4 is LOST and not counted.
    rec = _record(digests=[[7, 7, 8, 9, 3]], rounds=[[5, 5, 5, 5, 5]],
                  modes=[[0, 0, 0, 0, 1]])
    m = belief_metrics(rec, types=np.array([1, 1, 1, 2, 1]), is_beacon=np.zeros(5, dtype=bool))
    assert m['round_agreement'] == pytest.approx(3 / 4)
    no_rounds = {k: v for k, v in rec.items() if k != 'rounds'}   # the headless record
    assert np.isnan(belief_metrics(no_rounds, types=np.array([1, 1, 1, 2, 1]),
                                   is_beacon=np.zeros(5, dtype=bool))['round_agreement'])


def test_optimal_paths_give_the_displacement_bound_and_the_least_settling_time():
    from shapely.geometry import box

    from swarm_mission.shapes import Shape
    from swarm_sim.metrics import run_metrics

    # Two type-1 robots at x = 0 and x = 10 end at x = 7 and x = 4. The optimal
    # assignment sends them to 4 and 7 (4 + 3 = 7 m, not 7 + 6 = 13 m); its longest
    # path, 4 m, is what no method's settling time can beat at 0.5 m/s.
    start = np.array([[0.0, 0.0], [10.0, 0.0]])
    end = np.array([[7.0, 0.0], [4.0, 0.0]])
    positions = np.stack([start, end])
    m = run_metrics(np.array([0.0, 20.0]), positions, np.zeros_like(positions), [1, 1],
                    Shape('strip', box(-1.0, -1.0, 11.0, 1.0)), {1: 0.15})
    assert m['displacement_lower_bound'] == pytest.approx(7.0)
    assert m['longest_assigned_path'] == pytest.approx(4.0)
