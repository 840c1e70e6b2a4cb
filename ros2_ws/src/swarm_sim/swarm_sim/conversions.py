"""The world model's readings as ROS messages (sim_node's side of the wire).

Pure functions from ``swarm_sim.world_model`` outputs to messages: per-robot IMU, GPS,
TOA ranges, proximity scans and radio deliveries, the same in one ``SensorBatch`` for
composed agents, and the ground truth (swarm_msgs/SwarmTruth, and as TF under its own
frame prefix: ``map -> truth/agent_K/base_link``, beside the agents' estimates ``map ->
agent_K/base_link``, so that tools show both and never mistake one for the other).
Stamps are ``builtin_interfaces/Time``.
"""

from __future__ import annotations

import math

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseWithCovarianceStamped
import numpy as np
from sensor_msgs.msg import Imu
from tf2_msgs.msg import TFMessage

from swarm_agent.conversions import (
    base_frame,
    frames_to_msg,
    proximity_to_msg,
    sensor_batch_to_msg,
    transform_of,
)
from swarm_msgs.msg import (
    AgentTruth,
    ForceBatch,
    ProximityArray,
    RadioPacketArray,
    RangeArray,
    RangeMeasurement,
    SensorBatch,
    SwarmTruth,
)
from swarm_sim.world_model import Readings, TruthSample

# Per-robot topics of the world, by kind: (message type, name under /agent_K/).
ROBOT_TOPICS = {'imu': (Imu, 'imu'), 'gps': (PoseWithCovarianceStamped, 'gps'),
                'ranges': (RangeArray, 'ranges'), 'proximity': (ProximityArray, 'proximity'),
                'rx': (RadioPacketArray, 'radio/rx')}


def stamp_of(t: float) -> Time:
    """Sim time ``t`` (s) as a stamp."""
    sec = int(t)
    return Time(sec=sec, nanosec=int(round((t - sec) * 1e9)) % 1_000_000_000)


def imu_msg(stamp: Time, accel, noise_std: float) -> Imu:
    """A map-frame acceleration (m/s^2) with its per-axis noise variance."""
    msg = Imu()
    msg.header.stamp = stamp
    msg.header.frame_id = 'map'
    msg.linear_acceleration.x = float(accel[0])
    msg.linear_acceleration.y = float(accel[1])
    msg.linear_acceleration_covariance[0] = noise_std ** 2
    msg.linear_acceleration_covariance[4] = noise_std ** 2
    return msg


def gps_msg(stamp: Time, fix, std: float) -> PoseWithCovarianceStamped:
    """A beacon's GPS fix (m, map frame) with its per-axis variance."""
    msg = PoseWithCovarianceStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = 'map'
    msg.pose.pose.position.x, msg.pose.pose.position.y = float(fix[0]), float(fix[1])
    msg.pose.covariance[0] = msg.pose.covariance[7] = std ** 2
    return msg


def range_msg(stamp: Time, receiver: int, ranges) -> RangeArray:
    """TOA ranges (beacon id, metres, std) measured by robot ``receiver``."""
    msg = RangeArray()
    msg.header.stamp = stamp
    msg.receiver = int(receiver)
    msg.ranges = [RangeMeasurement(beacon_id=b, range=r, stddev=s) for b, r, s in ranges]
    return msg


def truth_msg(stamp: Time, fleet, truth: TruthSample) -> SwarmTruth:
    """Every robot's true state (metrics only), in fleet order."""
    msg = SwarmTruth()
    msg.header.stamp = stamp
    msg.header.frame_id = 'map'
    pos, vel = truth.positions, truth.velocities
    msg.agents = [AgentTruth(
        id=r.id, type=r.type, is_beacon=r.is_beacon, alive=bool(truth.alive[i]),
        position=[float(pos[i, 0]), float(pos[i, 1])],
        velocity=[float(vel[i, 0]), float(vel[i, 1])], yaw=float(truth.yaws[i]))
        for i, r in enumerate(fleet)]
    return msg


TRUTH_PREFIX = 'truth'


def truth_tf(stamp: Time, fleet, truth: TruthSample, prefix: str = TRUTH_PREFIX
             ) -> TFMessage:
    """The living robots' true poses as TF ``map -> <prefix>/agent_K/base_link``: true
    position and the body's true yaw (0 for point masses; a pybullet body's own heading,
    which the agents' map-aligned estimate frames do not track: their brains need none,
    see swarm_agent.conversions)."""
    pos = truth.positions
    return TFMessage(transforms=[
        transform_of(stamp, 'map', f'{prefix}/{base_frame(r.id)}', pos[i, 0], pos[i, 1],
                     float(truth.yaws[i]))
        for i, r in enumerate(fleet) if truth.alive[i]])


def robot_messages(readings: Readings, ids: list[int], imu_std: float, proximity_std: float
                   ) -> list[tuple[str, int, object]]:
    """The per-robot messages of a report: (kind, robot id, message), kind one of imu,
    gps, ranges, proximity, rx (each living robot gets its scan, an empty one too)."""
    stamp, out = stamp_of(readings.t), []
    if readings.rx is not None:
        frames: dict[int, list] = {}
        for t, packet, receivers in readings.rx:
            for receiver in receivers:
                frames.setdefault(receiver, []).append((t, packet))
        out += [('rx', r, frames_to_msg(f, stamp)) for r, f in frames.items()]
    if readings.imu is not None:
        out += [('imu', ids[i], imu_msg(stamp, readings.imu[i], imu_std))
                for i in readings.living]
    out += [('gps', ids[i], gps_msg(stamp, fix, std)) for i, fix, std in readings.gps or ()]
    out += [('ranges', ids[i], range_msg(stamp, ids[i], r)) for i, r in readings.ranges or ()]
    if readings.proximity is not None:
        out += [('proximity', ids[i], proximity_to_msg(
            stamp, ids[i], *readings.proximity.of(i), proximity_std)) for i in readings.living]
    return out


def sensor_batch(readings: Readings, ids: list[int], imu_std: float, proximity_std: float
                 ) -> SensorBatch | None:
    """imu, gps, ranges, proximity and radio deliveries of every robot in one message
    (None: none due)."""
    if (readings.rx is None and readings.imu is None and readings.ranges is None
            and readings.proximity is None and readings.gps is None):
        return None
    stamp, batch = stamp_of(readings.t), {}
    living = readings.living
    if readings.rx is not None:
        batch['rx'] = readings.rx
    if readings.gps is not None:
        batch['gps'] = [(ids[i], fix[0], fix[1], std) for i, fix, std in readings.gps]
    if readings.imu is not None:
        batch.update(imu_ids=[ids[i] for i in living], imu_accel=readings.imu[living],
                     imu_noise_std=imu_std)
    if readings.ranges is not None:
        batch['ranges'] = [range_msg(stamp, ids[i], r) for i, r in readings.ranges]
    scan = readings.proximity
    if scan is not None:
        counts = np.bincount(scan.observers, minlength=len(ids))[living]
        batch.update(prox_ids=[ids[i] for i in living], prox_counts=counts,
                     prox_offsets=scan.offsets, prox_radii=scan.radii,
                     prox_stddev=proximity_std)
    return sensor_batch_to_msg(stamp, **batch)


def force_batch_rows(msg: ForceBatch, index: dict[int, int]
                     ) -> tuple[list[int], list[list[float]], list[float], list[str]]:
    """(fleet rows, forces, stamps, errors) of a composed process's ForceBatch: a batch
    whose arrays differ in length is dropped, a command for an unknown robot or without
    a finite stamp is left out, each with one error line."""
    n = len(msg.ids)
    if not len(msg.fx) == len(msg.fy) == len(msg.stamps) == n:
        return [], [], [], [f'{n} ids but {len(msg.fx)} fx, {len(msg.fy)} fy and '
                            f'{len(msg.stamps)} stamps; dropped']
    rows, forces, stamps, errors = [], [], [], []
    for agent, fx, fy, stamp in zip(msg.ids, msg.fx, msg.fy, msg.stamps):
        if int(agent) in index and math.isfinite(stamp):
            rows.append(index[int(agent)])
            forces.append([fx, fy])
            stamps.append(stamp)
        else:
            errors.append(f'a command for robot {agent} stamped {stamp} (unknown robot or no '
                          'valid stamp); ignored')
    return rows, forces, stamps, errors
