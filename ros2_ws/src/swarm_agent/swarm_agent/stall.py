"""A robot that pushes and does not move: stall detection (beyond the thesis).

Between fixes the agent dead-reckons with its accelerometer (eq. 3.30). A body that
runs into something it cannot push away (the workspace wall, an obstacle, a robot
pushing back) decelerates, and the filter integrates the stop; from then on the accelerometer
reads only its bias and noise. Nothing in the filter says the body now stands, and
without fixes the bias is not observable, so the velocity estimate runs off by the bias
times the time: a type-1 robot held against the boundary wall at its force limit in
pybullet dead-reckoned itself 0.15 m/s off after 150 s and 33 m off after 300 s, and
the robot kept pushing towards where it believed its goal was.

Physics tells the two apart, with the filter's help. A free robot pushed at its force
limit ``u_limit`` (``agent_factory``: eq. 3.111's u_max plus twice the Coulomb
friction) accelerates at ``(u_limit - mu_1 m g - m g sin(slope) - mu_2 v) / m`` along
the force: 2.8 to 4.5 m/s^2 for the types of Table 4.1 on the terrain's steepest slope
(7 deg, see ``swarm_sim.terrain``); and any motion across the force, which nothing
drives, is braked by dry friction at mu_1 g cos(slope) - g sin(slope), 0.6 m/s^2 or
more. So a force held within ``SATURATED`` of the limit for ``stall_window_s`` while
the mean of the accelerometer's readings (its estimated bias removed) stays under
``stall_accel`` in magnitude is a body held by something. Held is not yet standing: a
robot sliding along an obstacle's face at 0.3-0.5 m/s, its full force pushing partly
into it, reads the same (the one-hour soak: agent 13, 1.3 m off in its dead reckoning,
along the east face of thesis_shape_1's obstacle at x = 35 m). What tells them apart is the stop:
a body that stopped decelerated first, and the filter integrated that, so its velocity
estimate is near zero; a sliding one still holds its speed. The brain therefore asks
its filter (``Localizer.stood_still``: the zero-velocity update only within the
innovation gate), and only if it agrees the robot counts as stalled: the update stops
the estimate running and lets the filter learn the bias, the velocity loop's integral
(wound up against the obstacle) is cleared, and the robot sidesteps: for
``stall_sidestep_s`` its setpoint turns 90 degrees counter-clockwise, always the same
way, so two robots pushing into each other head-on pass each other and a robot at a
wall slides along it.

A robot with no accelerometer (the hardware agent: its poses come from the camera)
never calls ``imu`` and never stalls.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

SATURATED = 0.95   # a force at least this share of the limit is at the limit


class StallParams(Protocol):
    """The brain's stall parameters (``BrainConfig``; live: read at every use)."""

    stall_window_s: float    # s, 0: off
    stall_accel: float       # m/s^2
    stall_sidestep_s: float  # s


class StallDetector:
    """Judges, once per ``stall_window_s`` of force at its limit, whether the body
    stands."""

    def __init__(self, force_limit: float | None, params: StallParams) -> None:
        """``force_limit`` (N; None: off)."""
        limit = SATURATED * force_limit if force_limit is not None else math.inf
        self._limit_sq = limit * limit
        self.params = params
        self.count = 0                          # stalls taken, once per stretch
        self._since: float | None = None        # start of the window being judged
        self._sum = np.zeros(2)                 # of the readings in the window
        self._samples = 0                       # (both reset when a window opens)
        self._stood = False                     # the last judgement, as taken
        self._sidestep_until = -math.inf

    def force(self, t: float, force: np.ndarray) -> None:
        """The force commanded at ``t`` (N, map frame), every control step: a few float
        operations, no allocation (it runs at 50 Hz for every agent)."""
        fx, fy = float(force[0]), float(force[1])
        if fx * fx + fy * fy < self._limit_sq or self.params.stall_window_s <= 0.0:
            self._since = None
            self._stood = False
        elif self._since is None:
            self._open(t)

    def imu(self, t: float, accel: np.ndarray, bias: np.ndarray) -> bool:
        """One accelerometer sample at ``t`` (m/s^2, map frame) and the filter's bias
        estimate. True when it ends a window at the force limit that the body did not
        accelerate in: the caller checks its filter agrees and says so with ``stands``."""
        if self._since is None:
            return False
        self._sum += accel
        self._sum -= bias
        self._samples += 1
        if t - self._since < self.params.stall_window_s:
            return False
        mean = self._sum / self._samples
        standing = math.hypot(float(mean[0]), float(mean[1])) < self.params.stall_accel
        self._stood = self._stood and standing
        self._open(t)
        return standing

    def _open(self, t: float) -> None:
        """Start a window to judge at ``t``."""
        self._since = t
        self._sum.fill(0.0)
        self._samples = 0

    def stands(self, t: float, taken: bool) -> None:
        """What the caller made of a judgement of standing at ``t``: ``taken`` if its
        filter agreed and took the zero-velocity update (a stall, counted once per
        stretch, and a sidestep); not taken when the filter still holds a speed (the
        body slides along an obstacle)."""
        if taken:
            if not self._stood:
                self.count += 1
            self._sidestep_until = t + self.params.stall_sidestep_s
        self._stood = taken

    def sidestepping(self, t: float) -> bool:
        """Whether the setpoint is turned aside at ``t``."""
        return t < self._sidestep_until

    def steer(self, t: float, setpoint: np.ndarray) -> np.ndarray:
        """``setpoint`` turned 90 degrees counter-clockwise while sidestepping."""
        if not self.sidestepping(t):
            return setpoint
        return np.array([-setpoint[1], setpoint[0]])
