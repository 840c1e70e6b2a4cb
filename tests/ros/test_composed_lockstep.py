"""composed_node: a lockstepping world's every clock advance answered; batched inputs.

sim_node runs at most ``max_agent_lag_s`` (0.2 s) of sim time ahead of the slowest
agent's last command stamp, and only advances /clock when it may: an agent that lets a
clock advance go unanswered stalls the world (measured before the fix: 10 s wall stalls
until the world stopped waiting for it, twelve-agent runs at RTF 1-1.5 instead of 3-4.6).
The first test is that world without the physics: it advances /clock by 0.1 s as
sim_node computes it (steps x 0.01 s) and requires, after every advance, a command from
every agent stamped at most one advance behind, within a wall-clock bound. The second
feeds the container one SensorBatch, as sim_node with ``sensor_batch`` does.
"""

from __future__ import annotations

import contextlib
import time

import pytest

rclpy = pytest.importorskip('rclpy')

from builtin_interfaces.msg import Time  # noqa: E402
from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.qos import QoSProfile  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from spin import ros_context, spin_until  # noqa: E402

from swarm_agent.agent_node import make_executor  # noqa: E402
from swarm_agent.composed_node import ComposedAgents  # noqa: E402
from swarm_common import qos  # noqa: E402
from swarm_common.fleet import RobotSpec, save_fleet  # noqa: E402

AGENTS = 6
ADVANCES = 150
STEP_S = 0.01        # sim_node's physics step
STEPS_PER_ADVANCE = 10


@contextlib.contextmanager
def _container(tmp_path, robots, **params):
    """ComposedAgents over ``robots`` and a 'world' probe node, spun by one executor.
    ``params`` are given on the command line, as the launch plan gives them: they reach
    every node of the process (the agents' too) unless a node overrides them."""
    fleet_file = tmp_path / 'fleet.yaml'
    save_fleet(fleet_file, robots)
    args = ['--ros-args', '-p', f'fleet_file:={fleet_file}'] + [
        arg for name, value in params.items()
        for arg in ('-p', f'{name}:={str(value).lower() if isinstance(value, bool) else value}')]
    with ros_context(make_executor, args) as (context, executor):
        container = ComposedAgents(executor, context=context)
        executor.add_node(container)
        probe = rclpy.create_node('world', context=context)
        executor.add_node(probe)
        try:
            yield executor, container, probe
        finally:
            container.destroy_all()
            container.destroy_node()
            probe.destroy_node()


def test_every_clock_advance_is_answered_by_every_agent(tmp_path):
    # Far apart, no shape and no goals: every agent stands still, so its zero force is
    # repeated at the keepalive rate only (the case that stalled).
    robots = [RobotSpec(i, 1 + i % 3, i < 3, 10.0 * i, 0.0) for i in range(AGENTS)]
    with _container(tmp_path, robots, use_sim_time=True) as (executor, container, probe):
        clock = probe.create_publisher(Clock, '/clock', 10)
        stamps = {i: -1.0 for i in range(AGENTS)}
        for i in range(AGENTS):
            probe.create_subscription(
                WrenchStamped, f'/agent_{i}/cmd_force',
                lambda m, i=i: stamps.__setitem__(i, m.header.stamp.sec
                                                  + m.header.stamp.nanosec * 1e-9),
                QoSProfile(**qos.COMMAND))

        def publish(t: float) -> None:
            sec = int(t)
            clock.publish(Clock(clock=Time(sec=sec, nanosec=int(round((t - sec) * 1e9)))))

        def answered(t: float) -> bool:
            # The world's rule: it may step again once the slowest stamp + 0.2 s is
            # beyond t, i.e. every agent has answered this advance or the one before.
            return min(stamps.values()) >= t - 0.1 - 1e-6

        # The stall's cause: the container's timers ran on the container node's own
        # clock, fed by its own /clock subscription, while the agents' clocks followed a
        # second one; a timer could fire on a time the agents had not read yet. One time
        # source now feeds both (a race between two DDS readers, hence checked directly).
        source = container._sim_time
        agent_clocks = {id(a.get_clock()) for a in container.agents.values()}
        stepping = [tmr for tmr in container.timers if tmr.clock is not container.get_clock()]
        assert len(stepping) == 4                 # control, state, routes, status line
        timer_clocks = {id(tmr.clock) for tmr in stepping}
        assert len(timer_clocks) == 1
        assert agent_clocks | timer_clocks <= {id(c) for c in source._associated_clocks}
        # use_sim_time on the command line reaches every node of the process; the agents
        # still do not subscribe to /clock (a hundred subscriptions would each take
        # every clock message: measured, 1,600 callbacks a second for 100 agents).
        assert not any(s.topic_name == '/clock' for a in container.agents.values()
                       for s in a.subscriptions)
        # Start-up: advance until every agent has commanded once (discovery, first timers).
        k = 0
        deadline = time.monotonic() + 30.0
        while min(stamps.values()) < 0.0 and time.monotonic() < deadline:
            k += 1
            publish(k * STEPS_PER_ADVANCE * STEP_S)
            spin_until(executor, lambda: min(stamps.values()) >= 0.0, 0.5)
        assert min(stamps.values()) >= 0.0, f'agents never commanded: {stamps}'
        late = []
        for j in range(k + 1, k + 1 + ADVANCES):
            t = j * STEPS_PER_ADVANCE * STEP_S
            publish(t)
            if not spin_until(executor, lambda t=t: answered(t), 2.0):
                late.append((round(t, 2), dict(stamps)))
                publish(t)   # what sim_node does while it holds: repeat the time
                spin_until(executor, lambda t=t: answered(t), 1.0)
        assert not late, f'{len(late)} of {ADVANCES} advances unanswered, first {late[:3]}'


def test_a_composed_process_takes_its_agents_inputs_from_one_sensor_batch(tmp_path):
    """sensor_batch: the world's one message per step reaches each agent's brain."""
    from swarm_agent.agent_factory import swarm_keyring
    from swarm_agent.conversions import sensor_batch_to_msg
    from swarm_agent.frame_auth import FrameAuth
    from swarm_agent.mesh_messages import NeighbourInfo
    from swarm_agent.packet import BROADCAST, Kind, Packet
    from swarm_agent.wire import encode_heartbeat
    from swarm_msgs.msg import (
        ForceBatch,
        RangeArray,
        RangeMeasurement,
        SensorBatch,
    )

    robots = [RobotSpec(0, 1, True, 0.0, 0.0), RobotSpec(1, 2, False, 5.0, 0.0),
              RobotSpec(2, 3, False, 9.0, 0.0)]
    info = NeighbourInfo(1, True, 0, (0.5, -0.25), (0.0, 0.0))
    # Sealed under the development key the agents hold (frames are authenticated).
    heartbeat = FrameAuth(swarm_keyring()).seal(
        Packet(0, BROADCAST, Kind.HEARTBEAT, 7, 1, encode_heartbeat(7, info.encode())))
    with _container(tmp_path, robots, sensor_batch=True) as (executor, container, probe):
        batch = probe.create_publisher(SensorBatch, '/swarm/sensor_batch',
                                       QoSProfile(**qos.RADIO))
        commands = []
        probe.create_subscription(ForceBatch, '/swarm/cmd_batch', commands.append,
                                  QoSProfile(**qos.COMMAND_BATCH))
        agent1, agent2 = container.agents[1], container.agents[2]
        # Nothing per robot: the agents have no imu, ranges, proximity, radio/rx or
        # cmd_force topics and their commands leave in batches (the first one holds every
        # agent's).
        topics = {name for name, _ in probe.get_topic_names_and_types()}
        assert not any(t.endswith(('/imu', '/ranges', '/proximity', '/radio/rx', '/cmd_force'))
                       for t in topics), topics
        # No agent is in the executor (the beacon's GPS comes in the batch too): only the
        # container and the probe.
        assert not any(t.endswith('/gps') for t in topics), topics
        assert set(executor.get_nodes()) == {container, probe}
        assert spin_until(executor, lambda: batch.get_subscription_count() > 0, 10.0)
        # A batch steps the agents (no timer does): an empty one, as a holding world sends.
        batch.publish(sensor_batch_to_msg(Time(sec=2)))
        assert spin_until(executor, lambda: bool(commands), 10.0)
        first = commands[0]
        assert sorted(first.ids) == [0, 1, 2]
        assert len(first.fx) == len(first.fy) == len(first.stamps) == 3
        before = agent2.brain.localizer.velocity.copy()
        beacon = container.agents[0].brain.localizer
        assert abs(beacon.position).max() < 0.05
        batch.publish(sensor_batch_to_msg(
            Time(sec=3), imu_ids=[2], imu_accel=[[2.0, 0.0]], imu_noise_std=0.01,
            ranges=[RangeArray(receiver=1, ranges=[RangeMeasurement(
                beacon_id=0, range=4.5, stddev=0.1)])],
            prox_ids=[1, 7], prox_counts=[1, 0], prox_offsets=[[4.0, 0.0]], prox_radii=[0.6],
            prox_stddev=0.02, rx=[(3.0, heartbeat, [1])], gps=[(0, 0.5, -0.5, 0.2)]))
        assert spin_until(executor, lambda: 0 in agent1.brain.neighbours, 10.0)
        # The beacon's GPS fix pulled its estimate from (0, 0) towards (0.5, -0.5).
        assert spin_until(executor, lambda: beacon.position[0] > 0.1, 10.0)
        assert beacon.position[1] < -0.1
        assert agent1.brain.neighbours[0].info == info          # radio delivery
        assert agent1.brain._ranges == [(0, 4.5, 0.1)]          # ranges
        offsets, radii = agent1.brain._proximity                # proximity
        assert offsets.tolist() == [[4.0, 0.0]] and radii.tolist() == [0.6]
        assert agent2.brain._proximity is None                  # no scan for it
        assert 0 not in agent2.brain.neighbours                 # only its receiver's
        batch.publish(sensor_batch_to_msg(Time(sec=4), imu_ids=[2], imu_accel=[[2.0, 0.0]]))
        assert spin_until(
            executor, lambda: agent2.brain.localizer.velocity[0] > before[0], 10.0)


def test_with_sim_time_each_batch_is_the_agents_clock_and_one_control_tick(tmp_path):
    """A batch at every world step (sim_node with sensor_batch): every agent answers each
    new step once, stamped with the step's time; a held world's repeat adds nothing; the
    container has no /clock subscription for its agents."""
    from swarm_agent.conversions import sensor_batch_to_msg
    from swarm_msgs.msg import ForceBatch, SensorBatch

    robots = [RobotSpec(i, 1 + i % 3, i < 2, 10.0 * i, 0.0) for i in range(4)]
    with _container(tmp_path, robots, use_sim_time=True, sensor_batch=True) as (
            executor, container, probe):
        # The container node's own clock keeps rclpy's /clock subscription (logging);
        # nothing else in the process listens to /clock.
        clock_subs = [s for s in container.subscriptions if s.topic_name == '/clock']
        assert len(clock_subs) <= 1
        assert not any(s.topic_name == '/clock' for a in container.agents.values()
                       for s in a.subscriptions)
        batch = probe.create_publisher(SensorBatch, '/swarm/sensor_batch',
                                       QoSProfile(**qos.RADIO))
        commands = []
        probe.create_subscription(ForceBatch, '/swarm/cmd_batch', commands.append,
                                  QoSProfile(**qos.COMMAND_BATCH))
        assert spin_until(executor, lambda: batch.get_subscription_count() > 0, 10.0)
        assert spin_until(executor, lambda: probe.count_publishers('/swarm/cmd_batch') > 0,
                          10.0)
        # 20 ms steps, each published once, then a repeat of the last (a held clock).
        steps = [Time(sec=0, nanosec=20_000_000 * k) for k in range(10)]
        for stamp in steps + [steps[-1]]:
            sent = len(commands)
            batch.publish(sensor_batch_to_msg(stamp))
            spin_until(executor, lambda sent=sent: len(commands) > sent, 2.0)
        spin_until(executor, lambda: False, 0.3)
        assert len(commands) == len(steps)
        for stamp, command in zip(steps, commands):
            assert sorted(command.ids) == [0, 1, 2, 3]
            expected = stamp.sec + stamp.nanosec * 1e-9
            assert list(command.stamps) == pytest.approx([expected] * 4, abs=1e-9)
            assert command.header.stamp == stamp
        assert all(abs(a.get_clock().now().nanoseconds - 180_000_000) == 0
                   for a in container.agents.values())
