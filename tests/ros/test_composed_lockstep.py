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
from rclpy.parameter import Parameter  # noqa: E402
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
    """ComposedAgents over ``robots`` and a 'world' probe node, spun by one executor."""
    fleet_file = tmp_path / 'fleet.yaml'
    save_fleet(fleet_file, robots)
    with ros_context(make_executor) as (context, executor):
        container = ComposedAgents(executor, context=context, parameter_overrides=[
            Parameter(name, value=value)
            for name, value in {'fleet_file': str(fleet_file), **params}.items()])
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
        source = container._time_source
        agent_clocks = {id(a.get_clock()) for a in container.agents.values()}
        stepping = [tmr for tmr in container.timers if tmr.clock is not container.get_clock()]
        assert len(stepping) == 4                 # control, state, routes, status line
        timer_clocks = {id(tmr.clock) for tmr in stepping}
        assert len(timer_clocks) == 1
        assert agent_clocks | timer_clocks <= {id(c) for c in source._associated_clocks}
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
        # Only the beacon (its GPS subscription) is in the executor with the container
        # and the probe: the others have nothing to wait for.
        assert set(executor.get_nodes()) == {container, probe, container.agents[0]}
        assert spin_until(executor, lambda: bool(commands), 10.0)
        first = commands[0]
        assert sorted(first.ids) == [0, 1, 2]
        assert len(first.fx) == len(first.fy) == len(first.stamps) == 3
        assert spin_until(executor, lambda: batch.get_subscription_count() > 0, 10.0)
        before = agent2.brain.localizer.velocity.copy()
        batch.publish(sensor_batch_to_msg(
            Time(sec=3), imu_ids=[2], imu_accel=[[2.0, 0.0]], imu_noise_std=0.01,
            ranges=[RangeArray(receiver=1, ranges=[RangeMeasurement(
                beacon_id=0, range=4.5, stddev=0.1)])],
            prox_ids=[1, 7], prox_counts=[1, 0], prox_offsets=[[4.0, 0.0]], prox_radii=[0.6],
            prox_stddev=0.02, rx=[(3.0, heartbeat, [1])]))
        assert spin_until(executor, lambda: 0 in agent1.brain.neighbours, 10.0)
        assert agent1.brain.neighbours[0].info == info          # radio delivery
        assert agent1.brain._ranges == [(0, 4.5, 0.1)]          # ranges
        offsets, radii = agent1.brain._proximity                # proximity
        assert offsets.tolist() == [[4.0, 0.0]] and radii.tolist() == [0.6]
        assert agent2.brain._proximity is None                  # no scan for it
        assert 0 not in agent2.brain.neighbours                 # only its receiver's
        batch.publish(sensor_batch_to_msg(Time(sec=4), imu_ids=[2], imu_accel=[[2.0, 0.0]]))
        assert spin_until(
            executor, lambda: agent2.brain.localizer.velocity[0] > before[0], 10.0)
