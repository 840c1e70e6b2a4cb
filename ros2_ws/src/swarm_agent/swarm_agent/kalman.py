"""Kalman filter of the local positioning system (thesis 3.1.4, eqs. 3.28-3.44).

State x = [x, y, vx, vy] in the map frame. The accelerometer is the input of the
propagation (eq. 3.30): x+ = F x + G a with F = [[I, dt I], [0, I]], G = [[dt^2/2 I],
[dt I]]. Its white noise (0.01 m/s^2 in the thesis) and a bias allowance (up to 0.1 mg)
enter the process noise Q = G G^T (sigma_a^2 + sigma_b^2). Position fixes (trilateration,
or GPS for beacons) update the filter with their own covariance R.
"""

from __future__ import annotations

import numpy as np


class KalmanFilter:
    """Constant-acceleration-input filter over [x, y, vx, vy]."""

    def __init__(self, position, velocity=(0.0, 0.0), position_std: float = 1.0,
                 velocity_std: float = 0.1, accel_noise_std: float = 0.01,
                 accel_bias_std: float = 0.001) -> None:
        self.x = np.r_[np.asarray(position, float), np.asarray(velocity, float)]
        self.P = np.diag([position_std ** 2] * 2 + [velocity_std ** 2] * 2)
        self.q = accel_noise_std ** 2 + accel_bias_std ** 2
        self._dt: float | None = None  # the IMU period is fixed: F, G, Q built once per dt

    def _model(self, dt: float) -> None:
        i2 = np.eye(2)
        self._f = np.block([[i2, dt * i2], [np.zeros((2, 2)), i2]])
        self._g = np.vstack([0.5 * dt * dt * i2, dt * i2])
        self._q = self.q * (self._g @ self._g.T)
        self._dt = dt

    def predict(self, dt: float, accel) -> None:
        """Propagate by ``dt`` seconds with the measured acceleration (eqs. 3.30-3.33)."""
        if dt <= 0:
            return
        if self._dt is None or abs(dt - self._dt) > 1e-9:
            self._model(dt)
        # x+ = F x + G a and P+ = F P F^T + Q written out for F = [[I, dt I], [0, I]]:
        # the same algebra as the matrix products, at a fifth of their cost at 50 Hz.
        ax, ay = float(accel[0]), float(accel[1])
        x = self.x
        h = 0.5 * dt * dt
        self.x = np.array([x[0] + dt * x[2] + h * ax, x[1] + dt * x[3] + h * ay,
                           x[2] + dt * ax, x[3] + dt * ay])
        p = self.P
        pv = p[:, 2:]                      # columns of the velocity block
        p = p.copy()
        p[:, :2] += dt * pv                # P F^T
        p[:2, :] += dt * p[2:, :]          # F (P F^T)
        self.P = p + self._q

    def innovation_distance(self, z, R) -> float:
        """Squared Mahalanobis distance of a position fix from the prediction.

        Chi-square with 2 degrees of freedom when the filter and the fix are consistent
        (99.9 % of consistent fixes fall below 13.8).
        """
        s = self.P[:2, :2] + np.asarray(R, float)
        y = np.asarray(z, float) - self.x[:2]
        return float(y @ np.linalg.solve(s, y))

    def update_position(self, z, R) -> None:
        """Measurement update with a position fix z (2,) of covariance R (eqs. 3.34-3.44)."""
        h = np.hstack([np.eye(2), np.zeros((2, 2))])
        s = h @ self.P @ h.T + np.asarray(R, float)
        k = self.P @ h.T @ np.linalg.inv(s)
        self.x = self.x + k @ (np.asarray(z, float) - h @ self.x)
        ikh = np.eye(4) - k @ h
        self.P = ikh @ self.P @ ikh.T + k @ np.asarray(R, float) @ k.T  # Joseph form
