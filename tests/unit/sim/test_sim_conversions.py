"""The world's readings as messages (swarm_sim.conversions), sim_node's side of the wire."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip('swarm_msgs')

from swarm_agent.conversions import frames_from_msg, sensor_batch_from_msg  # noqa: E402
from swarm_agent.packet import BROADCAST, Packet  # noqa: E402
from swarm_msgs.msg import ForceBatch  # noqa: E402
from swarm_sim.conversions import (  # noqa: E402
    force_batch_rows,
    robot_messages,
    sensor_batch,
    stamp_of,
)
from swarm_sim.sensors import ProximityScan  # noqa: E402
from swarm_sim.world_model import Readings  # noqa: E402

IDS = [4, 7, 9]


def _readings() -> Readings:
    frame = Packet(source=4, destination=BROADCAST, kind=0, sequence=1, ttl=1, payload=b'x')
    scan = ProximityScan(np.array([0, 1]), np.array([[1.0, 0.0], [-1.0, 0.0]]),
                         np.array([0.3, 0.5]))
    return Readings(2.25, np.array([0, 1]), rx=[(2.2, frame, [7, 9])],
                    imu=np.array([[0.1, 0.2], [0.3, 0.4], [9.0, 9.0]]),
                    ranges=[(0, [(7, 5.0, 0.3)]), (1, [])], proximity=scan,
                    gps=[(0, np.array([1.0, 2.0]), 2.0)])


def test_a_stamp_carries_seconds_and_nanoseconds():
    stamp = stamp_of(2.25)
    assert (stamp.sec, stamp.nanosec) == (2, 250_000_000)


def test_each_living_robot_gets_its_messages():
    messages = robot_messages(_readings(), IDS, imu_std=0.01, proximity_std=0.02)
    kinds = sorted((kind, agent) for kind, agent, _ in messages)
    assert kinds == [('gps', 4), ('imu', 4), ('imu', 7), ('proximity', 4), ('proximity', 7),
                     ('ranges', 4), ('ranges', 7), ('rx', 7), ('rx', 9)]   # 9 is removed
    by = {(kind, agent): msg for kind, agent, msg in messages}
    assert by['imu', 7].linear_acceleration.x == 0.3
    assert by['imu', 7].linear_acceleration_covariance[0] == pytest.approx(1e-4)
    assert by['gps', 4].pose.covariance[7] == 4.0
    assert [(r.beacon_id, r.range) for r in by['ranges', 4].ranges] == [(7, 5.0)]
    assert [t for t, _ in frames_from_msg(by['rx', 9])] == [pytest.approx(2.2)]


def test_a_composed_world_gets_one_batch_or_none_when_nothing_is_due():
    readings = _readings()
    batch = sensor_batch(readings, IDS, imu_std=0.01, proximity_std=0.02)
    imu, _, proximity, rx, gps = sensor_batch_from_msg(batch)
    assert imu == [(4, 0.1, 0.2), (7, 0.3, 0.4)]
    assert gps == [(4, 1.0, 2.0, 2.0)]        # the beacon's fix rides in the batch too
    assert sorted(proximity) == [4, 7] and sorted({r for _, _, rs in rx for r in rs}) == [7, 9]
    assert sensor_batch(Readings(1.0, np.array([0])), IDS, 0.01, 0.02) is None


def test_a_force_batch_keeps_the_valid_commands_and_names_the_others():
    index = {4: 0, 7: 1, 9: 2}
    rows, forces, stamps, errors = force_batch_rows(
        ForceBatch(ids=[4, 8, 9], fx=[1.0, 2.0, 3.0], fy=[0.0, 0.0, -1.0],
                   stamps=[0.5, 0.5, math.nan]), index)
    assert (rows, forces, stamps) == ([0], [[1.0, 0.0]], [0.5])
    assert len(errors) == 2 and 'robot 8' in errors[0] and 'robot 9' in errors[1]
    rows, _, _, errors = force_batch_rows(ForceBatch(ids=[4], fx=[1.0], fy=[], stamps=[0.0]),
                                          index)
    assert rows == [] and errors == ['1 ids but 1 fx, 0 fy and 1 stamps; dropped']
