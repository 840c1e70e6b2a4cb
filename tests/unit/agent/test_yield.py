"""Collision avoidance inside the brain: the filter acts on proximity scans, a parked
robot yields to a neighbour that comes too close and then returns to its goal."""

from __future__ import annotations

import numpy as np
from shapely.geometry import box

from swarm_agent.agent_factory import make_brain
from swarm_common.goals import Goal
from swarm_common.shapes import Shape

DT = 0.02


def _parked_brain():
    """A type-2 robot (coverage radius 0.3 m) parked on its goal at the origin."""
    brain = make_brain(agent_id=1, agent_type=2, initial_position=(0.0, 0.0))
    brain.set_shape(Shape('square', box(-5.0, -5.0, 5.0, 5.0)), 1)
    brain.set_goals([Goal(0, 2, 0.0, 0.0, 0.3)], 1)
    t = 0.0
    while t < 3.0:          # round 0 reports the row, round 1 (t = 2 s) assigns it
        brain.step(t)
        t += DT
    assert brain.goal_id == 0 and brain._parked
    return brain, t


def test_a_parked_robot_yields_and_returns_to_its_goal():
    brain, t = _parked_brain()
    assert not brain.step(t).force.any()
    # A type-3 neighbour (0.5 m) 0.6 m to the east: 0.5 m inside the 0.3 m buffer.
    for _ in range(10):
        t += DT
        brain.on_proximity(t, [[0.6, 0.0]], [0.5])
        out = brain.step(t)
    params = brain.config.setpoint
    np.testing.assert_allclose(out.velocity_setpoint,
                               [-0.5 * params.avoid_rate * 0.5, 0.0], atol=1e-9)
    assert out.force[0] < 0.0                    # pushed west, away from the neighbour
    # The neighbour leaves: the robot stops yielding and heads back to its goal.
    brain.localizer.position[:] = [-0.5, 0.0]    # where the push took it
    for _ in range(60):
        t += DT
        brain.on_proximity(t, np.zeros((0, 2)), [])
        out = brain.step(t)
    assert not brain._yielding and not brain._parked
    assert out.velocity_setpoint[0] > 0.0         # east, back to the goal


def test_stale_scans_are_not_used():
    brain, t = _parked_brain()
    brain.on_proximity(t, [[0.6, 0.0]], [0.5])
    assert brain.step(t + DT).velocity_setpoint.any()
    # Without a fresh scan for longer than proximity_stale_s, and with no neighbour
    # heard on the radio, nobody is near: the robot parks again.
    t += brain.config.proximity_stale_s + 0.6
    assert not brain.step(t).velocity_setpoint.any()


def test_malformed_scans_are_dropped():
    brain, t = _parked_brain()
    brain.on_proximity(t, [[np.nan, 0.0], [0.6, 0.0]], [0.5, 0.5])   # one bad row
    np.testing.assert_allclose(brain._proximity[0], [[0.6, 0.0]])
    brain.on_proximity(t, [[0.6, 0.0]], [0.5, 0.3])                   # lengths differ
    np.testing.assert_allclose(brain._proximity[0], [[0.6, 0.0]])     # kept the last


def test_a_robot_parked_outside_the_shape_moves_back_in():
    """A goal 0.2 m inside the contour and a robot parked 0.5 m from it, outside: within
    the resume radius (0.8 m), but eq. 4.1 never holds there, so it drives to its goal;
    the same offset inside the shape stays parked."""
    brain, t = _parked_brain()
    brain.set_shape(Shape('edge', box(-5.0, -5.0, 0.2, 5.0)), 2)
    brain.localizer.position[:] = [0.5, 0.0]          # outside: x > 0.2
    for _ in range(30):
        t += DT
        out = brain.step(t)
    assert not brain._parked and out.velocity_setpoint[0] < 0.0   # west, back inside
    brain, t = _parked_brain()
    brain.set_shape(Shape('edge', box(-5.0, -5.0, 0.2, 5.0)), 2)
    brain.localizer.position[:] = [-0.5, 0.0]         # as far, inside
    for _ in range(30):
        t += DT
        out = brain.step(t)
    assert brain._parked and not out.velocity_setpoint.any()
