"""Mission planner: versioning, sequences, self-repair (pure, no ROS)."""

import math

import numpy as np
import pytest

from swarm_common.robot_types import load_robot_types
from swarm_common.shapes import load_shape, ShapeError
from swarm_mission.mission import (
    load_sequence,
    Mission,
    MissionConfig,
    morph_sequence,
    parse_morph,
)

RADII = {t: r.coverage_radius for t, r in load_robot_types().items()}


def _mission(method='bubble', n=(4, 4, 2), remesh='incremental'):
    types = [1] * n[0] + [2] * n[1] + [3] * n[2]
    return Mission(MissionConfig(method=method, seed=3, agent_timeout_s=2.0, remesh=remesh),
                   agent_types=dict(enumerate(types)), radii=RADII)


def test_shape_is_versioned_and_partitioned_for_the_swarm():
    m = _mission()
    assert m.set_shape(load_shape('circle_314'))
    assert (m.shape_version, m.goal_version) == (1, 1)
    by_type = {t: sum(g.type == t for g in m.goals) for t in (1, 2, 3)}
    assert by_type == {1: 4, 2: 4, 3: 2}
    assert len({g.id for g in m.goals}) == len(m.goals)


def test_forces_method_needs_no_goals():
    m = _mission('forces')
    assert m.set_shape(load_shape('circle_314'))
    assert m.goals == [] and m.goal_version == 1


def test_silent_agents_are_declared_lost_and_survivors_repartitioned():
    m = _mission()
    m.set_shape(load_shape('circle_314'))
    for agent in m.agent_types:
        m.agent_seen(agent, 0.0)
    for agent in m.agent_types:
        if agent not in (0, 9):
            m.agent_seen(agent, 3.0)
    assert m.check_liveness(1.0) == []
    assert m.check_liveness(3.0) == [0, 9]
    assert m.goal_version == 2
    assert len(m.goals) == 8
    assert sum(g.type == 3 for g in m.goals) == 1
    assert m.check_liveness(3.5) == []
    # Agent 9 was only out of the mesh (behind an obstacle): heard again, it gets a goal.
    m.agent_seen(9, 4.0)
    assert m.check_liveness(4.0) == [] and 9 in m.alive and 9 not in m.lost
    assert m.goal_version == 3 and len(m.goals) == 9
    assert m.check_liveness(4.5) == [] and m.goal_version == 3


def test_sequence_file_is_read_and_validated(tmp_path):
    good = tmp_path / 'seq.yaml'
    good.write_text('sequence:\n  - {time: 0, shape: circle_314}\n'
                    '  - {time: 60, shape: table43_2}\n')
    steps = load_sequence(good)
    assert [s.time for s in steps] == [0.0, 60.0]
    assert steps[1].shape.name == 'table43_2'
    bad = tmp_path / 'bad.yaml'
    bad.write_text('sequence:\n  - {time: 10, shape: circle_314}\n  - {time: 5, shape: x}\n')
    with pytest.raises(ShapeError):
        load_sequence(bad)
    with pytest.raises(ShapeError, match='non-empty "sequence"'):
        empty = tmp_path / 'empty.yaml'
        empty.write_text('foo: 1\n')
        load_sequence(empty)


def test_smooth_changes_move_turn_and_grow_the_region_in_even_steps():
    base = load_shape('thesis_shape_1')
    c = base.centroid
    move = morph_sequence(base, 'move', 15.0, start=200.0, duration=60.0, steps=30)
    assert [s.time for s in move[:3]] == [200.0, 202.0, 204.0] and move[-1].time == 258.0
    shifts = [s.shape.centroid[0] - c[0] for s in move]
    assert np.allclose(np.diff(shifts), 0.5) and shifts[-1] == pytest.approx(15.0)
    turn = morph_sequence(base, 'rotate', 90.0, start=0.0, duration=10.0, steps=5)
    assert all(np.allclose(s.shape.centroid, c, atol=1e-9) for s in turn)
    assert turn[-1].shape.area == pytest.approx(base.area)
    # A quarter turn about the centroid maps the offset (dx, dy) of a vertex to (-dy, dx).
    x, y = np.asarray(base.region.exterior.coords[0]) - c
    assert turn[-1].shape.region.exterior.coords[0] == pytest.approx((c[0] - y, c[1] + x))
    grow = morph_sequence(base, 'grow', 0.3, start=0.0, duration=10.0, steps=3)
    assert [s.shape.area / base.area for s in grow] == pytest.approx(
        [1.1 ** 2, 1.2 ** 2, 1.3 ** 2])


def test_smooth_changes_leave_workspace_obstacles_in_place():
    base = load_shape('thesis_shape_1')   # four workspace obstacles
    moved = morph_sequence(base, 'move', 5.0, start=0.0, duration=4.0, steps=2)[-1].shape
    assert moved.obstacles == base.obstacles
    assert moved.centroid[0] == pytest.approx(base.centroid[0] + 5.0)


@pytest.mark.parametrize(('spec', 'says'), [
    ('spin:3@0+10', 'unknown shape change'), ('move:3@10', 'write KIND:AMOUNT@START'),
    ('grow:-1@0+10', 'above -1'), ('move:3@0+0', 'duration > 0'),
    ('move:nan@0+10', 'finite'), ('move:3@0+10/0', 'steps >= 1'),
    ('move:1,2,3@0+10', 'one or two finite numbers'), ('rotate:1,2@0+10', 'degrees')])
def test_bad_shape_changes_are_rejected_with_the_reason(spec, says):
    with pytest.raises(ShapeError, match=says):
        parse_morph(spec, load_shape('circle_314'))


def test_a_move_may_go_in_any_direction():
    base = load_shape('circle_314')
    steps = parse_morph('move:6,-8@0+4', base)
    assert steps[-1].shape.centroid == pytest.approx(base.centroid + [6.0, -8.0])
    assert steps[0].shape.centroid == pytest.approx(base.centroid + [3.0, -4.0])


def test_a_shape_change_spec_defaults_to_one_shape_per_consensus_period():
    steps = parse_morph('rotate:45@100+30', load_shape('circle_314'))
    assert len(steps) == 15 and steps[0].time == 100.0 and steps[-1].time == 128.0


def test_incremental_remesh_keeps_goal_ids_and_moves_goals_with_the_shape():
    base = load_shape('circle_314')
    m = _mission()
    m.set_shape(base)
    before = {g.id: (g.x, g.y) for g in m.goals}
    m.set_shape(base.translated(1.0, 0.0))
    after = {g.id: (g.x, g.y) for g in m.goals}
    assert set(after) == set(before)
    # Every goal follows the shape: about 1 m along x, none jumps across the formation.
    shift = np.array([np.subtract(after[i], before[i]) for i in before])
    assert np.median(shift[:, 0]) == pytest.approx(1.0, abs=0.3)
    assert np.max(np.hypot(*shift.T)) < 3.0


def test_scratch_remesh_partitions_the_changed_shape_anew():
    base, moved = load_shape('circle_314'), load_shape('circle_314').translated(1.0, 0.0)
    m = _mission(remesh='scratch')
    m.set_shape(base)
    m.set_shape(moved)
    fresh = _mission(remesh='scratch')
    fresh.set_shape(moved)
    assert [(g.id, g.type) for g in m.goals] == [(g.id, g.type) for g in fresh.goals]
    assert np.allclose([(g.x, g.y) for g in m.goals], [(g.x, g.y) for g in fresh.goals])
    assert not math.isclose(m.goals[0].x, _first_incremental_x(base, moved), abs_tol=1e-6)


def _first_incremental_x(base, moved):
    m = _mission()
    m.set_shape(base)
    m.set_shape(moved)
    return m.goals[0].x


def test_unknown_remesh_mode_is_rejected_naming_the_parameter():
    with pytest.raises(ShapeError, match='remesh'):
        MissionConfig(remesh='lazy')
