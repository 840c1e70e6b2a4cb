"""The mission node's state file (swarm_mission.mission_state): what a restarted node
resumes, and the files it must not resume."""

from __future__ import annotations

import json

import pytest

from swarm_common.shapes import load_shape, shape_from_rings
from swarm_mission import mission_state
from swarm_mission.mission import Mission, MissionConfig
from swarm_mission.mission_state import MissionState, MissionStateError

TYPES = {0: 1, 1: 1, 2: 2, 3: 2, 4: 3}
RADII = {1: 1.0, 2: 1.2, 3: 1.5}


def _mission() -> Mission:
    return Mission(MissionConfig(seed=3), agent_types=dict(TYPES), radii=RADII)


def test_a_resumed_mission_holds_the_same_shape_goals_versions_and_lost_agents(tmp_path):
    before = _mission()
    before.set_shape(load_shape('circle_314'))
    # A shape set at run time (the case a node restarted from its parameters loses),
    # with a hole and an obstacle so that every ring kind goes through the file.
    ring = shape_from_rings([[0, 0], [20, 0], [20, 15], [0, 15]], [[[8, 5], [12, 5], [12, 9]]],
                            [[[30, 30], [32, 30], [31, 33]]], name='set_at_run_time')
    before.set_shape(ring)
    before.agent_seen(4, 0.0)
    before.check_liveness(100.0)          # agent 4 silent for 100 s: lost, goals again
    assert before.lost == {4} and (before.shape_version, before.goal_version) == (2, 3)
    path = tmp_path / 'mission_state.json'
    mission_state.save(path, mission_state.capture(before, 'run-a', 2, 12.5))

    state = mission_state.load(path, 'run-a')
    after = _mission()
    mission_state.resume(after, state, 130.0)
    assert after.shape.name == 'set_at_run_time'
    assert after.shape.region.equals_exact(before.shape.region, 0.0)
    assert after.shape.obstacles[0].equals_exact(before.shape.obstacles[0], 0.0)
    assert after.goals == before.goals                       # the very goals, not a new
    assert (after.shape_version, after.goal_version) == (2, 3)   # partition
    assert after.lost == {4} and after.alive == {0, 1, 2, 3}
    assert (state.next_step, state.sequence_start) == (2, 12.5)
    # The lost agent heard again after the restart rejoins and the goals are made again.
    after.agent_seen(4, 131.0)
    after.check_liveness(131.5)
    assert after.lost == set() and after.goal_version == 4


def test_another_runs_state_is_not_resumed_and_no_file_is_no_state(tmp_path):
    path = tmp_path / 'mission_state.json'
    assert mission_state.load(path, 'run-a') is None
    mission_state.save(path, MissionState('run-a'))
    assert mission_state.load(path, 'run-b') is None
    assert mission_state.load(path, 'run-a') == MissionState('run-a')
    assert not (tmp_path / 'mission_state.json.tmp').exists()


@pytest.mark.parametrize(('text', 'words'), [
    ('{"format": 1, "run_id": "r", "shape"', 'is not valid JSON'),
    ('[1, 2]', 'is not a mission state file'),
    (json.dumps({'format': 99, 'run_id': 'r'}), 'is not a mission state file of format 1'),
    (json.dumps({'format': 1, 'run_id': 'r', 'shape': None, 'shape_version': 1,
                 'goals': [{'id': 0}], 'goal_version': 1, 'next_step': 0,
                 'sequence_start': None, 'lost': []}), 'broken mission state'),
    (json.dumps({'format': 1, 'run_id': 'r', 'shape': {'name': 'x', 'outer': [[0, 0]]},
                 'shape_version': 1, 'goals': [], 'goal_version': 1, 'next_step': 0,
                 'sequence_start': None, 'lost': []}), 'broken mission state'),
])
def test_a_broken_state_file_is_one_line_naming_the_file_and_the_fix(tmp_path, text, words):
    path = tmp_path / 'mission_state.json'
    path.write_text(text)
    with pytest.raises(MissionStateError) as raised:
        mission_state.load(path, 'r')
    message = str(raised.value)
    assert words in message and str(path) in message and '\n' not in message
