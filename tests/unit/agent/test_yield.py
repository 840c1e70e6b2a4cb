"""Collision avoidance inside the brain: the filter acts on proximity scans, a parked
robot yields to a neighbour that comes too close and then returns to its goal, and a
robot held far from its goal goes round the robots that hold it."""

from __future__ import annotations

import numpy as np
from shapely.geometry import box
import yaml

from swarm_agent.agent_factory import make_brain
from swarm_agent.brain import AgentBrain
from swarm_agent.setpoint import avoid_collisions, SetpointParams, stays_parked
from swarm_bringup import hil
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


def test_stays_parked_only_where_the_filter_leaves_a_parked_robot_still(kernels):
    """``stays_parked`` against the filter itself, over random neighbourhoods (some
    neighbours inside the parked margin, some on its edge, some outside), with and
    without a yield margin: where it is True, ``avoid_collisions`` gives a parked
    robot's zero setpoint back as zero; with one neighbour it is True exactly there.
    (Boxed in on all sides the filter may give zero too, its least-violating answer;
    stays_parked is False there and the brain recomputes.)"""
    rng = np.random.default_rng(7)
    for margin in (0.0, 0.25):
        params = SetpointParams(yield_margin=margin)
        reach = 0.3 + 0.5 + params.avoid_buffer + margin     # own + neighbour + margins
        answers = {True: 0, False: 0}
        for _ in range(600):
            k = int(rng.integers(1, 6))
            distance = rng.uniform(0.5 * reach, 2.0 * reach, k)
            if rng.random() < 0.2:
                distance[0] = reach                          # on the margin's edge
            angle = rng.uniform(-np.pi, np.pi, k)
            offsets = np.column_stack([distance * np.cos(angle), distance * np.sin(angle)])
            radii = np.full(k, 0.5)
            still = not avoid_collisions(np.zeros(2), offsets, radii, 0.3, params,
                                         parked=True).any()
            answer = stays_parked(offsets, radii, 0.3, params)
            assert still or not answer
            if k == 1:
                assert answer == still
            answers[answer] += 1
        assert min(answers.values()) > 100          # both answers were tested
    assert stays_parked(np.zeros((0, 2)), np.zeros(0), 0.3, SetpointParams())


def test_a_parked_robot_at_rest_takes_a_clear_scan_without_a_step():
    """A scan with every neighbour outside the parked margin leaves a parked robot at
    rest (``rest`` is true: nothing to recompute) with the same command and force as a
    brain made to recompute; a neighbour inside the margin still wakes it to yield."""
    brain, t = _parked_brain()
    reference, _ = _parked_brain()
    for brain_ in (brain, reference):
        brain_.step(t)
    clear = [[1.2, 0.0], [0.0, -1.3]]             # beyond 0.3 + 0.5 + 0.3 m
    for _ in range(30):
        t += DT
        brain.on_proximity(t, clear, [0.5, 0.5])
        reference.on_proximity(t, clear, [0.5, 0.5])
        reference._avoid_due = True                # recomputes, as every scan did
        resting = brain.rest(t)
        out, ref = (brain.step(t) if not resting else None), reference.step(t)
        if out is not None:
            np.testing.assert_array_equal(out.force, ref.force)
        assert not ref.force.any() and not ref.velocity_setpoint.any()
        assert not brain._commanded
    assert resting
    t += DT
    brain.on_proximity(t, [[0.6, 0.0]], [0.5])     # 0.5 m inside the 0.3 m buffer
    assert not brain.rest(t)
    assert brain.step(t).velocity_setpoint[0] < 0.0   # yields west


def test_one_call_for_many_scans_is_the_same_as_one_call_each(kernels):
    """``AgentBrain.take_proximity`` for several brains (a world's scan: a parked one
    with a clear scan, a parked one with a neighbour inside its margin, one with no
    detections, a moving one, a row that is not finite) leaves each brain as
    ``on_proximity`` with its own rows does."""
    def brains():
        parked = [_parked_brain()[0] for _ in range(3)]
        moving = make_brain(agent_id=4, agent_type=2, initial_position=(0.0, 0.0))
        return [*parked, moving]
    offsets = np.array([[1.2, 0.0], [0.0, -1.3],   # brain 0: clear
                        [0.6, 0.0], [np.nan, 0.0],  # brain 1: close, and a bad row
                        [0.6, 0.0]])                # brain 3 (moving): close
    radii = np.array([0.5, 0.5, 0.5, 0.5, 0.5])
    starts, ends = np.array([0, 2, 4, 4]), np.array([2, 4, 4, 5])
    many, each = brains(), brains()
    for brain in many + each:
        brain._avoid_due = False
    AgentBrain.take_proximity(3.5, many, offsets, radii, starts, ends)
    for brain, lo, hi in zip(each, starts, ends):
        brain.on_proximity(3.5, offsets[lo:hi], radii[lo:hi])
    for a, b in zip(many, each):
        np.testing.assert_array_equal(a._proximity[0], b._proximity[0])
        np.testing.assert_array_equal(a._proximity[1], b._proximity[1])
        assert a._proximity_at == b._proximity_at == 3.5
        assert a._avoid_due == b._avoid_due
    assert [b._avoid_due for b in many] == [False, True, False, True]


def _held_in_the_pocket(detour_after_s: float, seconds: float):
    """Robot 2 of the stalled hw_square run (tests/unit/agent/test_held_robots.py): a
    type-2 robot (11 cm) with the arena's parameters, 0.45 m from its goal, between
    robots 0 (16 cm) and 3 (8 cm) of its proximity scans, held where it stands. Its
    commands every 0.5 s after the first assignment (2 s)."""
    hw = yaml.safe_load(hil.bridge_config('hw_agent.yaml').read_text())['/**'][
        'ros__parameters']
    settings = {f'setpoint.{k}': v for k, v in hw['setpoint'].items()}
    settings.update({'hold_radius': hw['hold_radius'], 'resume_radius': hw['resume_radius'],
                     'setpoint.detour_after_s': detour_after_s})
    robot, goal = np.array([-0.130, 0.199]), (-0.238, -0.239)
    brain = make_brain(agent_id=2, agent_type=2, initial_position=robot, external_pose=True,
                       robot_types_file=str(hil.bridge_config('hw_robot_types.yaml')),
                       settings=settings)
    brain.set_shape(Shape('square', box(-1.0, -1.0, 1.0, 1.0)), 1)
    brain.set_goals([Goal(2, 2, *goal, 0.11)], 1)
    offsets = np.array([[0.026, -0.021], [-0.316, 0.239]]) - robot
    commands = []
    for step in range(int(seconds / DT) + 1):
        t = step * DT
        brain.localizer.position[:] = robot
        brain.localizer.velocity[:] = 0.0
        brain.on_proximity(t, offsets, [0.16, 0.08])
        out = brain.step(t)
        if step % 25 == 0 and t >= 2.0:
            commands.append(out.velocity_setpoint.copy())
    return brain, np.array(commands), offsets / np.linalg.norm(offsets, axis=1)[:, None]


def test_a_brain_held_far_from_its_goal_goes_round_after_detour_after_s():
    """Held (its command under a quarter of its 3.5 cm/s setpoint) from the first
    assignment at 2 s, it plans round at 4 s and drives out of the pocket from the next
    outer tick at 3.5 cm/s, closing on neither neighbour; with detour_after_s 0 (the
    simulation's default) it stays held."""
    brain, commands, towards = _held_in_the_pocket(2.0, 8.0)
    v_max = brain.config.setpoint.v_max
    speeds = np.linalg.norm(commands, axis=1)
    assert speeds[:5].max() < 0.25 * v_max                       # 2.0-4.0 s: held
    assert speeds[6:].min() > 0.9 * v_max                       # from 5 s: going round
    assert (commands[6:] @ towards.T).max() <= 1e-9
    assert brain._detour.active and 'went round 1 times' in brain.status_line()
    brain, commands, _ = _held_in_the_pocket(0.0, 8.0)
    assert np.linalg.norm(commands, axis=1).max() < 0.25 * v_max
    assert 'went round 0 times' in brain.status_line()
