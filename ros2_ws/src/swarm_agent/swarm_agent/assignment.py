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

Identical inputs are solved once: ``AssignmentCache`` keeps the results of one process
(the evaluator's or a composed container's brains) keyed by the exact bytes of the rows
used, so the agents of one type holding the same versioned rows share one Hungarian
solve per round instead of one each.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Hashable, Mapping
import threading
from types import MappingProxyType

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


class AssignmentCache:
    """Least-recently-used results of ``assign`` by a key that determines its inputs.

    The key must fix the whole problem: ``AgentBrain._assign`` uses the bytes its rows'
    digest is computed over (every row's agent id and encoding: type, goal version,
    round and quantised costs) and the goal ids, so equal keys mean equal matrices and,
    ``assign`` being deterministic, equal answers. Results are read-only mappings shared
    by every caller. ``solves`` counts the calls that ran the solver.
    """

    def __init__(self, max_size: int = 256) -> None:
        if max_size < 1:
            raise ValueError(f'an assignment cache holds at least 1 result, got {max_size}')
        self.max_size = max_size
        self.solves = 0
        self._results: OrderedDict[Hashable, Mapping[int, int]] = OrderedDict()
        self._lock = threading.Lock()   # a composed container may step brains on threads

    def get(self, key: Hashable, solve: Callable[[], Mapping[int, int]]) -> Mapping[int, int]:
        """The result kept under ``key``, or ``solve()``'s, kept."""
        with self._lock:
            result = self._results.get(key)
            if result is not None:
                self._results.move_to_end(key)
                return result
        result = MappingProxyType(dict(solve()))
        with self._lock:
            self.solves += 1
            self._results[key] = result
            if len(self._results) > self.max_size:
                self._results.popitem(last=False)
        return result

    def clear(self) -> None:
        with self._lock:
            self._results.clear()


SHARED = AssignmentCache()   # the one cache of this process
