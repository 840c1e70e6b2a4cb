"""sim_node's faults on command, its RViz markers and its batched command input.

Robots a few metres apart and no agents (the world is not held for them). Run-time
parameters, set by a parameter client as the launcher's: a range cut, packet loss and a
sweeping wall; the medium's links and drop counters follow, and bad values are refused
with the reason. Fault topics: a radio off and on, an obstacle moved (bodies and radio
shadow), bad commands ignored; the markers follow. A composed process's ForceBatch. The
proximity scans, per robot and in the sensor batch, and their parameters.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from rclpy.parameter import Parameter  # noqa: E402
from rclpy.parameter_client import AsyncParameterClient  # noqa: E402
from spin import sim_world, spin_until  # noqa: E402

from swarm_agent.packet import BROADCAST, Packet  # noqa: E402
from swarm_common.fleet import RobotSpec  # noqa: E402


def _world(tmp_path, robots, **params):
    """A SimNode over ``robots`` (RobotSpec) with a probe node, spun by one executor."""
    return sim_world(tmp_path, robots, 'fault_probe', **params)


THREE = [RobotSpec(0, 1, True, 0.0, 0.0), RobotSpec(1, 1, True, 6.0, 0.0),
         RobotSpec(2, 1, False, 12.0, 0.0)]


def _until(executor, condition, timeout=20.0):
    return spin_until(executor, condition, timeout, step=0.05)


def test_range_loss_and_wall_set_at_run_time_change_the_medium(tmp_path):
    with _world(tmp_path, THREE) as (executor, sim, probe):
        _check_run_time_settings(executor, sim, AsyncParameterClient(probe, 'sim'))


def _check_run_time_settings(executor, sim, client):

    def set_param(name, value):
        future = client.set_parameters([Parameter(name, value=value)])
        assert _until(executor, future.done), f'no answer setting {name}'
        return future.result().results[0]

    def broadcast(count):
        # Straight into the sim's medium (what its /radio/tx callback does per frame)
        for k in range(count):
            sim.world.medium.transmit(sim.world.t, Packet(source=1, destination=BROADCAST, kind=0,
                                              sequence=k, ttl=1, payload=b'hb'))

    assert _until(executor, client.services_are_ready)
    assert _until(executor, lambda: sim.world.t > 0.5)
    assert sorted(sim.world.medium.neighbours(1)) == [0, 2]
    assert set_param('radio_range_m', 5.0).successful
    assert _until(executor, lambda: sim.world.medium.neighbours(1) == [])  # links follow
    refused = set_param('radio_range_m', -1.0)     # outside its generated range
    assert not refused.successful and 'radio_range_m out of range' in refused.reason
    # A parameter the world reads once, at start, is read-only (generated from
    # MediumConfig with read_only): refused, the medium unchanged.
    refused = set_param('medium.latency_s', 0.5)
    assert not refused.successful and 'read-only' in refused.reason
    assert sim.world.medium.config.latency_s == 0.005
    assert sim.world.medium.config.range_m == 5.0
    assert set_param('radio_range_m', 25.0).successful
    assert _until(executor, lambda: sorted(sim.world.medium.neighbours(1)) == [0, 2])

    assert set_param('loss', 1.0).successful
    before = sim.world.medium.stats.dropped_loss
    broadcast(20)
    assert _until(executor, lambda: sim.world.medium.stats.dropped_loss == before + 2 * 20)
    assert not set_param('loss', 1.5).successful and sim.world.medium.config.loss == 1.0
    assert set_param('loss', 0.0).successful

    # A wall from x = -20 m at 5 m/s reaches the robots (x 0..12) within a few seconds
    # of sim time and cuts 0-1 and 1-2 while it stands between them.
    t0 = sim.world.t
    assert set_param('radio_wall_speed_mps', 5.0).successful
    # The wall starts when the sim applied the setting, which it kept stepping around.
    assert sim.world.medium.wall is not None and t0 <= sim.world.medium.wall.t0 <= sim.world.t
    assert _until(executor, lambda: len(sim.world.medium.neighbours(1)) < 2, timeout=30.0)
    assert _until(executor, lambda: sim.world.medium.wall is None, timeout=30.0)  # it left
    assert _until(executor, lambda: sorted(sim.world.medium.neighbours(1)) == [0, 2])


def test_radio_kill_and_obstacle_move_on_command_bad_commands_ignored(tmp_path):
    """The world's other faults: a robot's radio dies and comes back, an obstacle moves.

    Robots at x = 0, 6 and 12 m; a 2 m square wall at x 8..10 shadows the 1-2 link. On
    the pybullet backend the prism moves with the radio shadow. Unknown robots, unknown
    obstacles and malformed commands leave the world as it was, and it keeps stepping.
    """
    pytest.importorskip('pybullet')
    shape_file = tmp_path / 'shape.json'
    shape_file.write_text(json.dumps({
        'outer': [[-5, 5], [-5, 9], [-1, 9], [-1, 5]],
        'obstacles': [[[8, -1], [10, -1], [10, 1], [8, 1]]]}))
    with _world(tmp_path, THREE, backend='pybullet', terrain='flat',
                shape=str(shape_file)) as (executor, sim, probe):
        _check_radio_obstacle_and_markers(executor, sim, probe)


def _check_radio_obstacle_and_markers(executor, sim, probe):
    from rclpy.qos import QoSProfile
    from std_msgs.msg import Float64MultiArray, Int32MultiArray
    from visualization_msgs.msg import MarkerArray

    from swarm_common import qos
    from swarm_msgs.msg import AgentState

    radio_off = probe.create_publisher(Int32MultiArray, '/swarm/radio_off', 10)
    radio_on = probe.create_publisher(Int32MultiArray, '/swarm/radio_on', 10)
    move = probe.create_publisher(Float64MultiArray, '/swarm/move_obstacle', 10)
    state_pub = probe.create_publisher(AgentState, '/agent_2/state', QoSProfile(**qos.STATE))
    views = []
    probe.create_subscription(MarkerArray, '/swarm/markers', views.append,
                              QoSProfile(**qos.STATE))

    def wall_height_at(x, y):
        return float(sim.world.backend.ground_height([[x, y]])[0])

    assert _until(executor, lambda: sim.world.t > 0.5)
    assert sorted(sim.world.medium.neighbours(1)) == [0]     # the wall shadows 1-2
    assert wall_height_at(9.0, 0.0) > 0.5              # a prism stands there
    # Every command publisher matched before its first message: a volatile message sent
    # before discovery completes is lost (seen under load: radio_on unmatched).
    assert _until(executor, lambda: all(
        pub.get_subscription_count() > 0 for pub in (radio_off, radio_on, move, state_pub)))
    radio_off.publish(Int32MultiArray(data=[0, 99]))   # 99: not in the fleet
    assert _until(executor, lambda: sim.world.medium.neighbours(1) == [])
    assert sim.world.alive.all()                             # the robot stays in the world
    radio_on.publish(Int32MultiArray(data=[0]))
    assert _until(executor, lambda: sim.world.medium.neighbours(1) == [0])

    for bad in ([0.0, 1.0], [5.0, 0.0, 10.0], [0.5, 0.0, 10.0], [0.0, math.nan, 1.0]):
        move.publish(Float64MultiArray(data=bad))      # short, no obstacle 5, 0.5, NaN
    t_bad = sim.world.t
    assert _until(executor, lambda: sim.world.t > t_bad + 1.0)
    assert sorted(sim.world.medium.neighbours(1)) == [0] and wall_height_at(9.0, 0.0) > 0.5

    move.publish(Float64MultiArray(data=[0.0, 0.0, 10.0]))   # out of the way
    assert _until(executor, lambda: sorted(sim.world.medium.neighbours(1)) == [0, 2])
    assert wall_height_at(9.0, 0.0) < 0.1 and wall_height_at(9.0, 10.0) > 0.5
    assert sim.world.obstacles[0].centroid.y == pytest.approx(10.0)

    # The RViz view follows: the moved obstacle, the links, the mode agent 2 reports.
    state_pub.publish(AgentState(id=2, mode=AgentState.MODE_LOST))
    assert _until(executor, lambda: sim._modes.get(2) == AgentState.MODE_LOST)
    # A view drawn after the mode arrived (one drawn before may still be in flight).
    def drawn_after(t: float) -> list:
        return [v for v in views if _seconds(v.markers[0]) > t + 1e-6]

    t_mode = sim.world.t
    assert _until(executor, lambda: len(drawn_after(t_mode)) > 0)
    latest = {(m.ns, m.id): m for m in drawn_after(t_mode)[-1].markers}
    outline = latest[('obstacles', 0)]
    assert min(p.y for p in outline.points) == pytest.approx(9.0)
    assert len(latest[('links', 0)].points) == 2 * 3          # every pair, no wall
    assert latest[('modes', 2)].color.r == 1.0                # orange: lost

    # A removed robot leaves the medium, whose links then cover the living ones only:
    # the view still draws them between the right robots (1 at x = 6, 2 at x = 12).
    kill = probe.create_publisher(Int32MultiArray, '/swarm/kill', 10)
    assert _until(executor, lambda: kill.get_subscription_count() > 0)
    kill.publish(Int32MultiArray(data=[0]))
    assert _until(executor, lambda: not sim.world.alive[0])
    t_kill = sim.world.t
    assert _until(executor, lambda: len(drawn_after(t_kill)) > 0)
    lines = {(m.ns, m.id): m for m in drawn_after(t_kill)[-1].markers}[('links', 0)]
    assert sorted(round(p.x) for p in lines.points) == [6, 12]


def test_the_world_takes_a_composed_process_commands_in_one_batch(tmp_path):
    """sensor_batch: forces arrive as swarm_msgs/ForceBatch; a malformed one is dropped."""
    from rclpy.qos import QoSProfile

    from swarm_common import qos
    from swarm_msgs.msg import ForceBatch

    robots = [RobotSpec(0, 1, True, 0.0, 0.0), RobotSpec(1, 2, True, 6.0, 0.0)]
    with _world(tmp_path, robots, max_agent_lag_s=0.2,
                sensor_batch=True) as (executor, sim, probe):
        pub = probe.create_publisher(ForceBatch, '/swarm/cmd_batch',
                                     QoSProfile(**qos.COMMAND_BATCH))
        topics = {name for name, _ in probe.get_topic_names_and_types()}
        assert not any(t.endswith('/cmd_force') for t in topics), topics
        pub.publish(ForceBatch(ids=[0, 1], fx=[1.0, 0.0], fy=[0.0, -2.0], stamps=[0.0, 0.0]))
        assert _until(executor, lambda: sim.world.forces[1, 1] == -2.0)
        assert sim.world.forces[0].tolist() == [1.0, 0.0]
        assert sim.pacer.stamp.tolist() == [0.0, 0.0]
        # Both answered t = 0: the world steps (0.2 s ahead at most) and waits again.
        assert _until(executor, lambda: sim.world.t >= 0.2 - 1e-9)
        assert sim.world.t <= 0.2 + 1e-9
        pub.publish(ForceBatch(ids=[0, 1], fx=[5.0], fy=[0.0, 0.0], stamps=[0.2, 0.2]))
        pub.publish(ForceBatch(ids=[1, 7], fx=[3.0, 1.0], fy=[0.0, 0.0],
                               stamps=[math.nan, 0.2]))    # no stamp, no robot 7
        pub.publish(ForceBatch(ids=[0], fx=[0.5], fy=[0.5], stamps=[0.2]))
        assert _until(executor, lambda: sim.world.forces[0, 0] == 0.5)
        assert sim.world.forces[1].tolist() == [0.0, -2.0]       # the malformed ones were dropped
        assert np.isfinite(sim.pacer.stamp).all()


def _seconds(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def test_the_world_publishes_each_robots_proximity_scan(tmp_path):
    """/agent_K/proximity at proximity_rate_hz: robots 0 and 1 (2 m apart) see each other,
    robot 2 (10 m off) gets empty scans; a removed robot neither sees nor is seen."""
    from rclpy.qos import QoSProfile
    from std_msgs.msg import Int32MultiArray

    from swarm_agent.conversions import proximity_from_msg
    from swarm_common import qos
    from swarm_msgs.msg import ProximityArray

    robots = [RobotSpec(0, 1, True, 0.0, 0.0), RobotSpec(1, 3, True, 2.0, 0.0),
              RobotSpec(2, 1, False, 12.0, 0.0)]
    with _world(tmp_path, robots) as (executor, sim, probe):
        scans = {i: [] for i in range(3)}
        for i in range(3):
            probe.create_subscription(ProximityArray, f'/agent_{i}/proximity',
                                      scans[i].append, QoSProfile(**qos.SENSOR))
        assert _until(executor, lambda: all(len(s) >= 3 for s in scans.values()))
        radius = {r: sim.types[r].coverage_radius for r in (1, 3)}
        for i, (offset, seen_radius) in ((0, ((2.0, 0.0), radius[3])),
                                         (1, ((-2.0, 0.0), radius[1]))):
            msg = scans[i][-1]
            assert msg.receiver == i and msg.stddev == 0.02
            offsets, radii = proximity_from_msg(msg)
            np.testing.assert_allclose(offsets, [offset], atol=0.1)
            assert radii.tolist() == [seen_radius]
        assert all(len(m.x) == 0 and m.receiver == 2 for m in scans[2])
        # Scans are stamped at 10 Hz of sim time (best effort: one may be dropped).
        steps = np.diff([_seconds(m) for m in scans[0]]) / 0.1
        assert steps.min() > 0.5 and np.allclose(steps, np.round(steps), atol=1e-4)

        kill = probe.create_publisher(Int32MultiArray, '/swarm/kill', 10)
        assert _until(executor, lambda: kill.get_subscription_count() > 0)
        kill.publish(Int32MultiArray(data=[1]))
        assert _until(executor, lambda: not sim.world.alive[1])
        killed_at = sim.world.t

        def after(i):
            return [m for m in scans[i] if _seconds(m) > killed_at + 1e-6]

        assert _until(executor, lambda: len(after(0)) >= 3)
        assert not after(1) and all(len(m.x) == 0 for m in after(0))


def test_a_composed_world_sends_proximity_in_its_sensor_batch(tmp_path):
    """sensor_batch: the scans and the beacons' GPS travel in /swarm/sensor_batch, not on
    per-robot topics, and a batch goes with every /clock message (composed agents step
    on it)."""
    from rclpy.qos import QoSProfile
    from rosgraph_msgs.msg import Clock

    from swarm_agent.conversions import sensor_batch_from_msg
    from swarm_common import qos
    from swarm_msgs.msg import SensorBatch

    robots = [RobotSpec(0, 1, True, 0.0, 0.0), RobotSpec(1, 2, True, 0.0, 2.5)]
    with _world(tmp_path, robots, sensor_batch=True) as (executor, sim, probe):
        batches, clocks = [], []
        probe.create_subscription(SensorBatch, '/swarm/sensor_batch', batches.append,
                                  QoSProfile(**qos.RADIO))
        probe.create_subscription(Clock, '/clock', clocks.append, 100)
        assert _until(executor, lambda: sum(len(b.prox_ids) > 0 for b in batches) >= 2
                      and sum(len(b.gps_ids) > 0 for b in batches) >= 2)
        topics = {name for name, _ in probe.get_topic_names_and_types()}
        assert not any(t.endswith(('/proximity', '/gps')) for t in topics), topics
        gps = next(sensor_batch_from_msg(b).gps for b in batches if b.gps_ids)
        assert sorted(i for i, *_ in gps) == [0, 1]
        # Every clock message heard since the first batch has its batch (the last clock
        # may be ahead of its batch in flight).
        stamps = {(b.header.stamp.sec, b.header.stamp.nanosec) for b in batches}
        first = min(stamps)
        heard = [(c.clock.sec, c.clock.nanosec) for c in clocks[:-1]]
        heard = [c for c in heard if c >= first]
        assert len(heard) >= 5 and set(heard) <= stamps
        by_id = sensor_batch_from_msg(next(b for b in batches if b.prox_ids)).proximity
        assert sorted(by_id) == [0, 1]
        np.testing.assert_allclose(by_id[0][0], [[0.0, 2.5]], atol=0.1)
        np.testing.assert_allclose(by_id[1][0], [[0.0, -2.5]], atol=0.1)


def test_a_held_composed_world_repeats_its_time_in_empty_batches(tmp_path):
    """Holding t = 0 (here for observers that never come), sim_node repeats /clock and
    with it an empty batch: a composed process steps its agents on the batch, so without
    it they would never answer the time the world waits at."""
    from rclpy.qos import QoSProfile

    from swarm_common import qos
    from swarm_msgs.msg import SensorBatch

    with _world(tmp_path, THREE, sensor_batch=True, truth_subscribers=5,
                wait_for_agents_s=60.0) as (executor, sim, probe):
        batches = []
        probe.create_subscription(SensorBatch, '/swarm/sensor_batch', batches.append,
                                  QoSProfile(**qos.RADIO))
        assert _until(executor, lambda: len(batches) >= 3)   # a repeat every 0.25 s
        assert sim.world.t == 0.0
        assert all(b.header.stamp.sec == 0 and b.header.stamp.nanosec == 0 for b in batches)
        assert not any(b.imu_ids or b.prox_ids or b.gps_ids or b.ranges or b.rx_ids
                       for b in batches)


@pytest.mark.parametrize(('name', 'value'), [('proximity_rate_hz', -1.0),
                                             ('proximity_range_m', 0.0),
                                             ('proximity_std', math.nan)])
def test_a_bad_proximity_setting_is_refused_with_its_name(tmp_path, name, value):
    """Outside the range generated from SimParameters (NaN too): rclpy refuses the
    declaration, which run_node prints as one line."""
    from rclpy.exceptions import ParameterException

    with pytest.raises(ParameterException, match=f'Parameter {name} out of range'):
        with _world(tmp_path, THREE, **{name: value}):
            pass


def test_a_proximity_rate_of_zero_turns_the_sensor_off(tmp_path):
    with _world(tmp_path, THREE, proximity_rate_hz=0.0) as (executor, sim, probe):
        assert sim.world.proximity is None and not any(k == 'proximity' for k, _ in sim.pubs)
        assert _until(executor, lambda: sim.world.t > 0.5)
        topics = {name for name, _ in probe.get_topic_names_and_types()}
        assert not any(t.endswith('/proximity') for t in topics), topics


def test_one_tx_callback_takes_every_queued_radio_batch(tmp_path):
    """One process per agent sends one /radio/tx batch per agent: the world's callback
    drains what waits behind the batch it was given (rclpy takes one message per
    subscription per wait; 50 agents' batches queued for seconds of sim time)."""
    from rclpy.qos import QoSProfile

    from swarm_agent.conversions import frames_to_msg
    from swarm_common import qos
    from swarm_msgs.msg import RadioPacketArray

    with _world(tmp_path, THREE) as (executor, sim, probe):
        tx = probe.create_publisher(RadioPacketArray, '/radio/tx', QoSProfile(**qos.RADIO))
        assert _until(executor, lambda: tx.get_subscription_count() > 0)
        calls = []
        drain = sim._on_tx
        sim._tx_sub.callback = lambda msg: (calls.append(1), drain(msg))
        for k in range(30):
            tx.publish(frames_to_msg([(0.0, Packet(source=1, destination=BROADCAST, kind=0,
                                                   sequence=k, ttl=1, payload=b'x'))]))
        assert _until(executor, lambda: sim.world.medium.stats.sent >= 30)
        assert sim.world.medium.stats.sent == 30
        assert len(calls) < 30          # taken in fewer callbacks than messages
