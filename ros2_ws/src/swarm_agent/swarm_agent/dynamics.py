"""Headless dynamics for fast evaluation: planar point masses with Table 4.1 friction.

Not a copy of pybullet: each robot is a point mass m with fluid friction -mu_2 v and
Coulomb dry friction mu_1 m g opposing the motion, integrated semi-implicitly, all
robots at once. Dry friction is applied as an impulse bounded by mu_1 g dt, so a robot
at rest stays at rest until the applied force exceeds mu_1 m g (static friction) and a
sliding robot stops exactly instead of chattering around zero velocity.
"""

from __future__ import annotations

from collections.abc import Sequence
import math

import numpy as np

from swarm_common.jit import helper, kernel
from swarm_common.robot_types import GRAVITY, RobotType


class PointMassSwarm:
    """N point masses; see the module docstring."""

    def __init__(self, types: Sequence[RobotType], positions, velocities=None, *,
                 gravity: float = GRAVITY) -> None:
        self.mass = np.array([t.mass for t in types], dtype=float)
        self.fluid = np.array([t.fluid_friction for t in types], dtype=float)
        self.dry = np.array([t.dry_friction for t in types], dtype=float)
        self.gravity = gravity
        self.positions = np.array(positions, dtype=float).reshape(-1, 2)
        self.velocities = np.zeros_like(self.positions) if velocities is None else \
            np.array(velocities, dtype=float).reshape(-1, 2)
        self._accel = np.zeros_like(self.positions)

    def step(self, dt: float, forces) -> None:
        """Advance by ``dt`` under the applied forces (N, map frame), shape (N, 2)."""
        forces = np.asarray(forces, dtype=float).reshape(-1, 2)
        self.positions, self.velocities, self._accel = _step(
            self.positions, self.velocities, forces, self.mass, self.fluid, self.dry,
            float(self.gravity), float(dt))

    def accelerations(self) -> np.ndarray:
        """True accelerations of the last step (what an ideal accelerometer measures)."""
        return self._accel.copy()


@helper
def _finite(x: float) -> float:
    """``x``, with NaN as 0 and an infinity as the largest float of its sign."""
    if x != x:
        return 0.0
    if x > _LARGEST:
        return _LARGEST
    if x < -_LARGEST:
        return -_LARGEST
    return x


_LARGEST = 1.7976931348623157e308     # np.finfo(float).max


@kernel(np.zeros((2, 2)), np.zeros((2, 2)), np.ones((2, 2)), np.ones(2), np.ones(2),
        np.full(2, 0.1), 9.81, 0.02)
def _step(positions: np.ndarray, velocities: np.ndarray, forces: np.ndarray,
          mass: np.ndarray, fluid: np.ndarray, dry: np.ndarray, gravity: float,
          dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One step of every point mass: (positions, velocities, accelerations) after it.

    Applied force, then Coulomb dry friction as an impulse bounded by mu_1 g dt, then
    fluid friction implicitly (unconditionally stable). Dry friction acts before the
    implicit division so that a constant force F gives exactly the continuous terminal
    speed (F - mu_1 m g) / mu_2. A force that is not a number is none, an infinite one
    the largest float (``np.nan_to_num``).
    """
    n = positions.shape[0]
    new_p, new_v, accel = np.empty((n, 2)), np.empty((n, 2)), np.empty((n, 2))
    for i in range(n):
        vx = velocities[i, 0] + dt * _finite(forces[i, 0]) / mass[i]
        vy = velocities[i, 1] + dt * _finite(forces[i, 1]) / mass[i]
        speed = math.sqrt(vx * vx + vy * vy)
        dv_max = dry[i] * gravity * dt
        scale = 0.0 if speed <= dv_max else 1.0 - dv_max / max(speed, 1e-12)
        damp = 1.0 + dt * fluid[i] / mass[i]
        vx, vy = vx * scale / damp, vy * scale / damp
        accel[i, 0] = (vx - velocities[i, 0]) / dt
        accel[i, 1] = (vy - velocities[i, 1]) / dt
        new_v[i, 0], new_v[i, 1] = vx, vy
        new_p[i, 0] = positions[i, 0] + vx * dt
        new_p[i, 1] = positions[i, 1] + vy * dt
    return new_p, new_v, accel
