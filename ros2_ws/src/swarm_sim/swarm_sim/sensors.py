"""Sensor noise models of thesis 4.2, shared by sim_node and the headless evaluator.

- IMU: true acceleration + a per-robot constant bias drawn uniformly in a disc of
  radius ``bias_max`` (0.1 mg) + white noise of ``noise_std`` (0.01 m/s^2) per axis.
- GPS (beacons only): true position + Gaussian noise of ``std`` (2 m) per axis.
TOA ranges come from the radio medium (``RadioMedium.toa_ranges``).
"""

from __future__ import annotations

import numpy as np

MG = 9.80665e-3


class ImuModel:
    """Accelerometers of N robots."""

    def __init__(self, n: int, rng: np.random.Generator, bias_max: float = 0.1 * MG,
                 noise_std: float = 0.01) -> None:
        self.rng = rng
        self.noise_std = noise_std
        angle = rng.uniform(0.0, 2.0 * np.pi, n)
        radius = bias_max * np.sqrt(rng.uniform(0.0, 1.0, n))
        self.bias = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])

    def measure(self, true_accel) -> np.ndarray:
        """Measured accelerations (N, 2)."""
        true_accel = np.asarray(true_accel, dtype=float).reshape(-1, 2)
        return true_accel + self.bias + self.rng.normal(0.0, self.noise_std, true_accel.shape)


class GpsModel:
    """Absolute position fixes of the beacons."""

    def __init__(self, rng: np.random.Generator, std: float = 2.0) -> None:
        self.rng = rng
        self.std = std

    def measure(self, true_position) -> tuple[np.ndarray, float]:
        """(fix, std) for one robot."""
        return np.asarray(true_position, float) + self.rng.normal(0.0, self.std, 2), self.std
