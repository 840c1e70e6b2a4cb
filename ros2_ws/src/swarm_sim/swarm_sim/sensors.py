"""Sensor noise models of thesis 4.2, shared by sim_node and the headless evaluator.

- IMU: true acceleration + a per-robot constant bias drawn uniformly in a disc of
  radius ``bias_max`` (0.1 mg) + white noise of ``noise_std`` (0.01 m/s^2) per axis.
- GPS (beacons only): true position + Gaussian noise of ``std`` (2 m) per axis.
- Trilateration fix, thesis profile (``TrilaterationFixModel``, used by the localization
  study): true position + Gaussian noise of ``std`` (2 m) per axis, as 4.2 simulates it.
- Proximity (beyond the thesis): every robot within ``range_m`` (3 m) of another is
  seen by it as an offset (its centre minus the observer's, map frame) with Gaussian
  noise of ``noise_std`` (2 cm) per axis, plus its coverage radius. This is what a ring
  of ultrasonic or infrared rangers, or a lidar whose returns are clustered into
  bodies, gives a robot: relative positions accurate to centimetres, where the
  neighbours' own broadcast estimates are off by the localization error (about 0.5 m).
  Collision avoidance needs the former (``swarm_agent.setpoint.avoid_collisions``).
  Occlusion by obstacles or other robots is not modelled.
TOA ranges come from the radio medium (``RadioMedium.toa_ranges``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

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


class TrilaterationFixModel(GpsModel):
    """The trilateration output as the thesis simulates it (3.1.4 eq. 3.32, 4.2): the
    true position plus Gaussian noise of ``std`` (2 m) per axis, whenever the agent has
    the three beacon neighbours a trilateration needs. The alternative, TOA ranges to
    the beacons' broadcast estimates trilaterated by the agent, is what the simulator
    and the ROS system run (``RadioMedium.toa_ranges``)."""


@dataclass(frozen=True)
class ProximityScan:
    """What every robot's proximity sensor saw at one instant.

    Detections are grouped by observer: ``observers`` (M,) robot indices in ascending
    order, ``offsets`` (M, 2) neighbour centre minus observer centre (m, map frame,
    noisy), ``radii`` (M,) the neighbours' coverage radii.
    """

    observers: np.ndarray
    offsets: np.ndarray
    radii: np.ndarray

    def of(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """(offsets (k, 2), radii (k,)) seen by robot index ``i``."""
        (lo,), (hi,) = self.rows_of([i])
        return self.offsets[lo:hi], self.radii[lo:hi]

    def rows_of(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(starts, ends): robot ``indices[k]`` saw the rows ``starts[k]:ends[k]``."""
        indices = np.asarray(indices)
        return (np.searchsorted(self.observers, indices),
                np.searchsorted(self.observers, indices + 1))


class ProximityModel:
    """Proximity sensors of N robots; see the module docstring."""

    def __init__(self, rng: np.random.Generator, range_m: float = 3.0,
                 noise_std: float = 0.02) -> None:
        if not range_m > 0 or not noise_std >= 0:
            raise ValueError(f'proximity range_m must be positive and noise_std not negative, '
                             f'got {range_m} and {noise_std}')
        self.rng = rng
        self.range_m = range_m
        self.noise_std = noise_std

    def measure(self, positions, radii, alive=None) -> ProximityScan:
        """Scan of every living robot; ``positions`` (N, 2), ``radii`` (N,)."""
        positions = np.asarray(positions, dtype=float).reshape(-1, 2)
        radii = np.asarray(radii, dtype=float)
        living = np.arange(len(positions)) if alive is None else np.flatnonzero(alive)
        # A k-d tree finds the pairs in range in O(N log N); both ends see each other.
        pairs = cKDTree(positions[living]).query_pairs(self.range_m, output_type='ndarray')
        if len(pairs) == 0:
            return ProximityScan(np.zeros(0, int), np.zeros((0, 2)), np.zeros(0))
        a, b = living[pairs[:, 0]], living[pairs[:, 1]]
        observers = np.concatenate([a, b])
        seen = np.concatenate([b, a])
        order = np.argsort(observers, kind='stable')
        observers, seen = observers[order], seen[order]
        offsets = positions[seen] - positions[observers]
        offsets = offsets + self.rng.normal(0.0, self.noise_std, offsets.shape)
        return ProximityScan(observers, offsets, radii[seen])
