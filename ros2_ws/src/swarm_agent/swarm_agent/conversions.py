"""Pure conversions between messages and the brain's domain types.

Imports message classes only (no rclpy), so it is tested without a ROS graph.

Standard interfaces (REP 103, REP 105). An agent's estimate is ``map ->
agent_K/base_link`` (TF, tf2_msgs/TFMessage on /tf) and ``odom`` (nav_msgs/Odometry:
pose in ``map``, twist in the body frame ``agent_K/base_link``); ``cmd_vel`` is a Twist
in that body frame. The body frame's heading is a ``Heading``:

- Simulation: ``MAP_ALIGNED`` (yaw 0, exactly). The simulated robots are holonomic
  (omni wheels, thesis 5.1; point masses or rigid bodies pushed by map-frame forces),
  and the brain estimates no heading: nothing it senses or commands depends on one (its
  IMU samples and force commands are in the map frame). A body frame that keeps the map
  axes is therefore exact for what the brain knows, and REP 105's body-frame twist is
  the map-frame velocity estimate component by component. The direction of the velocity
  is not taken as the heading: a holonomic robot does not turn towards its motion, a
  parked robot has no velocity direction (the frame would spin at every noisy sample),
  and the body-frame lateral speed would always read zero, as if the robot were a
  differential drive.
- Hardware: the overhead camera measures each robot's yaw (thesis 5.3), so the body
  frame is the robot's own: the agent takes the camera's yaw (and hw_agent_node its
  rate) as its heading, and rotates its map-frame setpoint into that frame for
  ``cmd_vel``; the bridge sends it to the board as is.
"""

from __future__ import annotations

from array import array
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
import math
from typing import NamedTuple

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped, Quaternion, TransformStamped, Twist
from nav_msgs.msg import Odometry
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


class SensorInputs(NamedTuple):
    """A SensorBatch's contents (``sensor_batch_from_msg``)."""

    imu: list[tuple[int, float, float]]           # (robot id, ax, ay) m/s^2, map frame
    ranges: list[RangeArray]
    proximity: dict[int, tuple[np.ndarray, np.ndarray]]   # id: offsets (k, 2), radii (k,)
    rx: list[tuple[float, Packet, list[int]]]     # (stamp, frame, receivers), by arrival
    gps: list[tuple[int, float, float, float]]    # (beacon id, x, y, std) m


def sensor_batch_to_msg(stamp: Time, *, imu_ids=(), imu_accel=None, imu_noise_std: float = 0.0,
                        gps: Sequence[tuple[int, float, float, float]] = (),
                        ranges: Iterable[RangeArray] = (),
                        prox_ids=(), prox_counts=(), prox_offsets=None, prox_radii=None,
                        prox_stddev: float = 0.0,
                        rx: Sequence[tuple[float, Packet, Sequence[int]]] = ()
                        ) -> SensorBatch:
    """One step's sensor data and radio deliveries of many robots -> swarm_msgs/SensorBatch.

    ``imu_accel`` (len(imu_ids), 2) map-frame accelerations; ``gps`` beacons' fixes
    ``(id, x, y, std)``; ``rx`` the deliveries in
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
    if gps:
        ids, xs, ys, stds = zip(*gps)
        msg.gps_ids = array('H', [int(i) for i in ids])
        msg.gps_x, msg.gps_y = array('d', map(float, xs)), array('d', map(float, ys))
        msg.gps_std = array('d', map(float, stds))
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


def sensor_batch_from_msg(msg: SensorBatch) -> SensorInputs:
    """swarm_msgs/SensorBatch -> its SensorInputs (the radio deliveries grouped by frame
    in arrival order, ``(stamp, packet, receivers)``, as ``sensor_batch_to_msg`` takes
    them). Raises PacketError when the imu, gps, proximity or radio arrays disagree or a
    frame is corrupt."""
    if not len(msg.imu_ax) == len(msg.imu_ay) == len(msg.imu_ids):
        raise PacketError(f'{len(msg.imu_ids)} imu ids but {len(msg.imu_ax)} x and '
                          f'{len(msg.imu_ay)} y accelerations')
    if not len(msg.gps_ids) == len(msg.gps_x) == len(msg.gps_y) == len(msg.gps_std):
        raise PacketError(f'{len(msg.gps_ids)} gps ids but {len(msg.gps_x)} x, '
                          f'{len(msg.gps_y)} y and {len(msg.gps_std)} std values')
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
    # Each frame's receivers: the deliveries (receiver, frame) stably sorted by frame keep
    # the receivers' order (a thousand or more deliveries a step for 100 agents).
    frame_of = np.asarray(msg.rx_frames, dtype=np.int64)
    receivers = np.repeat(np.asarray(msg.rx_ids, dtype=np.int64),
                          np.asarray(msg.rx_counts, dtype=np.int64))
    by_frame = receivers[np.argsort(frame_of, kind='stable')].tolist()
    ends = np.cumsum(np.bincount(frame_of, minlength=len(distinct))).tolist()
    rx, start = [], 0
    for (stamp, packet), end in zip(distinct, ends):
        if end > start:
            rx.append((stamp, packet, by_frame[start:end]))
            start = end
    gps = list(zip((int(i) for i in msg.gps_ids), msg.gps_x, msg.gps_y, msg.gps_std))
    return SensorInputs(imu, list(msg.ranges), proximity, rx, gps)


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


@dataclass(frozen=True)
class Heading:
    """A robot's heading: yaw (rad, counter-clockwise from the map x axis, REP 103), its
    rate (rad/s) and their standard deviations. See the module docstring."""

    yaw: float = 0.0
    yaw_std: float = 0.0
    rate: float = 0.0
    rate_std: float = 0.0


# Simulation: the body frame keeps the map axes (module docstring).
MAP_ALIGNED = Heading()


def base_frame(agent_id: int) -> str:
    """The body frame of agent ``agent_id`` (REP 105 base_link, one per robot)."""
    return f'agent_{int(agent_id)}/base_link'


def yaw_quaternion(yaw: float) -> Quaternion:
    """A rotation by ``yaw`` (rad) about z as a geometry_msgs/Quaternion."""
    return Quaternion(x=0.0, y=0.0, z=math.sin(0.5 * yaw), w=math.cos(0.5 * yaw))


def pose_stamped(x: float, y: float, yaw: float, stamp: Time,
                 frame_id: str = 'map') -> PoseStamped:
    """A planar pose (m, m, rad CCW) as a geometry_msgs/PoseStamped in ``frame_id``."""
    msg = PoseStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.pose.position.x, msg.pose.position.y = float(x), float(y)
    msg.pose.orientation = yaw_quaternion(yaw)
    return msg


def yaw_of(q) -> float:
    """Yaw (rad, counter-clockwise, in (-pi, pi]) of a geometry_msgs quaternion."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def map_to_body(vx: float, vy: float, yaw: float) -> tuple[float, float]:
    """A map-frame vector in the body frame of a robot heading ``yaw`` (R(yaw)^T v)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return c * vx + s * vy, -s * vx + c * vy


def setpoint_to_twist(setpoint, heading: Heading = MAP_ALIGNED) -> Twist:
    """The brain's map-frame velocity setpoint (m/s) as ``cmd_vel``: a Twist in the body
    frame (REP 103); no rotation is commanded (angular.z 0: the setpoint of thesis 3.2.4
    is a translation)."""
    twist = Twist()
    twist.linear.x, twist.linear.y = map_to_body(float(setpoint[0]), float(setpoint[1]),
                                                 heading.yaw)
    return twist


def snapshot_to_odometry(snap: Snapshot, stamp: Time | None = None,
                         heading: Heading = MAP_ALIGNED,
                         frame_id: str = 'map') -> Odometry:
    """Brain snapshot -> nav_msgs/Odometry (REP 105).

    Pose in ``frame_id``: the position estimate with its covariance (the Kalman filter's
    P[:2, :2], thesis 3.1.4) and the heading's yaw with its variance. Twist in the child
    frame ``agent_K/base_link``: the velocity estimate and its covariance P[2:4, 2:4]
    rotated into the body frame (R^T v, R^T P R), the heading's rate as angular.z. The
    robot is planar: z, roll and pitch are 0 by construction, with variance 0.
    """
    msg = Odometry()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.child_frame_id = base_frame(snap.agent_id)
    p = np.zeros((4, 4))
    cov = np.asarray(snap.covariance, dtype=float)
    if cov.size == 16:
        p = cov.reshape(4, 4)
    pose = msg.pose
    pose.pose.position.x, pose.pose.position.y = (float(v) for v in snap.position[:2])
    pose.pose.orientation = yaw_quaternion(heading.yaw)
    pose_cov = np.zeros((6, 6))
    pose_cov[:2, :2] = p[:2, :2]
    pose_cov[5, 5] = heading.yaw_std ** 2
    pose.covariance = pose_cov.reshape(-1).tolist()
    c, s = math.cos(heading.yaw), math.sin(heading.yaw)
    rot = np.array([[c, -s], [s, c]])          # body -> map
    twist = msg.twist
    twist.twist.linear.x, twist.twist.linear.y = map_to_body(
        float(snap.velocity[0]), float(snap.velocity[1]), heading.yaw)
    twist.twist.angular.z = float(heading.rate)
    twist_cov = np.zeros((6, 6))
    twist_cov[:2, :2] = rot.T @ p[2:4, 2:4] @ rot
    twist_cov[5, 5] = heading.rate_std ** 2
    twist.covariance = twist_cov.reshape(-1).tolist()
    return msg


def transform_of(stamp: Time | None, parent: str, child: str, x: float, y: float,
                 yaw: float) -> TransformStamped:
    """A planar pose (m, m, rad) as the TransformStamped ``parent -> child``."""
    msg = TransformStamped()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = parent
    msg.child_frame_id = child
    msg.transform.translation.x, msg.transform.translation.y = float(x), float(y)
    msg.transform.rotation = yaw_quaternion(yaw)
    return msg


def snapshot_to_transform(snap: Snapshot, stamp: Time | None = None,
                          heading: Heading = MAP_ALIGNED,
                          frame_id: str = 'map') -> TransformStamped:
    """Brain snapshot -> the TF ``map -> agent_K/base_link`` of its estimate."""
    return transform_of(stamp, frame_id, base_frame(snap.agent_id), float(snap.position[0]),
                        float(snap.position[1]), heading.yaw)
