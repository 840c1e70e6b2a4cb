"""A robot's state from overhead-camera poses, predicted over the camera's latency (ch. 5.1).

The thesis's robots have no IMU and no LPS (5.1): the overhead camera's poses are all a
robot knows of itself. A camera pose describes the moment the frame was captured, and
reaches the agent a latency later (exposure, transfer, image processing: 50 ms plus the
tracker's few milliseconds with the rendered camera of the hardware-in-the-loop demo).
:class:`CameraPoseWindow` keeps the poses of the last ``window`` seconds by their
capture stamps (not their arrival times, which jitter with the load of the machine) and
gives

- the velocity and yaw rate: the displacement over the window divided by the capture
  times' difference;
- the pose now: the last pose predicted forward by its age with that velocity and rate
  (constant-velocity prediction, the prediction step of the filter of thesis 3.1.4 without
  an accelerometer), so the controller acts on where the robot is, not where it was.

A stamp of zero (unset), one in the future or one older than ``max_age`` (a camera
clock that is not the agents', or a stalled pipeline) is replaced by the arrival time:
the pose is then used as it is, without prediction. Poses older than the last one
(reordered on the network) are dropped.

Pure module (no rclpy).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import math

import numpy as np

FUTURE_SLACK_S = 0.005     # clocks of one host agree to better than this


@dataclass(frozen=True)
class PoseEstimate:
    """Position (m), velocity (m/s), yaw (rad CCW) and yaw rate (rad/s) at ``t`` (s);
    ``age``: seconds from the capture of the last pose to ``t``."""

    position: np.ndarray
    velocity: np.ndarray
    yaw: float
    rate: float
    t: float
    age: float


class CameraPoseWindow:
    """Camera poses of the last ``window`` seconds; see the module docstring."""

    def __init__(self, window: float, max_age: float) -> None:
        if not (window > 0.0 and max_age >= 0.0):
            raise ValueError(f'window {window} s must be positive and max_age {max_age} s '
                             'not negative')
        self.window = float(window)
        self.max_age = float(max_age)
        self.poses: deque[tuple[float, float, float, float]] = deque()   # t, x, y, yaw
        self.compensated = 0      # poses whose capture stamp was used
        self.restamped = 0        # poses stamped with their arrival time instead

    def add(self, stamp: float, received: float, x: float, y: float, yaw: float) -> bool:
        """A pose captured at ``stamp`` (s, 0 if unknown) that arrived at ``received``
        (s, the same clock); False if it is not finite or older than the last."""
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(yaw)):
            return False
        if (math.isfinite(stamp) and stamp > 0.0 and stamp <= received + FUTURE_SLACK_S
                and received - stamp <= self.max_age):
            t = min(stamp, received)
            self.compensated += 1
        else:
            t = received
            self.restamped += 1
        if self.poses and t <= self.poses[-1][0]:
            return False
        self.poses.append((t, float(x), float(y), float(yaw)))
        while len(self.poses) > 2 and t - self.poses[1][0] >= self.window:
            self.poses.popleft()
        return True

    @property
    def last_stamp(self) -> float | None:
        """Capture time of the last pose (s), None before the first."""
        return self.poses[-1][0] if self.poses else None

    def estimate(self, now: float) -> PoseEstimate:
        """The state at ``now``: the last pose predicted forward by its age (at most
        ``max_age``) with the velocity and yaw rate over the window."""
        if not self.poses:
            raise ValueError('no camera pose yet')
        t, x, y, yaw = self.poses[-1]
        t0, x0, y0, yaw0 = self.poses[0]
        dt = t - t0
        if dt > 1e-3:
            velocity = np.array([x - x0, y - y0]) / dt
            rate = math.remainder(yaw - yaw0, math.tau) / dt
        else:
            velocity, rate = np.zeros(2), 0.0
        age = min(max(now - t, 0.0), self.max_age)
        return PoseEstimate(np.array([x, y]) + velocity * age, velocity,
                            math.remainder(yaw + rate * age, math.tau), rate, now, age)
