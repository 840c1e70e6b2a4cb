"""The bag writer (swarm_bringup.bag): ROS 2 messages in an MCAP bag that standard tools
read, written chunk by chunk so that a killed recorder leaves a readable bag.

Messages are serialized by mcap-ros2-support from the bag's own schema (the CDR bytes a
publisher sends) and read back with its decoder, field by field, without ROS.
"""

from __future__ import annotations

import logging
import pathlib

from bag_fixtures import cdr, FakeClock
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import pytest

from swarm_bringup.bag import (
    BagError,
    BagWriter,
    canonical_type,
    message_definition,
    nested_types,
    read_messages,
    SEPARATOR,
)

pytest.importorskip('ament_index_python')
try:
    message_definition('swarm_msgs/msg/AgentState')
except BagError:
    pytest.skip('swarm_msgs is not installed (make bootstrap)', allow_module_level=True)


HEADER = {'stamp': {'sec': 12, 'nanosec': 500_000_000}, 'frame_id': 'map'}
STATE = {'header': HEADER, 'id': 3, 'type': 2, 'is_beacon': True, 'mode': 1,
         'position': [1.5, -2.25], 'velocity': [0.125, 0.0],
         'covariance': [float(k) for k in range(16)], 'assigned_goal': 7,
         'goal_version': 4, 'assignment_round': 9, 'assignment_digest': 0xDEADBEEF,
         'rows_used': 8, 'settled': False, 'localized': True}
GOALS = {'header': HEADER, 'version': 2, 'shape_version': 1, 'method': 'bubble',
         'goals': [{'id': 0, 'type': 1, 'x': 1.0, 'y': 2.0, 'radius': 0.15, 'beacon': False},
                   {'id': 1, 'type': 3, 'x': -4.5, 'y': 0.5, 'radius': 0.5, 'beacon': True}]}
TWIST = {'linear': {'x': 0.25, 'y': -0.5, 'z': 0.0},
         'angular': {'x': 0.0, 'y': 0.0, 'z': 1.25}}


def same(decoded, expected) -> None:
    """Every field of ``expected`` (nested dicts and lists too) equals the decoded one."""
    for name, value in expected.items():
        got = getattr(decoded, name)
        if isinstance(value, dict):
            same(got, value)
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            assert len(got) == len(value), name
            for g, v in zip(got, value):
                same(g, v)
        elif isinstance(value, list):
            assert list(got) == value, name
        else:
            assert got == value, name


def test_nested_definitions_follow_the_root_once_each():
    text = message_definition('geometry_msgs/msg/PoseStamped')
    parts = text.split(SEPARATOR + '\n')
    assert 'Header header' in parts[0] and 'Pose pose' in parts[0]
    names = [p.splitlines()[0] for p in parts[1:]]
    assert names == ['MSG: std_msgs/msg/Header', 'MSG: builtin_interfaces/msg/Time',
                     'MSG: geometry_msgs/msg/Pose', 'MSG: geometry_msgs/msg/Point',
                     'MSG: geometry_msgs/msg/Quaternion']


def test_nested_types_of_a_msg_text():
    text = ('# comment Foo bar\nHeader header\nint32 A=1\nPoint[] points\n'
            'geometry_msgs/Twist[<=3] twists\nstring<=8 name\nfloat64[4] cov\n')
    assert nested_types(text, 'geometry_msgs') == [
        'std_msgs/msg/Header', 'geometry_msgs/msg/Point', 'geometry_msgs/msg/Twist']


def test_a_type_without_an_installed_definition_is_named():
    with pytest.raises(BagError, match='no_such_pkg is not installed'):
        message_definition('no_such_pkg/msg/Thing')
    with pytest.raises(BagError, match='package/msg/Type'):
        canonical_type('Twist')


def test_round_trip_of_swarm_and_geometry_messages(tmp_path: pathlib.Path):
    path = tmp_path / 'run.mcap'
    with BagWriter(path) as bag:
        bag.add_topic('/agent_3/state', 'swarm_msgs/msg/AgentState')
        bag.add_topic('/agent_3/cmd_vel', 'geometry_msgs/Twist')
        bag.add_topic('/swarm/goals', 'swarm_msgs/msg/GoalArray')
        bag.write('/swarm/goals', cdr('swarm_msgs/msg/GoalArray', GOALS), 0)
        for k in range(3):
            bag.write('/agent_3/state', cdr('swarm_msgs/msg/AgentState', STATE),
                      log_time_ns=1_000_000_000 * k)
            bag.write('/agent_3/cmd_vel', cdr('geometry_msgs/msg/Twist', TWIST),
                      log_time_ns=1_000_000_000 * k + 5, publish_time_ns=7)
    got = list(read_messages(path))
    assert [(t, n, lt) for t, n, lt, _ in got] == [
        ('/swarm/goals', 'swarm_msgs/msg/GoalArray', 0)] + [
        (topic, kind, 1_000_000_000 * k + extra) for k in range(3)
        for topic, kind, extra in (('/agent_3/state', 'swarm_msgs/msg/AgentState', 0),
                                   ('/agent_3/cmd_vel', 'geometry_msgs/msg/Twist', 5))]
    same(got[0][3], GOALS)
    for _, kind, _, decoded in got[1:]:
        same(decoded, STATE if kind.endswith('AgentState') else TWIST)


def test_a_closed_bag_has_the_ros2_profile_schemas_and_summary(tmp_path: pathlib.Path):
    path = tmp_path / 'run.mcap'
    with BagWriter(path) as bag:
        bag.add_topic('/a/cmd_vel', 'geometry_msgs/msg/Twist')
        bag.add_topic('/b/cmd_vel', 'geometry_msgs/msg/Twist')
        bag.write('/a/cmd_vel', cdr('geometry_msgs/msg/Twist', TWIST), 10)
        bag.write('/b/cmd_vel', cdr('geometry_msgs/msg/Twist', TWIST), 20)
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        assert summary.statistics.message_count == 2
        assert len(summary.schemas) == 1   # one schema per type
        (schema,) = summary.schemas.values()
        assert (schema.name, schema.encoding) == ('geometry_msgs/msg/Twist', 'ros2msg')
        assert {c.topic: c.message_encoding for c in summary.channels.values()} == {
            '/a/cmd_vel': 'cdr', '/b/cmd_vel': 'cdr'}
        msgs = list(reader.iter_decoded_messages())
    assert [m[3].angular.z for m in msgs] == [1.25, 1.25]


def test_an_unclosed_bag_is_readable_up_to_its_last_flush(tmp_path: pathlib.Path, caplog):
    """A recorder killed (no close) leaves every message of the chunks flushed before."""
    clock = FakeClock()
    path = tmp_path / 'run.mcap'
    bag = BagWriter(path, flush_period_s=1.0, clock=clock)
    bag.add_topic('/cmd_vel', 'geometry_msgs/msg/Twist')
    data = cdr('geometry_msgs/msg/Twist', TWIST)
    for k in range(10):              # 10 messages over 0.9 s: none flushed yet
        clock.now = 0.1 * k
        bag.write('/cmd_vel', data, k)
    assert bag.unflushed == 10
    clock.now = 1.0                  # the 11th, at 1 s: flushes the chunk of all 11
    bag.write('/cmd_vel', data, 10)
    assert bag.unflushed == 0
    first_flush = path.stat().st_size
    for k in range(11, 15):          # 4 more, not flushed: lost if killed now
        bag.write('/cmd_vel', data, k)
    # Not closed: the file holds what the last flush wrote, nothing of the open chunk.
    assert [lt for _, _, lt, _ in read_messages(path)] == list(range(11))
    clock.now = 1.5                  # the recorder's timer: nothing due before 2 s
    assert not bag.flush_if_due()
    clock.now = 2.0
    assert bag.flush_if_due()
    assert [lt for _, _, lt, _ in read_messages(path)] == list(range(15))
    # Killed while writing the second chunk: the first one still reads.
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(path.read_bytes()[:(first_flush + path.stat().st_size) // 2])
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        assert [lt for _, _, lt, _ in read_messages(cut)] == list(range(11))
    # One line says the bag was cut and what it holds (log times 0..10 ns here).
    assert [r.getMessage() for r in caplog.records] == [
        f'bag {cut} was cut (its recorder was killed): 11 messages up to t=0.0 s read']
    # A tail cut mid-record (killed while writing) is dropped; the rest still reads.
    size = path.stat().st_size
    with open(path, 'ab') as f:
        f.write(b'\x06' + b'\xff' * 20)
    assert path.stat().st_size > size
    assert [lt for _, _, lt, _ in read_messages(path)] == list(range(15))
    bag.close()
    caplog.clear()
    with caplog.at_level(logging.WARNING):   # closed (footer written): not cut
        assert [lt for _, _, lt, _ in read_messages(path)] == list(range(15))
    assert not caplog.records


def test_bad_use_is_refused_in_one_line(tmp_path: pathlib.Path):
    with pytest.raises(BagError, match='does not exist'):
        BagWriter(tmp_path / 'missing' / 'run.mcap')
    with pytest.raises(BagError, match='above 0 s'):
        BagWriter(tmp_path / 'run.mcap', flush_period_s=0.0)
    with BagWriter(tmp_path / 'run.mcap') as bag:
        bag.add_topic('/x', 'geometry_msgs/msg/Twist')
        bag.add_topic('/x', 'geometry_msgs/msg/Twist')   # the same again: fine
        with pytest.raises(BagError, match='recorded as geometry_msgs/msg/Twist'):
            bag.add_topic('/x', 'geometry_msgs/msg/Point')
        with pytest.raises(BagError, match='not registered'):
            bag.write('/y', b'', 0)
    with pytest.raises(BagError, match='closed'):
        bag.write('/x', b'', 0)


def test_the_recording_qos_is_the_swarm_profile_made_compatible():
    from swarm_bringup.bag import DEFAULT_QOS, recording_qos
    from swarm_common import qos

    # Latched shape and goals: transient local, so the recorder gets the current ones.
    assert recording_qos('/swarm/goals') == qos.LATCHED
    assert recording_qos('/swarm/shape', [(qos.RELIABLE, qos.TRANSIENT_LOCAL)]) == \
        qos.LATCHED
    assert recording_qos('/agent_7/radio/rx') == qos.RADIO
    assert recording_qos('/agent_7/state')['depth'] == qos.STATE['depth']
    assert recording_qos('/state') == DEFAULT_QOS   # not a swarm topic
    # One best-effort or volatile publisher among others: what every one can match.
    mixed = recording_qos('/swarm/goals', [(qos.RELIABLE, qos.TRANSIENT_LOCAL),
                                           (qos.BEST_EFFORT, qos.VOLATILE)])
    assert (mixed['reliability'], mixed['durability']) == (qos.BEST_EFFORT, qos.VOLATILE)
    # A reliable transient-local publisher of a topic the swarm does not know (/rosout).
    rosout = recording_qos('/rosout', [(qos.RELIABLE, qos.TRANSIENT_LOCAL)])
    assert (rosout['reliability'], rosout['durability']) == (qos.RELIABLE,
                                                             qos.TRANSIENT_LOCAL)


def test_an_hour_of_chunks_holds_little_memory_and_reads_in_time_order(tmp_path):
    """The writer keeps one chunk index per flushed chunk for the summary; with one
    message index offset per topic in each (223 topics in a 50-agent run) that was 16 kB
    a chunk, 58 MiB after an hour of one-second chunks. The bag carries no message
    indexes, so a chunk index is a few hundred bytes, and readers still get every
    message in time order from the chunks."""
    import tracemalloc

    clock = FakeClock()
    topics = [f'/agent_{k}/cmd_vel' for k in range(223)]
    data = cdr('geometry_msgs/msg/Twist', TWIST)
    path = tmp_path / 'run.mcap'
    with BagWriter(path, flush_period_s=1.0, clock=clock) as bag:
        for topic in topics:
            bag.add_topic(topic, 'geometry_msgs/msg/Twist')

        def chunks(first: int, count: int) -> None:
            for second in range(first, first + count):
                clock.now = float(second)
                for k, topic in enumerate(topics):
                    bag.write(topic, data, second * 1_000_000_000 + k)

        chunks(0, 20)
        tracemalloc.start()
        held = tracemalloc.take_snapshot()
        chunks(20, 200)
        grown = sum(s.size_diff for s in tracemalloc.take_snapshot().compare_to(held, 'filename'))
        tracemalloc.stop()
    assert grown / 200 < 1024, f'{grown / 200:.0f} bytes held per chunk'
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        times = [m.log_time for _, _, m in reader.iter_messages(log_time_order=True)]
    assert len(times) == 220 * 223 and times == sorted(times)
