"""mission_node in-process: a smooth shape change (``morph``) publishes moved goals."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

rclpy = pytest.importorskip('rclpy')

from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile  # noqa: E402
from spin import ros_context, spin_until  # noqa: E402

from swarm_common import qos  # noqa: E402
from swarm_common.conversions import goals_from_msg  # noqa: E402
from swarm_common.shapes import ShapeError  # noqa: E402
from swarm_mission.mission_node import MissionNode  # noqa: E402
from swarm_msgs.msg import GoalArray  # noqa: E402


def _params(**extra) -> list[Parameter]:
    values = {'shape': 'circle_314', 'type_counts': '1:3,2:2', 'seed': 1, **extra}
    return [Parameter(name, value=value) for name, value in values.items()]


@pytest.mark.parametrize(('remesh', 'same_ids'), [('incremental', True), ('scratch', False)])
def test_a_morph_moves_the_goals_step_by_step(remesh, same_ids):
    with ros_context() as (context, executor):
        mission = MissionNode(context=context, parameter_overrides=_params(
            morph='move:4@0.5+2/2', remesh=remesh))
        probe = rclpy.create_node('probe', context=context)
        got: dict[int, GoalArray] = {}
        probe.create_subscription(GoalArray, '/swarm/goals',
                                  lambda m: got.setdefault(m.version, m),
                                  QoSProfile(**{**qos.LATCHED, 'depth': 10}))
        executor.add_node(mission)
        executor.add_node(probe)
        try:
            assert spin_until(executor, lambda: 3 in got, timeout=20.0), sorted(got)
        finally:
            mission.destroy_node()
            probe.destroy_node()
    goals = {v: sorted(goals_from_msg(got[v]), key=lambda g: g.id) for v in (1, 2, 3)}
    assert [got[v].shape_version for v in (1, 2, 3)] == [1, 2, 3]
    # The circle (radius 10 m, centred on the origin) moves 2 m along x per step: every
    # goal lies inside the circle in force, inside the 0.6 m formation margin.
    for v in (1, 2, 3):
        centre = np.array([2.0 * (v - 1), 0.0])
        assert all(np.hypot(*(np.array([g.x, g.y]) - centre)) < 10.0 - 0.6 for g in goals[v])
    if same_ids:
        # Incremental: every goal keeps its id and moves with the shape.
        assert [g.id for g in goals[3]] == [g.id for g in goals[1]]
        for k in range(len(goals[1])):
            assert goals[2][k].x - goals[1][k].x == pytest.approx(2.0, abs=1.0)
            assert goals[3][k].x - goals[1][k].x == pytest.approx(4.0, abs=1.0)
    else:
        # Scratch: a fresh partition of each moved circle (mean shift about 2 m a step).
        xs = [np.mean([g.x for g in goals[v]]) for v in (1, 2, 3)]
        assert xs[2] - xs[0] > 2.0


def test_morph_and_sequence_file_together_are_refused(tmp_path):
    sequence = tmp_path / 'seq.yaml'
    sequence.write_text('sequence: [{time: 0, shape: circle_314}]\n')
    with ros_context() as (context, _):
        with pytest.raises(ShapeError, match='sequence_file or morph, not both'):
            MissionNode(context=context, parameter_overrides=_params(
                morph='move:4@0.5+1', sequence_file=str(sequence)))


def test_fleet_beacons_get_beacon_goals_on_the_wire(tmp_path):
    """On a 20 m x 38 m chevron, longer than 0.9 x 25 m of radio, the fleet file's beacons
    (two of type 1, one of type 2, one of type 3) get as many beacon goals of their
    types, published in GoalState.beacon."""
    shape = tmp_path / 'chevron.json'
    shape.write_text(json.dumps({'outer': [[0, 0], [10, 8], [20, 0], [20, 30], [10, 38],
                                           [0, 30], [6, 19]]}))
    fleet = tmp_path / 'fleet.yaml'
    types = [1] * 6 + [2] * 6 + [3] * 4
    robots = [{'id': i, 'type': t, 'beacon': i in (0, 1, 6, 12), 'x': float(i), 'y': -5.0}
              for i, t in enumerate(types)]
    fleet.write_text(yaml.safe_dump({'robots': robots}))
    with ros_context() as (context, executor):
        mission = MissionNode(context=context, parameter_overrides=_params(
            shape=str(shape), fleet_file=str(fleet)))
        probe = rclpy.create_node('probe', context=context)
        got: list[GoalArray] = []
        probe.create_subscription(GoalArray, '/swarm/goals', got.append,
                                  QoSProfile(**qos.LATCHED))
        executor.add_node(mission)
        executor.add_node(probe)
        try:
            assert spin_until(executor, lambda: bool(got), timeout=20.0)
        finally:
            mission.destroy_node()
            probe.destroy_node()
    goals = goals_from_msg(got[-1])
    assert len(goals) == 16
    assert sorted(g.type for g in goals if g.beacon) == [1, 1, 2, 3]
    assert [g.beacon for g in goals] == [g.beacon for g in mission.mission.goals]


def test_a_restarted_mission_node_publishes_the_shape_set_at_run_time_again(tmp_path):
    """A shape set through the service, then the node dies and a new one starts with the
    same state_file and run_id: it publishes that shape and the very goals under the same
    versions (the agents keep their assignment). A new run_id starts from the parameters."""
    from swarm_common.conversions import shape_to_msg
    from swarm_common.shapes import load_shape
    from swarm_msgs.msg import FormationShape
    from swarm_msgs.srv import SetShape

    state = tmp_path / 'mission_state.json'

    def run(run_id: str, set_shape: bool) -> tuple[FormationShape, GoalArray]:
        with ros_context() as (context, executor):
            mission = MissionNode(context=context, parameter_overrides=_params(
                state_file=str(state), run_id=run_id))
            probe = rclpy.create_node('probe', context=context)
            shapes: list[FormationShape] = []
            goals: list[GoalArray] = []
            probe.create_subscription(FormationShape, '/swarm/shape', shapes.append,
                                      QoSProfile(**qos.LATCHED))
            probe.create_subscription(GoalArray, '/swarm/goals', goals.append,
                                      QoSProfile(**qos.LATCHED))
            executor.add_node(mission)
            executor.add_node(probe)
            try:
                # Shape and goals are two topics: either may arrive first.
                assert spin_until(executor, lambda: bool(goals) and bool(shapes), timeout=20.0)
                if set_shape:
                    client = probe.create_client(SetShape, '/swarm/set_shape')
                    request = SetShape.Request(shape=shape_to_msg(
                        load_shape('thesis_shape_1'), 0))
                    future = client.call_async(request)
                    assert spin_until(executor, future.done, timeout=20.0)
                    assert future.result().success, future.result().message
                    assert spin_until(executor, lambda: goals[-1].version == 2
                                      and shapes[-1].version == 2, timeout=20.0)
            finally:
                mission.destroy_node()
                probe.destroy_node()
        return shapes[-1], goals[-1]

    shape_before, goals_before = run('run-a', set_shape=True)
    shape_after, goals_after = run('run-a', set_shape=False)
    assert (shape_after.version, goals_after.version) == (2, 2)
    assert shape_after.name == shape_before.name
    assert goals_from_msg(goals_after) == goals_from_msg(goals_before)
    shape_new_run, goals_new_run = run('run-b', set_shape=False)
    assert (shape_new_run.version, goals_new_run.version) == (1, 1)
    assert shape_new_run.name == 'circle_314'


def test_liveness_heard_before_the_simulated_clock_does_not_lose_every_agent():
    """A mission node on simulated time that hears mission/alive before its first /clock
    (a respawned node under load) must not stamp those reports at time 0: when the clock
    then reads 10 s, every agent would look silent for 10 s (> agent_timeout_s 6 s), be
    declared lost, be heard again and the shape re-partitioned (goals v2). The goals stay
    v1 and no agent is lost."""
    from builtin_interfaces.msg import Time
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Int32MultiArray

    with ros_context() as (context, executor):
        mission = MissionNode(context=context, parameter_overrides=_params() + [
            Parameter('use_sim_time', value=True)])
        probe = rclpy.create_node('probe', context=context)
        alive = probe.create_publisher(Int32MultiArray, '/mission/alive',
                                       QoSProfile(**qos.STATE))
        clock = probe.create_publisher(Clock, '/clock', 10)
        goals: list[GoalArray] = []
        probe.create_subscription(GoalArray, '/swarm/goals', goals.append,
                                  QoSProfile(**qos.LATCHED))
        heard: list[Int32MultiArray] = []   # the probe's copies: delivered to the node too
        probe.create_subscription(Int32MultiArray, '/mission/alive', heard.append,
                                  QoSProfile(**qos.STATE))
        executor.add_node(mission)
        executor.add_node(probe)
        agents = sorted(mission.mission.agent_types)
        try:
            assert spin_until(executor, lambda: bool(goals), timeout=20.0)
            # Reports before any clock, delivered to the node.
            assert spin_until(executor, lambda: alive.get_subscription_count() > 1
                              and clock.get_subscription_count() > 0, timeout=20.0)
            for k in range(5):
                alive.publish(Int32MultiArray(data=agents))
                assert spin_until(executor, lambda k=k: len(heard) > k, timeout=20.0)
            assert mission._now() == 0.0
            # The simulator's clock arrives at 10 s and runs on; the agents keep reporting.
            for k in range(8):
                now = 10.0 + 0.5 * k
                clock.publish(Clock(clock=Time(sec=int(now), nanosec=int(now % 1 * 1e9))))
                assert spin_until(executor, lambda now=now: mission._now() >= now, timeout=20.0)
                spin_until(executor, lambda: False, timeout=0.1)   # the node's timer
                alive.publish(Int32MultiArray(data=agents))
                assert spin_until(executor, lambda k=k: len(heard) > 5 + k, timeout=20.0)
        finally:
            mission.destroy_node()
            probe.destroy_node()
    assert not [e for e in mission.mission.events if 'lost' in e], mission.mission.events
    assert mission.mission.goal_version == 1 and goals[-1].version == 1
