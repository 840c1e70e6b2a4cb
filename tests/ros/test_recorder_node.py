"""recorder_node in-process: two topics of the swarm recorded into an MCAP bag and read
back field by field; sim-time log times; a latched goal list published before the
recorder started is recorded too; a bad parameter is one line and exit 2."""

from __future__ import annotations

import pathlib
import subprocess
import sys

import pytest

rclpy = pytest.importorskip('rclpy')

from builtin_interfaces.msg import Time  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from spin import ros_context, spin_until  # noqa: E402

from swarm_bringup.bag import read_messages  # noqa: E402
from swarm_bringup.recorder_node import RecorderNode  # noqa: E402
from swarm_common import qos  # noqa: E402
from swarm_msgs.msg import AgentState, GoalArray, GoalState  # noqa: E402

SIM_START_S = 42   # the sim time on /clock while the test publishes


def _state(k: int) -> AgentState:
    msg = AgentState(id=3, type=2, mode=AgentState.MODE_LOST, assigned_goal=k,
                     goal_version=4, assignment_digest=0xDEADBEEF, localized=True)
    msg.header.frame_id = 'map'
    msg.header.stamp = Time(sec=SIM_START_S, nanosec=k)
    msg.position = [1.5 + k, -2.25]
    msg.covariance = [float(i) for i in range(16)]
    return msg


def test_two_topics_are_recorded_and_read_back(tmp_path: pathlib.Path):
    bag = tmp_path / 'run.mcap'
    goals = GoalArray(version=2, shape_version=1, method='bubble', goals=[
        GoalState(id=0, type=1, x=1.0, y=2.0, radius=0.15),
        GoalState(id=1, type=3, x=-4.5, y=0.5, radius=0.5, beacon=True)])
    with ros_context() as (context, executor):
        pub = rclpy.create_node('publisher', context=context)
        clock = pub.create_publisher(Clock, '/clock', 10)
        goals_pub = pub.create_publisher(GoalArray, '/swarm/goals', QoSProfile(**qos.LATCHED))
        state_pub = pub.create_publisher(AgentState, '/agent_3/state',
                                         QoSProfile(**qos.STATE))
        goals_pub.publish(goals)   # before the recorder exists: latched
        recorder = RecorderNode(context=context, parameter_overrides=[
            Parameter('output', value=str(bag)), Parameter('use_sim_time', value=True),
            Parameter('discovery_period_s', value=0.1),
            Parameter('topics', value=['/swarm/goals', '/agent_3/state', '/clock'])])
        executor.add_node(pub)
        executor.add_node(recorder)
        sim_time = Clock(clock=Time(sec=SIM_START_S))
        try:
            assert spin_until(executor, lambda: len(recorder.subscriptions_by_topic) == 3,
                              timeout=20.0), recorder.subscriptions_by_topic
            assert recorder.skipped == set()
            # The recorder's clock follows /clock before the states are sent.
            assert spin_until(executor, lambda: (
                clock.publish(sim_time) or
                recorder.get_clock().now().nanoseconds >= SIM_START_S * 10**9), timeout=20.0)
            sent = 0

            def publish_and_count() -> bool:
                nonlocal sent
                if sent < 5:
                    state_pub.publish(_state(sent))
                    sent += 1
                # The latched goals arrive at some point after the subscription.
                return recorder.bag.counts.get('/agent_3/state', 0) >= 5 and \
                    recorder.bag.counts.get('/swarm/goals', 0) >= 1

            assert spin_until(executor, publish_and_count, timeout=20.0), recorder.bag.counts
            assert recorder.bag.counts['/swarm/goals'] == 1
        finally:
            recorder.close()
            recorder.destroy_node()
            pub.destroy_node()
    records = list(read_messages(bag))
    assert {(topic, kind) for topic, kind, _, _ in records} == {
        ('/swarm/goals', 'swarm_msgs/msg/GoalArray'), ('/clock', 'rosgraph_msgs/msg/Clock'),
        ('/agent_3/state', 'swarm_msgs/msg/AgentState')}
    (recorded_goals,) = [msg for topic, _, _, msg in records if topic == '/swarm/goals']
    states = [(t, msg) for topic, _, t, msg in records if topic == '/agent_3/state']
    assert (recorded_goals.version, recorded_goals.method) == (2, 'bubble')
    assert [(g.id, g.type, g.x, g.y, g.radius, g.beacon) for g in recorded_goals.goals] == [
        (0, 1, 1.0, 2.0, 0.15, False), (1, 3, -4.5, 0.5, 0.5, True)]
    assert len(states) == 5
    for k, (log_time, state) in enumerate(states):
        assert log_time >= SIM_START_S * 10**9   # sim time, not wall time (~1.7e18 ns)
        assert log_time < (SIM_START_S + 1) * 10**9
        expected = _state(k)
        for field in ('id', 'type', 'mode', 'assigned_goal', 'goal_version',
                      'assignment_digest', 'localized', 'is_beacon', 'settled'):
            assert getattr(state, field) == getattr(expected, field), field
        assert list(state.position) == list(expected.position)
        assert list(state.covariance) == list(expected.covariance)
        assert (state.header.frame_id, state.header.stamp.nanosec) == ('map', k)


@pytest.mark.parametrize(('args', 'names'), [
    ([], 'parameter output is empty'),
    (['-p', 'output:=/nonexistent/dir/run.mcap'], '/nonexistent/dir'),
    (['-p', 'output:=/tmp/x.mcap', '-p', 'topics:=[agent_0/state]'], "'agent_0/state'"),
    (['-p', 'output:=/tmp/x.mcap', '-p', 'flush_period_s:=0.0'], 'flush_period_s'),
])
def test_a_bad_parameter_is_one_line_and_exit_2(args, names):
    proc = subprocess.run([sys.executable, '-m', 'swarm_bringup.recorder_node', '--ros-args',
                           *args], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert 'Traceback' not in proc.stderr + proc.stdout
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and names in lines[0], proc.stderr


@pytest.mark.parametrize('stop', ['SIGINT', 'SIGKILL'])
def test_a_stopped_recorder_leaves_a_readable_bag(processes, tmp_path: pathlib.Path, stop,
                                                 caplog):
    """Ctrl-C (the launcher's stop) closes the bag with its summary; a SIGKILLed
    recorder leaves what it flushed (every wall second) readable, and the reader says in
    one line that the bag was cut."""
    import logging
    import signal
    import time

    from mcap.reader import make_reader

    bag = tmp_path / 'run.mcap'
    proc = processes.python('-m', 'swarm_bringup.recorder_node', '--ros-args',
                            '-p', f'output:={bag}', '-p', 'topics:=[/agent_0/state]',
                            '-p', 'discovery_period_s:=0.2',
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    with ros_context() as (context, executor):
        pub = rclpy.create_node('publisher', context=context)
        state_pub = pub.create_publisher(AgentState, '/agent_0/state', QoSProfile(**qos.STATE))
        executor.add_node(pub)
        try:
            # Until the recorder listens, then 3 s more (three flushes) at 20 Hz.
            assert spin_until(executor, lambda: state_pub.get_subscription_count() > 0,
                              timeout=30.0)
            sent = 0
            published_at: list[float] = []

            def publish() -> bool:
                nonlocal sent
                if sent < 60:
                    state_pub.publish(_state(sent))
                    published_at.append(time.monotonic())
                    sent += 1
                return sent >= 60

            spin_until(executor, publish, timeout=60.0, step=0.05)
            # A message sent last is delivered before the signal.
            spin_until(executor, lambda: False, timeout=0.5)
            stopped_at = time.monotonic()
            proc.send_signal(getattr(signal, stop))
            output, _ = proc.communicate(timeout=30)
        finally:
            pub.destroy_node()
    with caplog.at_level(logging.WARNING, logger='swarm_bringup.bag'):
        recorded = [msg.assigned_goal for topic, _, _, msg in read_messages(bag)]
    cut_lines = [r.getMessage() for r in caplog.records if 'was cut' in r.getMessage()]
    if stop == 'SIGINT':
        assert proc.returncode == 0 and 'Traceback' not in output, output
        assert not cut_lines
        assert recorded == list(range(60))   # reliable, depth 10: none lost on localhost
        with open(bag, 'rb') as f:
            assert make_reader(f).get_summary().statistics.message_count == 60
    else:
        # The chunks flushed by the last full wall second: at least the first 20 (1 s at
        # 20 Hz), in order, and nothing made up.
        assert len(recorded) >= 20 and recorded == list(range(len(recorded))), recorded
        # All but the last seconds: every message published more than a flush period
        # (1 s) plus the flush timer's period and delivery slack (1 s) before the kill.
        old_enough = sum(t < stopped_at - 2.0 for t in published_at)
        assert len(recorded) >= old_enough, (len(recorded), old_enough)
        assert len(cut_lines) == 1 and cut_lines[0].startswith(
            f'bag {bag} was cut (its recorder was killed): {len(recorded)} messages up to')
