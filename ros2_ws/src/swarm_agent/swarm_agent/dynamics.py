"""Headless dynamics for fast evaluation: planar point masses with Table 4.1 friction.

Not a copy of pybullet: each robot is a point mass m with fluid friction -mu_2 v and
Coulomb dry friction mu_1 m g opposing the motion, integrated semi-implicitly, all
robots at once. Dry friction is applied as an impulse bounded by mu_1 g dt, so a robot
at rest stays at rest until the applied force exceeds mu_1 m g (static friction) and a
sliding robot stops exactly instead of chattering around zero velocity.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

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
        forces = np.nan_to_num(np.asarray(forces, dtype=float).reshape(-1, 2))
        v0 = self.velocities
        # Applied force, then Coulomb dry friction as an impulse bounded by mu_1 g dt,
        # then fluid friction implicitly (unconditionally stable). Dry friction acts
        # before the implicit division so that a constant force F gives exactly the
        # continuous terminal speed (F - mu_1 m g) / mu_2.
        v = v0 + dt * forces / self.mass[:, None]
        speed = np.linalg.norm(v, axis=1)
        dv_max = self.dry * self.gravity * dt
        stopping = speed <= dv_max
        scale = np.where(stopping, 0.0, 1.0 - dv_max / np.maximum(speed, 1e-12))
        v = v * scale[:, None] / (1.0 + dt * self.fluid / self.mass)[:, None]
        self._accel = (v - v0) / dt
        self.velocities = v
        self.positions = self.positions + v * dt

    def accelerations(self) -> np.ndarray:
        """True accelerations of the last step (what an ideal accelerometer measures)."""
        return self._accel.copy()
