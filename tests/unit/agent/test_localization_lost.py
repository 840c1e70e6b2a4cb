"""A LOST agent's ranges correct its position, not its velocity or bias
(swarm_agent.localization, ``lost_position_only``; swarm_agent.kalman,
``update_ranges(position_only=True)``)."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_agent.kalman import KalmanFilter
from swarm_agent.localization import LocalizationConfig, Localizer, Mode

BEACONS = np.array([[12.0, 10.0], [12.0, -10.0]])
IMU_DT = 0.02


def _filter() -> KalmanFilter:
    kf = KalmanFilter((0.5, -0.4), (0.3, 0.1), position_std=1.0, velocity_std=0.05)
    # Correlated, as after dead reckoning: position errors grow from velocity errors.
    for _ in range(200):
        kf.predict(IMU_DT, (0.0, 0.0))
    return kf


def test_a_position_only_update_leaves_velocity_and_bias_alone():
    """The gain's velocity and bias rows are zero: those states and their covariance
    stay as they were (the Joseph form's (I - K H) is the identity on their rows), the
    position moves towards the ranges and its covariance shrinks, and P stays a
    covariance (symmetric, positive definite)."""
    kf = _filter()
    x0, p0 = kf.x.copy(), kf.P.copy()
    truth = np.array([4.0, -2.0])
    ranges = np.linalg.norm(BEACONS - truth, axis=1)
    kf.update_ranges(BEACONS, ranges, np.full(2, 0.3 ** 2), position_only=True)
    np.testing.assert_array_equal(kf.x[2:], x0[2:])
    np.testing.assert_allclose(kf.P[2:, 2:], p0[2:, 2:], atol=1e-15)
    assert np.linalg.norm(kf.x[:2] - truth) < np.linalg.norm(x0[:2] - truth)
    assert np.trace(kf.P[:2, :2]) < np.trace(p0[:2, :2])
    np.testing.assert_allclose(kf.P, kf.P.T)
    assert np.linalg.eigvalsh(kf.P)[0] > 0.0


def _drive_lost(position_only: bool, drift: float = 0.03, ticks: int = 15) -> Localizer:
    """An agent driving east at 0.3 m/s (its IMU exact: the true acceleration is 0)
    ranges every 3 s to two beacons whose advertised positions drift north at ``drift``
    m/s, as a beacon's own error wanders while it drives on 2 m GPS. Noise-free
    ranges to the true beacons, each with 0.5 m of advertised anchor deviation."""
    config = LocalizationConfig(initial_position_std=0.3, lost_position_only=position_only)
    v = np.array([0.3, 0.0])
    loc = Localizer(config, (0.0, 0.0), initial_velocity=v)
    t = 0.0
    for k in range(1, ticks + 1):
        while t < 3.0 * k - 1e-9:
            t += IMU_DT
            loc.predict(t, (0.0, 0.0))
        ranges = np.linalg.norm(BEACONS - v * t, axis=1)
        advertised = BEACONS + np.array([0.0, drift * t])
        loc.localize(t, [(b, float(r), 0.5, 0.5) for b, r in zip(advertised, ranges)])
    return loc


@pytest.mark.parametrize('position_only', [True, False])
def test_two_drifting_beacons_do_not_steer_a_lost_agents_velocity(position_only):
    """Two beacons cannot tell their own drifting error from the agent's motion: taken
    as velocity, 45 s of such ranges leave the estimate about 0.04 m/s off (what the
    shape study's worst agents showed before their first localization), and dead
    reckoning carries that error on. With the ranges kept to the position the velocity
    stays the IMU's (exact here); the position follows the beacons either way."""
    loc = _drive_lost(position_only)
    assert loc.mode == Mode.LOST
    error = float(np.hypot(*(loc.velocity - (0.3, 0.0))))
    if position_only:
        assert error < 1e-9
    else:
        assert error > 0.02


def test_three_beacons_still_correct_the_velocity():
    """With three beacons the tick is a localization and the full update applies: a
    velocity estimate 0.1 m/s off is pulled towards the truth over five ticks."""
    truth_v = np.array([0.3, 0.0])
    beacons = np.vstack([BEACONS, [[-12.0, 0.0]]])
    loc = Localizer(LocalizationConfig(initial_position_std=0.3), (0.0, 0.0),
                    initial_velocity=(0.3, 0.1))
    loc.kf.P[2:4, 2:4] = np.eye(2) * 0.1 ** 2
    t = 0.0
    for k in range(1, 6):
        while t < 3.0 * k - 1e-9:
            t += IMU_DT
            loc.predict(t, (0.0, 0.0))
        ranges = np.linalg.norm(beacons - truth_v * t, axis=1)
        loc.localize(t, [(b, float(r), 0.1, 0.05) for b, r in zip(beacons, ranges)])
    assert loc.mode == Mode.NORMAL
    assert float(np.hypot(*(loc.velocity - truth_v))) < 0.03
