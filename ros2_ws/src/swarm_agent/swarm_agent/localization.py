"""Localization of one agent with lost / return-to-home modes (thesis 3.1.1-3.1.4).

``predict`` runs at the IMU rate, ``localize`` at every localization tick (3 s in the
thesis): with at least three beacon neighbours the agent trilaterates and updates its
Kalman filter (NORMAL); otherwise it counts a miss: LOST at the first, RETURN_HOME
after three in a row (3.1.3), back to NORMAL as soon as it localizes again. Beacons
update from their GPS fixes instead. Bad measurements (NaN, degenerate geometry) count
as a miss; nothing raises into the agent loop.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import enum
import logging

import numpy as np

from swarm_agent.kalman import KalmanFilter
from swarm_agent.trilateration import DegenerateGeometryError, trilaterate

LOG = logging.getLogger(__name__)
MG = 9.80665e-3  # m/s^2 per milli-g


class Mode(enum.IntEnum):
    """Localization modes; numbers equal swarm_msgs/AgentState MODE_*."""

    NORMAL = 0
    LOST = 1
    RETURN_HOME = 2


@dataclass
class LocalizationConfig:
    """Thesis 4.2 defaults."""

    period_s: float = 3.0
    accel_noise_std: float = 0.01         # m/s^2
    accel_bias_max: float = 0.1 * MG      # m/s^2
    min_beacons: int = 3
    misses_before_home: int = 3
    initial_position_std: float = 1.0     # m
    max_residual: float = 3.0             # m: worse trilaterations are rejected
    gate: float = 13.8                    # chi-square (2 dof, 99.9 %) innovation gate
    max_gated: int = 3                    # after this many gated fixes in a row, accept


class Localizer:
    """Kalman filter + trilateration + modes for one agent."""

    def __init__(self, config: LocalizationConfig, initial_position,
                 initial_velocity=(0.0, 0.0), home=None) -> None:
        self.config = config
        self.kf = KalmanFilter(initial_position, initial_velocity,
                               position_std=config.initial_position_std,
                               accel_noise_std=config.accel_noise_std,
                               accel_bias_std=config.accel_bias_max)
        self.mode = Mode.NORMAL
        self.missed_localizations = 0
        self.home = np.asarray(home if home is not None else initial_position, float)
        self._t: float | None = None
        self.stats = {'localizations': 0, 'misses': 0, 'rejected': 0, 'gated': 0}
        self._gated_in_row = 0

    @property
    def position(self) -> np.ndarray:
        return self.kf.x[:2]

    @property
    def velocity(self) -> np.ndarray:
        return self.kf.x[2:4]

    @property
    def position_std(self) -> float:
        """Standard deviation of the position estimate (m, mean of the two axes)."""
        p = self.kf.P
        return float(np.sqrt(max(0.5 * (p[0, 0] + p[1, 1]), 0.0)))

    @property
    def covariance(self) -> np.ndarray:
        return self.kf.P[:4, :4]

    def predict(self, t: float, accel) -> None:
        """IMU sample at time ``t`` (map-frame acceleration, m/s^2)."""
        if self._t is not None:
            self.kf.predict(t - self._t, accel)
        self._t = t

    def set_state(self, position, velocity, position_std: float,
                  velocity_std: float) -> None:
        """Overwrite the estimate with a direct measurement of it (hardware: camera poses).

        Without an IMU there is no prediction step; the overhead camera measures the
        position to about a centimetre and its displacement gives the velocity.
        """
        kf = self.kf
        kf.x = np.zeros_like(kf.x)
        kf.x[:2] = np.asarray(position, float)
        kf.x[2:4] = np.asarray(velocity, float)
        variances = np.zeros(len(kf.x))
        variances[:2] = position_std ** 2
        variances[2:4] = velocity_std ** 2
        variances[4:] = kf.P.diagonal()[4:]
        kf.P = np.diag(variances)
        self.mode = Mode.NORMAL
        self.missed_localizations = 0

    def gps_update(self, t: float, position, std: float) -> None:
        """Absolute fix (beacons; camera poses on hardware)."""
        self.kf.update_position(position, np.eye(2) * std ** 2)
        self.mode = Mode.NORMAL
        self.missed_localizations = 0

    def localize(self, t: float, beacons: Sequence[tuple[np.ndarray, float, float]],
                 displacement=(0.0, 0.0)) -> Mode:
        """Localization tick: (beacon position, range, range std) per beacon neighbour.

        The ranges may be older than the tick (TOA ranging runs at its own rate):
        ``displacement`` is the agent's own dead-reckoned motion since they were
        measured, so the fix is solved where the agent was and moved to where it is.
        Between two fixes the IMU integration drifts by millimetres (3.1.4), while a
        robot at 0.5 m/s moves a metre in two seconds.
        """
        shift = np.asarray(displacement, dtype=float)
        usable = [(np.asarray(p, float), float(r), float(s)) for p, r, s in beacons
                  if np.all(np.isfinite(p)) and np.isfinite(r) and np.isfinite(s) and s > 0]
        if len(usable) >= self.config.min_beacons:
            pos = np.array([u[0] for u in usable])
            rng = np.array([u[1] for u in usable])
            std = float(np.sqrt(np.mean([u[2] ** 2 for u in usable])))
            try:
                fix = trilaterate(pos, rng, initial=self.position - shift, range_std=std)
            except (DegenerateGeometryError, ValueError) as exc:
                LOG.debug('trilateration rejected: %s', exc)
                self.stats['rejected'] += 1
            else:
                z = fix.position + shift
                if (fix.residual <= self.config.max_residual
                        and self.kf.innovation_distance(z, fix.covariance) > self.config.gate
                        and self._gated_in_row < self.config.max_gated):
                    # A fix far outside the filter's and the fix's own uncertainty (a
                    # mirror solution, a beacon that moved unannounced): skip it, but
                    # only a few times in a row, in case the filter is the one wrong.
                    self._gated_in_row += 1
                    self.stats['gated'] += 1
                    return self.mode
                if fix.residual <= self.config.max_residual:
                    self._gated_in_row = 0
                    self.kf.update_position(z, fix.covariance)
                    self.mode = Mode.NORMAL
                    self.missed_localizations = 0
                    self.stats['localizations'] += 1
                    return self.mode
                self.stats['rejected'] += 1
        self.missed_localizations += 1
        self.stats['misses'] += 1
        home = self.missed_localizations >= self.config.misses_before_home
        self.mode = Mode.RETURN_HOME if home else Mode.LOST
        return self.mode
