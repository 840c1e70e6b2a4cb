"""Identical inputs computed once (issue 23): decoding per transmission, assignment per row set.

Every receiver of one transmission gets the same frame object (``frame_auth`` opens it
once), so the wire and mesh-message decoders keep their last result by the identity of
their argument (``wire.last_result``): the receivers share one frozen decoded value. The
agents of one type holding the same versioned cost rows compute the same Hungarian
assignment (thesis 3.2.2.2, Alg. 6), so a process solves each distinct row set once
(``assignment.AssignmentCache``). Neither may change what any agent decides.
"""

from __future__ import annotations

import pathlib

import numpy as np
import pytest

from swarm_agent import brain as brain_module
from swarm_agent import wire
from swarm_agent.agent_factory import make_brain
from swarm_agent.assignment import assign, AssignmentCache
from swarm_agent.frame_auth import FrameAuth, Keyring
from swarm_agent.mesh_messages import CostRow, NeighbourInfo
from swarm_agent.packet import BROADCAST, Kind, Packet
from swarm_common.goals import Goal
from swarm_common.shapes import load_shape
from swarm_sim.headless import HeadlessSwarm, Scenario

SQUARE = pathlib.Path(__file__).resolve().parents[2] / 'data' / 'square_8m.json'
KEYRING = Keyring(((1, bytes(range(32))),), 1)


# ------------------------------------------------------------------ decode once
def test_last_result_is_kept_by_identity_of_immutable_bytes_only():
    calls = []

    @wire.last_result
    def decode(data: bytes) -> tuple[int, ...]:
        calls.append(data)
        if not data:
            raise wire.WireError('empty')
        return tuple(data)

    frame = bytes([1, 2, 3])
    first = decode(frame)
    assert decode(frame) is first and len(calls) == 1
    # Equal bytes in another object: decoded again (identity, not content), same value.
    assert decode(bytes([1, 2, 3])) == first and len(calls) == 2
    # A mutable buffer is never kept: after a change it decodes to the new content.
    buffer = bytearray([4, 5])
    assert decode(buffer) == (4, 5)
    buffer[0] = 9
    assert decode(buffer) == (9, 5) and len(calls) == 4
    # A failure keeps nothing: it is raised again, and the last good result stays.
    empty = b''
    for _ in range(2):
        with pytest.raises(wire.WireError):
            decode(empty)
    assert len(calls) == 6


def _sealed(auth: FrameAuth, source: int, kind: Kind, payload: bytes) -> Packet:
    return auth.seal(Packet(source, BROADCAST, int(kind), 1, 32, payload))


def test_the_receivers_of_one_transmission_share_its_decoded_messages():
    """A heartbeat and a flooded cost row heard by two agents: one decode each, the
    very same frozen objects in both agents' state."""
    goals = [Goal(i, 1, float(i), 0.0, 0.15) for i in range(3)]
    receivers = []
    for agent in (1, 2):
        brain = make_brain(agent_id=agent, agent_type=1, keyring=KEYRING)
        brain.set_goals(goals, 1)
        receivers.append(brain)
    sender = FrameAuth(KEYRING)
    info = NeighbourInfo(1, False, 0, (3.0, 4.0), (0.0, 0.0))
    heartbeat = _sealed(sender, 9, Kind.HEARTBEAT, wire.encode_heartbeat(2, info.encode()))
    row = CostRow.from_costs(9, 1, 1, 5, np.array([1.0, 2.0, 3.0]))
    (chunk,) = wire.split_message(row.encode(), 1)
    flood = _sealed(sender, 9, Kind.FLOOD, wire.encode_routed(9, 1, chunk))
    for brain in receivers:
        brain.on_packet(0.0, heartbeat)
        brain.on_packet(0.0, flood)
    a, b = receivers
    assert a.neighbours[9].info == info
    assert a.neighbours[9].info is b.neighbours[9].info
    assert a._rows[5][9] == row
    assert a._rows[5][9] is b._rows[5][9]
    assert a.stats['rows_received'] == b.stats['rows_received'] == 1


# ------------------------------------------------------------------ assignment once
def _brains_with_rows(count: int, seed: int) -> dict:
    """``count`` type-1 agents that all hold every agent's row of round 1 (random
    costs, seeded); each built its own row as in the field."""
    rng = np.random.default_rng(seed)
    goals = [Goal(i, 1, float(x), float(y), 0.15)
             for i, (x, y) in enumerate(rng.uniform(-5.0, 5.0, (count, 2)))]
    shape = load_shape('circle_314')
    brains = {}
    for agent in range(count):
        brain = make_brain(agent_id=agent, agent_type=1,
                           initial_position=tuple(rng.uniform(-8.0, 8.0, 2)))
        brain.set_shape(shape, 1)
        brain.set_goals(goals, 1)
        brain._report_costs(1)
        brains[agent] = brain
    rows = {a: b._rows[1][a] for a, b in brains.items()}
    for brain in brains.values():
        for row in rows.values():
            brain._store_row(CostRow.decode(row.encode()))
    return brains


def test_agents_with_the_same_rows_share_one_solve(monkeypatch):
    cache = AssignmentCache()
    monkeypatch.setattr(brain_module, 'SHARED_ASSIGNMENTS', cache)
    brains = _brains_with_rows(8, seed=3)
    for brain in brains.values():
        brain._assign(1)
    assert cache.solves == 1
    # The shared answer is the one assign() gives on the rows without the cache.
    rows = {a: (1, b._rows[1][a].costs) for a, b in brains.items()}
    goal_ids = np.array([g.id for g in brains[0]._my_goals])
    expected = assign(rows, np.ones(len(goal_ids), dtype=int), goal_ids)
    assert {a: b.goal_id for a, b in brains.items()} == expected
    assert sorted(expected.values()) == list(range(8))   # 8 agents, 8 goals: a matching
    assert len({b.assignment_digest for b in brains.values()}) == 1
    # One agent missing one row holds another row set: a second solve, for it alone.
    lonely = brains[0]
    del lonely._rows[1][7]
    lonely._assign(1)
    assert cache.solves == 2 and lonely.rows_used == 7
    assert lonely.assignment_digest != brains[1].assignment_digest


def test_the_cache_keeps_the_most_recently_used_results():
    cache = AssignmentCache(max_size=2)
    solve = {'a': lambda: {1: 10}, 'b': lambda: {1: 11}, 'c': lambda: {1: 12}}
    for key in ('a', 'b', 'a', 'c'):       # 'b' is the least recently used when 'c' comes
        cache.get(key, solve[key])
    assert cache.solves == 3
    assert cache.get('a', solve['a']) == {1: 10} and cache.solves == 3
    assert cache.get('b', solve['b']) == {1: 11} and cache.solves == 4
    with pytest.raises(TypeError):
        cache.get('b', solve['b'])[1] = 0    # shared results are read-only
    with pytest.raises(ValueError, match='at least 1'):
        AssignmentCache(max_size=0)


class _NoCache(AssignmentCache):
    """Solves at every call: the brains as they were before the cache."""

    def get(self, key, solve):
        self.solves += 1
        return solve()


def _trial(monkeypatch, cache: AssignmentCache) -> dict:
    monkeypatch.setattr(brain_module, 'SHARED_ASSIGNMENTS', cache)
    scenario = Scenario(shape=load_shape(str(SQUARE)), type_counts={1: 5, 2: 4, 3: 3},
                        n_beacons=3, half_size=15.0, seed=1, duration_s=16.0)
    return HeadlessSwarm(scenario).run()


def test_a_headless_trial_is_the_same_with_and_without_the_cache(monkeypatch):
    """12 robots of three types, 16 s (eight consensus rounds): every goal, digest and
    position of the record is equal, and the cached run solves once per distinct row
    set, one per type and round where the uncached one solves once per agent."""
    cached, uncached = AssignmentCache(), _NoCache()
    with_cache = _trial(monkeypatch, cached)
    without = _trial(monkeypatch, uncached)
    for key in ('goal_ids', 'digests', 'positions', 'estimates'):
        assert np.array_equal(getattr(with_cache, key), getattr(without, key)), key
    assert with_cache.metrics['assignment_agreement'] == \
        without.metrics['assignment_agreement']
    assert with_cache.digests[-1].any(), 'no agent assigned: the trial tests nothing'
    # Without the cache each of the 12 agents solves at every round; with it, the agents
    # of a type holding the same rows (here all of them: one digest per type) share one.
    rounds = uncached.solves // 12
    assert rounds >= 6 and uncached.solves == 12 * rounds
    assert len(set(with_cache.digests[-1])) == 3
    assert cached.solves == 3 * rounds
