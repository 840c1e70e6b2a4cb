"""Goal assignment by the Hungarian algorithm, per robot type (thesis 3.2.2.2, Alg. 6).

``assign`` is the consensus function: every agent that holds the same cost rows calls
it and gets the same answer, independent of dict order (rows are sorted by agent id,
goals kept in the given order, and scipy's linear_sum_assignment is deterministic).

Documented fallbacks (never a hang):
- an agent whose row is missing is not assigned (the brain keeps its previous goal);
- more agents of a type than goals of that type: the rectangular problem leaves the
  costliest extras unassigned;
- more goals than agents: some goals stay empty;
- an unreachable goal (inf cost) is assigned only if nothing else is possible, and such
  an agent is then left unassigned rather than sent to an unreachable goal.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.optimize import linear_sum_assignment

UNREACHABLE = 1e12


def assign(rows: Mapping[int, tuple[int, np.ndarray]], goal_types: np.ndarray,
           goal_ids: np.ndarray | None = None) -> dict[int, int]:
    """Agent id -> goal id minimising the summed cost within each type.

    ``rows``: agent id -> (agent type, costs over the goals in ``goal_types`` order).
    """
    goal_types = np.asarray(goal_types)
    goal_ids = np.arange(len(goal_types)) if goal_ids is None else np.asarray(goal_ids)
    result: dict[int, int] = {}
    for t in sorted({int(r[0]) for r in rows.values()}):
        agents = sorted(a for a, (agent_type, _) in rows.items() if int(agent_type) == t)
        cols = np.flatnonzero(goal_types == t)
        if not agents or not len(cols):
            continue
        cost = np.array([np.asarray(rows[a][1], dtype=float)[cols] for a in agents])
        finite = np.where(np.isfinite(cost), cost, UNREACHABLE)
        r, c = linear_sum_assignment(finite)
        for i, j in zip(r, c):
            if finite[i, j] < UNREACHABLE:
                result[agents[i]] = int(goal_ids[cols[j]])
    return result
