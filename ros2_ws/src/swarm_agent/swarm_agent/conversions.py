"""Pure conversions between swarm_msgs messages and the brain's domain types.

Imports message classes only (no rclpy), so it is tested without a ROS graph.
"""

from __future__ import annotations

from array import array
from collections.abc import Iterable, Sequence

from builtin_interfaces.msg import Time
import numpy as np

from swarm_agent.brain import Snapshot
from swarm_agent.packet import pack_frames, Packet, PacketError, unpack_frames
from swarm_msgs.msg import (
    AgentState,
    ProximityArray,
    RadioPacketArray,
    RangeArray,
    RouteEntry,
    RouteTable,
    SensorBatch,
)


class SensorMessageError(ValueError):
    """A sensor message whose parallel arrays disagree in length."""


def stamp_seconds(stamp: Time) -> float:
    """A builtin_interfaces/Time as seconds (0.0 for an unset stamp)."""
    return stamp.sec + stamp.nanosec * 1e-9


def frames_to_msg(frames: Iterable[tuple[float, Packet]],
                  stamp: Time | None = None) -> RadioPacketArray:
    """``(transmission stamp in seconds, packet)`` pairs -> swarm_msgs/RadioPacketArray."""
    msg = RadioPacketArray()
    if stamp is not None:
        msg.header.stamp = stamp
    # array('B') is what rosidl keeps for uint8[]: assigned without a per-byte check.
    msg.frames = array('B', pack_frames(frames))
    return msg


def frames_from_msg(msg: RadioPacketArray) -> list[tuple[float, Packet]]:
    """swarm_msgs/RadioPacketArray -> ``(stamp, packet)`` pairs; PacketError if corrupt."""
    return unpack_frames(msg.frames)


def frames_or_log(msg: RadioPacketArray, logger, topic: str) -> list[tuple[float, Packet]]:
    """``frames_from_msg``, or no frames and one throttled error line naming ``topic``
    (a corrupt batch is dropped; the node keeps running). ``logger``: an rclpy logger."""
    try:
        return frames_from_msg(msg)
    except PacketError as exc:
        logger.error(f'dropped a corrupt radio batch on {topic}: {exc}',
                     throttle_duration_sec=10.0)
        return []


def proximity_to_msg(stamp: Time, receiver: int, offsets, radii,
                     stddev: float) -> ProximityArray:
    """One robot's proximity scan -> swarm_msgs/ProximityArray. ``offsets`` (k, 2):
    neighbour centres minus the receiver's (m, map frame); ``radii`` (k,) theirs (m)."""
    offsets = np.asarray(offsets, dtype=float).reshape(-1, 2)
    msg = ProximityArray()
    msg.header.stamp = stamp
    msg.receiver = int(receiver)
    # array('d') is what rosidl keeps for float64[]: assigned without a per-item check.
    msg.x = array('d', offsets[:, 0].tolist())
    msg.y = array('d', offsets[:, 1].tolist())
    msg.radius = array('d', np.asarray(radii, dtype=float).reshape(-1).tolist())
    msg.stddev = float(stddev)
    return msg


def proximity_from_msg(msg: ProximityArray) -> tuple[np.ndarray, np.ndarray]:
    """swarm_msgs/ProximityArray -> (offsets (k, 2), radii (k,)); SensorMessageError when
    x, y and radius differ in length."""
    if not len(msg.x) == len(msg.y) == len(msg.radius):
        raise SensorMessageError(f'proximity of robot {msg.receiver}: {len(msg.x)} x, '
                                 f'{len(msg.y)} y and {len(msg.radius)} radius values')
    offsets = np.empty((len(msg.x), 2))
    offsets[:, 0] = msg.x
    offsets[:, 1] = msg.y
    return offsets, np.array(msg.radius, dtype=float)


def sensor_batch_to_msg(stamp: Time, *, imu_ids=(), imu_accel=None, imu_noise_std: float = 0.0,
                        ranges: Iterable[RangeArray] = (),
                        prox_ids=(), prox_counts=(), prox_offsets=None, prox_radii=None,
                        prox_stddev: float = 0.0,
                        rx: Sequence[tuple[float, Packet, Sequence[int]]] = ()
                        ) -> SensorBatch:
    """One step's sensor data and radio deliveries of many robots -> swarm_msgs/SensorBatch.

    ``imu_accel`` (len(imu_ids), 2) map-frame accelerations; ``rx`` the deliveries in
    arrival order, grouped by frame as the medium makes them
    (``RadioMedium.deliver_grouped``): ``(stamp, packet, receivers)``. Each frame is
    packed once; each receiver gets the indices of its frames, in arrival order.
    """
    msg = SensorBatch()
    msg.header.stamp = stamp
    if len(imu_ids):
        accel = np.asarray(imu_accel, dtype=float).reshape(len(imu_ids), 2)
        msg.imu_ids = array('H', [int(i) for i in imu_ids])
        msg.imu_ax = array('d', accel[:, 0].tolist())
        msg.imu_ay = array('d', accel[:, 1].tolist())
        msg.imu_noise_std = float(imu_noise_std)
    msg.ranges = list(ranges)
    if len(prox_ids):
        # Scans grouped by observer: robot prox_ids[k] saw the next prox_counts[k] rows
        # of prox_offsets (M, 2) and prox_radii (M,).
        offsets = np.asarray(prox_offsets, dtype=float).reshape(-1, 2)
        msg.prox_ids = array('H', [int(i) for i in prox_ids])
        msg.prox_counts = array('I', [int(c) for c in prox_counts])
        msg.prox_x = array('d', offsets[:, 0].tolist())
        msg.prox_y = array('d', offsets[:, 1].tolist())
        msg.prox_radius = array('d', np.asarray(prox_radii, dtype=float).tolist())
        msg.prox_stddev = float(prox_stddev)
    if rx:
        # Vectorised: one (receiver, frame index) pair per delivery, stably sorted by
        # receiver so that each receiver's frames stay in arrival order.
        receivers = np.fromiter((r for _, _, rs in rx for r in rs), dtype=np.int64)
        frame_of = np.repeat(np.arange(len(rx)), [len(rs) for _, _, rs in rx])
        order = np.argsort(receivers, kind='stable')
        ids, counts = np.unique(receivers[order], return_counts=True)
        msg.rx_ids = array('H', ids.tolist())
        msg.rx_counts = array('I', counts.tolist())
        msg.rx_frames = array('I', frame_of[order].tolist())
        msg.frames = array('B', pack_frames((stamp_s, packet) for stamp_s, packet, _ in rx))
    return msg


def sensor_batch_from_msg(msg: SensorBatch) -> tuple[
        list[tuple[int, float, float]], list[RangeArray],
        dict[int, tuple[np.ndarray, np.ndarray]], dict[int, list[tuple[float, Packet]]]]:
    """swarm_msgs/SensorBatch -> (imu samples (id, ax, ay), range arrays, proximity scans
    by observer (offsets (k, 2), radii (k,)), rx frames by receiver). Raises PacketError
    when the imu, proximity or radio arrays disagree or a frame is corrupt."""
    if not len(msg.imu_ax) == len(msg.imu_ay) == len(msg.imu_ids):
        raise PacketError(f'{len(msg.imu_ids)} imu ids but {len(msg.imu_ax)} x and '
                          f'{len(msg.imu_ay)} y accelerations')
    rows = len(msg.prox_x)
    if len(msg.prox_ids) != len(msg.prox_counts) or sum(msg.prox_counts) != rows or \
            not rows == len(msg.prox_y) == len(msg.prox_radius):
        raise PacketError(f'{len(msg.prox_ids)} proximity observers with '
                          f'{len(msg.prox_counts)} counts summing to {sum(msg.prox_counts)} '
                          f'but {rows} x, {len(msg.prox_y)} y and {len(msg.prox_radius)} '
                          'radius values')
    offsets = np.column_stack([np.asarray(msg.prox_x, dtype=float),
                               np.asarray(msg.prox_y, dtype=float)])
    radii = np.asarray(msg.prox_radius, dtype=float)
    ends = np.cumsum(np.asarray(msg.prox_counts, dtype=np.int64))
    proximity = {int(i): (offsets[end - count:end], radii[end - count:end])
                 for i, count, end in zip(msg.prox_ids, msg.prox_counts, ends.tolist())}
    imu = list(zip((int(i) for i in msg.imu_ids), msg.imu_ax, msg.imu_ay))
    if len(msg.rx_ids) != len(msg.rx_counts) or sum(msg.rx_counts) != len(msg.rx_frames):
        raise PacketError(f'{len(msg.rx_ids)} receivers with {len(msg.rx_counts)} counts '
                          f'summing to {sum(msg.rx_counts)} frames, {len(msg.rx_frames)} '
                          'indices sent')
    distinct = unpack_frames(msg.frames)
    if len(msg.rx_frames) and max(msg.rx_frames) >= len(distinct):
        raise PacketError(f'frame index {max(msg.rx_frames)} beyond the {len(distinct)} '
                          'frames sent')
    refs, offset, rx = list(msg.rx_frames), 0, {}
    for receiver, count in zip(msg.rx_ids, msg.rx_counts):
        rx[int(receiver)] = [distinct[k] for k in refs[offset:offset + count]]
        offset += count
    return imu, list(msg.ranges), proximity, rx


def snapshot_to_state(snap: Snapshot, stamp: Time | None = None,
                      frame_id: str = 'map') -> AgentState:
    """Brain snapshot -> swarm_msgs/AgentState."""
    msg = AgentState()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.id = snap.agent_id
    msg.type = snap.agent_type
    msg.is_beacon = snap.is_beacon
    msg.mode = snap.mode
    msg.position = [float(v) for v in snap.position]
    msg.velocity = [float(v) for v in snap.velocity]
    cov = np.asarray(snap.covariance, dtype=float).reshape(-1)
    msg.covariance = [float(v) for v in cov] if cov.size == 16 else [0.0] * 16
    msg.assigned_goal = int(snap.goal_id)
    msg.goal_version = int(snap.goal_version)
    msg.assignment_round = int(snap.assignment_round) & 0xFFFFFFFF
    msg.assignment_digest = int(snap.assignment_digest) & 0xFFFFFFFF
    msg.rows_used = min(int(snap.rows_used), 0xFFFF)
    msg.settled = bool(snap.settled)
    msg.localized = bool(snap.localized)
    return msg


def routes_to_msg(owner: int, routes: Iterable, stamp: Time | None = None) -> RouteTable:
    """DSDV route entries (destination, next_hop, hop_count, sequence_number) -> RouteTable."""
    msg = RouteTable()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.owner = owner
    for r in routes:
        entry = RouteEntry()
        entry.destination = int(r.destination)
        entry.next_hop = int(r.next_hop)
        entry.hop_count = min(int(r.hop_count), RouteEntry.INFINITE_HOPS)
        entry.sequence_number = int(r.sequence_number) & 0xFFFFFFFF
        msg.routes.append(entry)
    return msg
