"""Hungarian goal assignment per robot type (thesis 3.2.2.2, Alg. 6).

The assignment minimises the summed path cost of each type (the swarm's total
displacement); it is a consensus, so every agent holding the same cost rows must get
the same answer whatever order the rows arrived in. Checked against brute force over
``itertools.permutations`` on small random cases.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from swarm_agent.assignment import assign

TYPES = (1, 2, 3)   # Table 4.1


def brute_force(rows: dict[int, tuple[int, np.ndarray]], goal_types: np.ndarray,
                goal_ids: np.ndarray) -> tuple[float, dict[int, int]]:
    """Exhaustive optimum per type: (total cost, agent id -> goal id).

    Every agent gets a goal while goals last (the larger side is left partly empty).
    """
    total, result = 0.0, {}
    for t in sorted({r[0] for r in rows.values()}):
        agents = sorted(a for a, (at, _) in rows.items() if at == t)
        cols = list(np.flatnonzero(goal_types == t))
        if not cols:
            continue
        best, best_pairs = np.inf, []
        if len(agents) <= len(cols):
            choices = ((agents, perm) for perm in itertools.permutations(cols, len(agents)))
        else:
            choices = ((perm, cols) for perm in itertools.permutations(agents, len(cols)))
        for who, where in choices:
            pairs = list(zip(who, where))
            cost = sum(rows[a][1][g] for a, g in pairs)
            if cost < best:
                best, best_pairs = cost, pairs
        total += best
        result.update({a: int(goal_ids[g]) for a, g in best_pairs})
    return total, result


def random_case(rng: np.random.Generator, agents_per_type: dict[int, int],
                goals_per_type: dict[int, int]) -> tuple[dict, np.ndarray, np.ndarray]:
    """Rows of path-like costs (distances between random points), shuffled goal types."""
    goal_types = np.array([t for t, n in goals_per_type.items() for _ in range(n)])
    rng.shuffle(goal_types)
    goals = rng.uniform(-50, 50, (len(goal_types), 2))    # thesis workspace +/-50 m
    ids = rng.permutation(1000)[:sum(agents_per_type.values())]
    types = [t for t, n in agents_per_type.items() for _ in range(n)]
    rows = {}
    for agent_id, t in zip(ids, types):
        position = rng.uniform(-50, 50, 2)
        rows[int(agent_id)] = (t, np.linalg.norm(goals - position, axis=1))
    goal_ids = rng.permutation(5000)[:len(goal_types)]
    return rows, goal_types, goal_ids


def total_cost(rows: dict, result: dict[int, int], goal_ids: np.ndarray) -> float:
    """Summed cost of an assignment given as agent id -> goal id."""
    column = {int(g): k for k, g in enumerate(goal_ids)}
    return sum(rows[a][1][column[g]] for a, g in result.items())


def shuffled(rows: dict, rng: np.random.Generator) -> dict:
    """The same rows inserted in another order, as lists instead of arrays."""
    keys = list(rows)
    rng.shuffle(keys)
    return {k: (rows[k][0], list(rows[k][1])) for k in keys}


@pytest.mark.parametrize('seed', range(6))
def test_hungarian_equals_brute_force_per_type(seed):
    rng = np.random.default_rng(seed)
    counts = {t: int(rng.integers(1, 6)) for t in TYPES}     # up to 5! per type
    rows, goal_types, goal_ids = random_case(rng, counts, counts)
    result = assign(rows, goal_types, goal_ids)
    best, expected = brute_force(rows, goal_types, goal_ids)
    assert result == expected
    assert total_cost(rows, result, goal_ids) == pytest.approx(best, rel=1e-12)
    # Agents only get goals of their own type, each goal at most once.
    type_of_goal = dict(zip(goal_ids.tolist(), goal_types.tolist()))
    assert all(type_of_goal[g] == rows[a][0] for a, g in result.items())
    assert len(set(result.values())) == len(result) == len(rows)


@pytest.mark.parametrize('seed', range(3))
def test_every_agent_computes_the_same_assignment_from_the_same_rows(seed):
    rng = np.random.default_rng(100 + seed)
    rows, goal_types, goal_ids = random_case(rng, {1: 6, 2: 5, 3: 3}, {1: 6, 2: 5, 3: 3})
    reference = assign(rows, goal_types, goal_ids)
    for _ in range(10):       # ten agents, each received the rows in its own order
        assert assign(shuffled(rows, rng), goal_types, goal_ids) == reference


def test_ties_are_broken_the_same_way_on_every_agent():
    rng = np.random.default_rng(7)
    rows = {a: (1, np.full(4, 2.5)) for a in (9, 3, 12, 5)}   # every choice costs the same
    reference = assign(rows, np.ones(4, dtype=int))
    assert sorted(reference) == [3, 5, 9, 12] and sorted(reference.values()) == [0, 1, 2, 3]
    for _ in range(10):
        assert assign(shuffled(rows, rng), np.ones(4, dtype=int)) == reference


def test_missing_rows_of_lost_agents_are_left_out_deterministically():
    rng = np.random.default_rng(11)
    rows, goal_types, goal_ids = random_case(rng, {1: 4, 2: 4}, {1: 4, 2: 4})
    lost = sorted(rows)[::3]
    survivors = {a: r for a, r in rows.items() if a not in lost}
    result = assign(survivors, goal_types, goal_ids)
    assert not set(lost) & set(result)
    assert set(result) == set(survivors)
    # The survivors get the optimum among themselves, the same on every agent.
    assert result == brute_force(survivors, goal_types, goal_ids)[1]
    for _ in range(5):
        assert assign(shuffled(survivors, rng), goal_types, goal_ids) == result


def test_more_goals_than_agents_leaves_the_costliest_goals_empty():
    rng = np.random.default_rng(21)
    rows, goal_types, goal_ids = random_case(rng, {1: 3, 2: 2}, {1: 6, 2: 4})
    result = assign(rows, goal_types, goal_ids)
    assert set(result) == set(rows)                      # every agent has a goal
    assert len(set(result.values())) == 5                # 5 of the 10 goals stay empty
    assert result == brute_force(rows, goal_types, goal_ids)[1]


def test_more_agents_than_goals_leaves_the_costliest_agents_unassigned():
    rng = np.random.default_rng(22)
    rows, goal_types, goal_ids = random_case(rng, {1: 6, 2: 3}, {1: 3, 2: 2})
    result = assign(rows, goal_types, goal_ids)
    assert len(result) == 5 and len(set(result.values())) == 5
    assert result == brute_force(rows, goal_types, goal_ids)[1]
    # An agent with no goal of its type at all is not assigned.
    rows[999] = (3, np.ones(len(goal_types)))
    assert 999 not in assign(rows, goal_types, goal_ids)


def test_unreachable_goals_are_avoided_and_never_assigned():
    # Agent 1 reaches only goal 0; agent 0 reaches both and is cheaper at goal 0.
    # The only assignment that serves both sends agent 0 to the costlier goal 1.
    inf = np.inf
    rows = {0: (1, np.array([1.0, 10.0])), 1: (1, np.array([2.0, inf]))}
    assert assign(rows, np.array([1, 1])) == {0: 1, 1: 0}
    # Agent 3 reaches only goal 71, so agent 0 (cost 1) beats agent 1 (cost 2) to goal
    # 70; agent 2 reaches nothing and is left unassigned rather than sent anywhere.
    rows[2] = (1, np.array([inf, inf]))
    rows[3] = (1, np.array([inf, 4.0]))
    result = assign(rows, np.array([1, 1]), np.array([70, 71]))
    assert result == {0: 70, 3: 71}
    # Nothing reachable at all: nobody is assigned, no error.
    assert assign({4: (1, np.array([inf, inf]))}, np.array([1, 1])) == {}
