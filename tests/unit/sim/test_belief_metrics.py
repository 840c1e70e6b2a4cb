"""Agreement of the assignment consensus, goal claims and localization error from a
record of agent beliefs (swarm_sim.metrics.belief_metrics)."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_sim.metrics import belief_metrics


def _record(digests, rounds=None, modes=None, goal_ids=None, times=None):
    digests = np.array(digests)
    samples, n = digests.shape
    rec = {'estimates': np.zeros((samples, n, 2)), 'positions': np.zeros((samples, n, 2)),
           'alive': np.ones((samples, n), dtype=bool),
           'modes': np.zeros((samples, n), dtype=int) if modes is None else np.array(modes),
           'digests': digests,
           'goal_ids': (np.tile(np.arange(n), (samples, 1)) if goal_ids is None
                        else np.array(goal_ids)),
           'times': np.arange(samples) * 0.5 if times is None else np.array(times)}
    if rounds is not None:
        rec['rounds'] = np.array(rounds)
    return rec


def test_a_state_sampled_before_its_agent_closed_the_round_is_not_a_disagreement():
    # Three agents of one type. At the second sample agent 2 still reports round 1
    # (digest 11) while the others are in round 2 (digest 22): sample by sample that is
    # one agent in three disagreeing, round by round nobody disagrees.
    rec = _record(digests=[[11, 11, 11], [22, 22, 11], [22, 22, 22]],
                  rounds=[[1, 1, 1], [2, 2, 1], [2, 2, 2]])
    m = belief_metrics(rec, types=np.array([1, 1, 1]), is_beacon=np.zeros(3, dtype=bool))
    assert m['assignment_agreement'] == pytest.approx((1 + 2 / 3 + 1) / 3)
    assert m['round_agreement'] == 1.0


def test_agreement_counts_every_living_agent_after_the_first_complete_round():
    # Five agents, types 1 1 1 2 1. Sample 0: agent 4 has no digest yet (the round is
    # not complete: not counted). Sample 1 (t = 0.5 s): everyone holds one; agents 0, 1
    # agree (7), agent 2 used other rows (8), agent 3 is alone in type 2, agent 4 is LOST
    # but counts (3): 3 of 5 agree. Sample 2: agent 4 lost its assignment (0) and
    # disagrees: agents 0, 1, 2 (7) and 3 agree, 4 of 5.
    rec = _record(digests=[[7, 7, 7, 9, 0], [7, 7, 8, 9, 3], [7, 7, 7, 9, 0]],
                  rounds=[[5, 5, 5, 5, 0], [5, 5, 5, 5, 5], [6, 6, 6, 6, 0]],
                  modes=[[0, 0, 0, 0, 1]] * 3)
    types = np.array([1, 1, 1, 2, 1])
    m = belief_metrics(rec, types=types, is_beacon=np.zeros(5, dtype=bool))
    assert m['first_consensus_time'] == 0.5
    assert m['assignment_agreement'] == pytest.approx((3 / 5 + 4 / 5) / 2)
    # Round 5, each agent's last digest in it: type 1 holds 7, 7, 8, 3 (2 of 4 agree),
    # type 2 holds 9 (1 of 1). Round 6: 3 of 3 and 1 of 1. 7 of 9.
    assert m['round_agreement'] == pytest.approx(7 / 9)
    no_rounds = {k: v for k, v in rec.items() if k != 'rounds'}   # the headless record
    assert np.isnan(belief_metrics(no_rounds, types=types,
                                   is_beacon=np.zeros(5, dtype=bool))['round_agreement'])
    # A round that never completes: no agreement to report.
    never = _record(digests=[[7, 7, 0]] * 3)
    assert np.isnan(belief_metrics(never, types=np.ones(3, int),
                                   is_beacon=np.zeros(3, bool))['assignment_agreement'])


def test_duplicate_goal_claims_are_counted_over_the_whole_run():
    # Four agents; samples every 0.5 s. At t = 0.5 s agents 0, 1, 2 all claim goal 0
    # (two claims beyond the first); at t = 1.0 s agents 0 and 1 claim goal 0 (one); at
    # the end everyone holds their own goal. Agent 3 is dead at t = 1.0 s, its stale
    # claim of goal 1 (also claimed by agent 1 then) does not count.
    goal_ids = [[-1, -1, -1, -1], [0, 0, 0, 3], [0, 0, 2, 1], [0, 1, 2, 3]]
    rec = _record(digests=[[1, 1, 1, 1]] * 4, goal_ids=goal_ids)
    rec['alive'][2, 3] = False
    m = belief_metrics(rec, types=np.ones(4, int), is_beacon=np.zeros(4, bool))
    assert m['duplicate_goal_claims_peak'] == 2
    assert m['duplicate_goal_claims_integral'] == pytest.approx(2 * 0.5 + 1 * 0.5)
    assert m['duplicate_goal_claims_final'] == 0


def test_localization_error_counts_non_beacons_after_their_first_fix():
    # Agent 0 is a beacon (never counted). Agent 1 is off by 10 m before its first fix
    # at sample 1, then by 1, 2 and 3 m. Agent 2 is off by 4 m from the start (fixed at
    # sample 0) and dies at sample 3 (not counted then).
    rec = _record(digests=[[1, 1, 1]] * 4)
    rec['estimates'][:, 0, 0] = 50.0
    rec['estimates'][:, 1, 0] = [10.0, 1.0, 2.0, 3.0]
    rec['estimates'][:, 2, 0] = 4.0
    rec['alive'][3, 2] = False
    rec['estimates'][3, 2] = np.nan
    rec['localized'] = np.array([[True, False, True], [True, True, True],
                                 [True, False, True], [True, True, False]])
    m = belief_metrics(rec, types=np.ones(3, int), is_beacon=np.array([True, False, False]))
    errors = np.array([1.0, 2.0, 3.0, 4.0, 4.0, 4.0])   # agent 1 from sample 1; agent 2
    assert m['max_localization_error'] == 4.0
    assert m['p95_localization_error'] == pytest.approx(np.percentile(errors, 95))
    assert m['rms_localization_error'] == pytest.approx(np.sqrt(np.mean(errors ** 2)))
