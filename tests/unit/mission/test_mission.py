"""Mission planner: versioning, sequences, self-repair (pure, no ROS)."""

import pytest

from swarm_mission.mission import load_sequence, Mission, MissionConfig
from swarm_mission.robot_types import load_robot_types
from swarm_mission.shapes import load_shape, ShapeError

RADII = {t: r.coverage_radius for t, r in load_robot_types().items()}


def _mission(method='bubble', n=(4, 4, 2)):
    types = [1] * n[0] + [2] * n[1] + [3] * n[2]
    return Mission(MissionConfig(method=method, seed=3, agent_timeout_s=2.0),
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
