"""Beacons take beacon goals: the class rule of the cost rows (swarm_agent.costs.class_costs).

Each agent builds its own row with the goals of the other class at inf; the rows cross
the wire (16-bit centimetres, inf kept) and the unchanged Hungarian assignment per type
(thesis 3.2.2.2, Alg. 6) then pairs beacons with beacon goals on every agent alike.
"""

from __future__ import annotations

import numpy as np

from swarm_agent.agent_factory import make_brain
from swarm_agent.assignment import assign
from swarm_agent.costs import class_costs
from swarm_agent.mesh_messages import CostRow
from swarm_common.goals import Goal
from swarm_common.shapes import load_shape


def test_class_costs_masks_the_other_class_only_when_goals_are_marked():
    costs = np.array([1.0, 2.0, 3.0])
    marked = np.array([True, False, False])
    assert np.array_equal(class_costs(costs, marked, True), [1.0, np.inf, np.inf])
    assert np.array_equal(class_costs(costs, marked, False), [np.inf, 2.0, 3.0])
    assert np.array_equal(class_costs(costs, [False] * 3, True), costs)


def test_inf_survives_the_narrow_wire_encoding():
    row = CostRow.from_costs(3, 2, 5, 7, np.array([np.inf, 1.23, np.inf, 0.0]))
    data = row.encode()
    assert len(data) == 14 + 2 * 4                       # narrow: 16 bits a cost
    costs = CostRow.decode(data).costs
    assert np.isinf(costs[[0, 2]]).all()
    assert np.allclose(costs[[1, 3]], [1.23, 0.0])


def test_every_beacon_takes_a_beacon_goal_and_all_agents_agree():
    """Six type-2 agents, two of them beacons standing far from the two beacon goals and
    next to ordinary ones: the minimum-sum assignment without the class rule would swap
    them; with it every beacon parks on a beacon goal."""
    shape = load_shape('circle_314')
    goals = [Goal(i, 2, x, y, 0.3, beacon=i in (0, 1)) for i, (x, y) in enumerate(
        [(-8.0, 0.0), (-8.0, 2.0), (0.0, 0.0), (2.0, 0.0), (8.0, 0.0), (8.0, 2.0)])]
    starts = {10: (8.0, 0.5), 11: (8.0, 1.5), 12: (-8.0, 0.5), 13: (-8.0, 1.5),
              14: (0.0, 0.5), 15: (2.0, 0.5)}
    beacons = {10, 11}
    brains = {}
    for agent, start in starts.items():
        brain = make_brain(agent_id=agent, agent_type=2, is_beacon=agent in beacons,
                           initial_position=start)
        brain.set_shape(shape, 1)
        brain.set_goals(goals, 1)
        brain._report_costs(1)
        brains[agent] = brain
    wire = {a: CostRow.decode(b._rows[1][a].encode()) for a, b in brains.items()}
    for agent, brain in brains.items():
        for other, row in wire.items():
            if other != agent:
                brain._store_row(row)
        brain._assign(1)
    chosen = {a: b.goal_id for a, b in brains.items()}
    assert {chosen[a] for a in beacons} == {0, 1}
    assert {chosen[a] for a in starts if a not in beacons} == {2, 3, 4, 5}
    assert len({b.assignment_digest for b in brains.values()}) == 1
    # Without the class rule the same positions would put the beacons on goals 4 and 5.
    plain = {a: (2, np.hypot(*(np.array([[g.x, g.y] for g in goals]) - s).T))
             for a, s in starts.items()}
    free = assign(plain, np.array([2] * 6), np.arange(6))
    assert {free[a] for a in beacons} == {4, 5}


def test_a_goal_that_changes_class_is_dropped():
    brain = make_brain(agent_id=1, agent_type=2, is_beacon=False)
    brain.set_goals([Goal(0, 2, 0.0, 0.0, 0.3), Goal(1, 2, 1.0, 0.0, 0.3)], 1)
    brain.goal_id = 0
    brain.set_goals([Goal(0, 2, 0.0, 0.0, 0.3, beacon=True), Goal(1, 2, 1.0, 0.0, 0.3)], 2)
    assert brain.goal_id == -1
