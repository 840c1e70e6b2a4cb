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

    def predict(self, dt: float, accel) -> None:
        """Propagate by ``dt`` seconds with the measured acceleration (eqs. 3.30-3.33)."""
        if dt <= 0:
            return
        i2 = np.eye(2)
        f = np.block([[i2, dt * i2], [np.zeros((2, 2)), i2]])
        g = np.vstack([0.5 * dt * dt * i2, dt * i2])
        self.x = f @ self.x + g @ np.asarray(accel, float)
        self.P = f @ self.P @ f.T + self.q * (g @ g.T)

    def update_position(self, z, R) -> None:
        """Measurement update with a position fix z (2,) of covariance R (eqs. 3.34-3.44)."""
        h = np.hstack([np.eye(2), np.zeros((2, 2))])
        s = h @ self.P @ h.T + np.asarray(R, float)
        k = self.P @ h.T @ np.linalg.inv(s)
        self.x = self.x + k @ (np.asarray(z, float) - h @ self.x)
        ikh = np.eye(4) - k @ h
        self.P = ikh @ self.P @ ikh.T + k @ np.asarray(R, float) @ k.T  # Joseph form
