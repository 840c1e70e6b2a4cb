"""Local positioning system (thesis 3.1.1-3.1.4): trilateration, Kalman filter, modes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from swarm_agent.kalman import KalmanFilter
from swarm_agent.localization import LocalizationConfig, Localizer, MG, Mode
from swarm_agent.trilateration import (
    crlb,
    DegenerateGeometryError,
    gauss_newton,
    geometry_rank,
    trilaterate,
)

# The filter's prediction and update are kernels (swarm_agent.kalman): compiled and as source.
pytestmark = pytest.mark.usefixtures('kernels')
TRIANGLE = np.array([[0.0, 0.0], [20.0, 0.0], [5.0, 18.0]])
PENTAGON = 12.0 * np.array([[np.cos(a), np.sin(a)]
                            for a in np.linspace(0, 2 * np.pi, 5, endpoint=False)])


def _ranges(beacons: np.ndarray, p) -> np.ndarray:
    return np.linalg.norm(beacons - np.asarray(p, float), axis=1)


# --------------------------------------------------------------------- trilateration
@pytest.mark.parametrize('p', [(7.0, 6.0), (-3.0, 25.0), (0.0, 0.0), (19.0, -4.0)])
def test_three_beacons_noiseless_exact(p):
    """Eqs. 3.8-3.12: the linear system of 3 beacons has the true position as solution."""
    fix = trilaterate(TRIANGLE, _ranges(TRIANGLE, p))
    np.testing.assert_allclose(fix.position, p, atol=1e-9)
    assert fix.method == 'linear+gauss-newton'
    assert fix.residual < 1e-9


def test_more_beacons_least_squares_noiseless_exact():
    """Eq. 3.17: with n > 3 beacons the least-squares solution is exact without noise."""
    beacons = np.vstack([PENTAGON, [[30.0, 2.0], [-4.0, -20.0]]])
    fix = trilaterate(beacons, _ranges(beacons, (3.5, -2.0)))
    np.testing.assert_allclose(fix.position, (3.5, -2.0), atol=1e-9)
    assert fix.method == 'least-squares+gauss-newton'


def _linear_only(beacons: np.ndarray, ranges: np.ndarray) -> np.ndarray:
    """Eqs. 3.8-3.17 alone (reference for the refinement test)."""
    a = 2.0 * (beacons[-1] - beacons[:-1])
    b = (ranges[:-1] ** 2 - ranges[-1] ** 2 - np.sum(beacons[:-1] ** 2, axis=1)
         + np.sum(beacons[-1] ** 2))
    return np.linalg.lstsq(a, b, rcond=None)[0]


def test_gauss_newton_refines_the_linear_estimate():
    """Eqs. 3.20-3.27 minimise the range residuals, which the linearised system does not.

    Subtracting squared ranges weights the beacons unequally, so with noise the linear
    solution is not the least-squares fit of the ranges; the refined one is, and it is
    closer to the truth on average.
    """
    rng = np.random.default_rng(3)
    truth = np.array([2.0, 3.0])
    beacons = np.vstack([PENTAGON, [[25.0, 25.0]]])
    lin_err, gn_err = [], []
    for _ in range(500):
        r = _ranges(beacons, truth) + rng.normal(0.0, 0.5, len(beacons))
        lin = _linear_only(beacons, r)
        fix = trilaterate(beacons, r, range_std=0.5)
        cost = lambda p, r=r: np.sum((_ranges(beacons, p) - r) ** 2)  # noqa: E731
        assert cost(fix.position) <= cost(lin) + 1e-12
        lin_err.append(np.sum((lin - truth) ** 2))
        gn_err.append(np.sum((fix.position - truth) ** 2))
    assert np.mean(gn_err) < np.mean(lin_err)


def test_gauss_newton_converges_from_a_far_start():
    p = gauss_newton(PENTAGON, _ranges(PENTAGON, (4.0, -1.0)), np.array([-8.0, 9.0]),
                     iterations=30)
    np.testing.assert_allclose(p, (4.0, -1.0), atol=1e-6)


@pytest.mark.parametrize('beacons', [
    [[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [35.0, 0.0]],      # collinear
    [[0.0, 0.0], [5.0, 5.0], [10.0, 10.0]],                    # collinear, diagonal
    [[3.0, 4.0], [3.0, 4.0], [3.0, 4.0]],                      # identical
    [[0.0, 0.0], [10.0, 0.0]],                                 # too few
])
def test_degenerate_geometry_raises(beacons):
    """Collinear beacons leave the mirror image ambiguous; identical ones fix nothing."""
    beacons = np.asarray(beacons)
    with pytest.raises(DegenerateGeometryError):
        trilaterate(beacons, _ranges(beacons, (4.0, 7.0)))


def test_identical_beacons_raise_even_with_a_prior():
    """A prior settles a mirror ambiguity, not a direction no range constrains."""
    beacons = np.array([[3.0, 4.0]] * 3)
    with pytest.raises(DegenerateGeometryError, match='one direction'):
        trilaterate(beacons, _ranges(beacons, (4.0, 7.0)), initial=(0.0, 0.0))


def test_collinear_beacons_with_a_prior_pick_the_near_side():
    """With a propagated estimate Gauss-Newton resolves the mirror ambiguity."""
    beacons = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]])
    assert geometry_rank(beacons) == 1 and geometry_rank(TRIANGLE) == 2
    fix = trilaterate(beacons, _ranges(beacons, (4.0, 7.0)), initial=(3.0, 5.0))
    np.testing.assert_allclose(fix.position, (4.0, 7.0), atol=1e-6)
    assert fix.method == 'gauss-newton (rank-deficient)'


@pytest.mark.parametrize(('ranges', 'match'), [
    ([1.0, np.nan, 3.0], 'finite'),
    ([1.0, np.inf, 3.0], 'finite'),
    ([1.0, -2.0, 3.0], 'non-negative'),
    ([1.0, 2.0], r'\(n,2\)'),
])
def test_bad_ranges_rejected(ranges, match):
    with pytest.raises(ValueError, match=match):
        trilaterate(TRIANGLE, ranges)


def test_nan_beacon_position_rejected():
    beacons = TRIANGLE.copy()
    beacons[1, 0] = np.nan
    with pytest.raises(ValueError, match='finite'):
        trilaterate(beacons, [1.0, 2.0, 3.0])


def test_monte_carlo_error_reaches_the_crlb():
    """Gauss-Newton is the ML estimate: its RMS error meets the Cramer-Rao bound.

    sigma = 0.3 m, five beacons 12 m around the agent; ratio RMS / sqrt(trace CRLB).
    For Gaussian errors of covariance C the squared error norm has mean tr C and
    variance 2 tr C^2, so the ratio estimated from n fixes has the standard error
    sqrt(2 tr C^2 / n) / (2 tr C) (0.0079 for n = 4000 and this ring); the band is
    four of them around 1.
    """
    rng = np.random.default_rng(11)
    truth = np.array([1.0, -2.0])
    sigma = 0.3
    n = 4000
    errors = np.array([trilaterate(PENTAGON, _ranges(PENTAGON, truth)
                                   + rng.normal(0.0, sigma, 5), range_std=sigma).position
                       - truth for _ in range(n)])
    bound = crlb(PENTAGON, truth, sigma)
    ratio = float(np.sqrt(np.mean(np.sum(errors ** 2, axis=1)) / np.trace(bound)))
    standard_error = float(np.sqrt(2.0 * np.trace(bound @ bound) / n) / (2.0 * np.trace(bound)))
    print(f'\nRMS error / sqrt(CRLB) = {ratio:.3f} +/- {standard_error:.4f} (n={n}, '
          f'sigma={sigma} m, 5 beacons)')
    assert abs(ratio - 1.0) <= 4.0 * standard_error
    # unbiased to within noise: the mean error's norm has RMS sqrt(tr C / n) (0.004 m)
    bias = float(np.linalg.norm(errors.mean(axis=0)))
    assert bias < 4.0 * np.sqrt(np.trace(bound) / n), bias
    # the covariance the fix reports is the same Fisher information, at the estimate
    fix = trilaterate(PENTAGON, _ranges(PENTAGON, truth), range_std=sigma)
    np.testing.assert_allclose(fix.covariance, bound, rtol=1e-6)


def test_crlb_of_a_ring_and_of_beacons_on_one_side():
    """A ring of n beacons has Fisher information n / (2 sigma^2) I: trace CRLB = 4 sigma^2 / n.

    Beacons all on one side constrain the position across their direction poorly.
    """
    assert np.trace(crlb(PENTAGON, (0.0, 0.0), 0.3)) == pytest.approx(4 * 0.09 / 5)
    one_side = np.array([[10.0, -3.0], [10.0, 0.0], [10.0, 3.0], [11.0, 1.0], [11.0, -1.0]])
    assert np.trace(crlb(one_side, (0.0, 0.0), 0.3)) > 5 * 4 * 0.09 / 5


# --------------------------------------------------------------------- Kalman filter
def test_covariance_decreases_on_update_and_grows_on_predict():
    """Eq. 3.44 (Joseph form): P+ <= P- in the Loewner order; eq. 3.33 adds Q."""
    kf = KalmanFilter((0.0, 0.0), position_std=3.0, velocity_std=0.5, estimate_bias=False)
    p0 = kf.P.copy()
    kf.predict(0.5, (0.0, 0.0))
    # position variance: P_xx + 2 dt P_xv + dt^2 P_vv + Q_xx with P_xv = 0 at the start
    q = (0.01 ** 2 + 0.001 ** 2) * 0.25 * 0.5 ** 4
    assert kf.P[0, 0] == pytest.approx(p0[0, 0] + 0.25 * p0[2, 2] + q)
    assert np.trace(kf.P) > np.trace(p0)
    before = kf.P.copy()
    kf.update_position((1.0, 1.0), np.eye(2) * 4.0)
    assert np.all(np.linalg.eigvalsh(before - kf.P) >= -1e-12)
    assert np.trace(kf.P) < np.trace(before)
    # scalar check of the position variance: 1/P+ = 1/P- + 1/R
    expected = 1.0 / (1.0 / before[0, 0] + 1.0 / 4.0)
    assert kf.P[0, 0] <= expected + 1e-9
    np.testing.assert_allclose(kf.P, kf.P.T)


def test_prediction_is_exact_for_constant_acceleration():
    """Eq. 3.30 integrates a constant input exactly: x = x0 + v0 t + a t^2 / 2."""
    kf = KalmanFilter((1.0, -2.0), velocity=(0.3, 0.1))
    a = np.array([0.05, -0.02])
    for _ in range(40):
        kf.predict(0.25, a)
    t = 10.0
    np.testing.assert_allclose(kf.x[:2], np.array([1.0, -2.0]) + np.array([0.3, 0.1]) * t
                               + 0.5 * a * t * t, atol=1e-12)
    np.testing.assert_allclose(kf.x[2:4], np.array([0.3, 0.1]) + a * t, atol=1e-12)


def test_tracks_constant_acceleration_with_noisy_imu_and_fixes():
    """Thesis noise: IMU 0.01 m/s^2 white + bias at 10 Hz, fixes of 2 m every 3 s.

    The filter starts 5 m off; after a minute the error stays within its own 3-sigma
    and the normalised estimation error squared averages about 2 (the state's position
    dimension), i.e. the filter is consistent.
    """
    rng = np.random.default_rng(5)
    a_true = np.array([0.02, -0.01])
    bias = np.array([0.5, -0.5]) * 0.1 * MG
    nees, errs = [], []
    for trial in range(25):
        x0 = rng.uniform(-5, 5, 2)
        kf = KalmanFilter(x0 + rng.normal(0, 2.0, 2), position_std=2.0, velocity_std=0.1,
                          accel_noise_std=0.01, accel_bias_std=0.1 * MG)
        dt = 0.1
        for k in range(1, 601):  # 60 s
            t = k * dt
            kf.predict(dt, a_true + bias + rng.normal(0, 0.01, 2))
            if k % 30 == 0:
                truth = x0 + 0.5 * a_true * t * t
                kf.update_position(truth + rng.normal(0, 2.0, 2), np.eye(2) * 4.0)
        truth = x0 + 0.5 * a_true * 60.0 ** 2
        e = kf.x[:2] - truth
        errs.append(np.linalg.norm(e))
        nees.append(float(e @ np.linalg.solve(kf.P[:2, :2], e)))
        assert np.linalg.norm(kf.x[2:4] - a_true * 60.0) < 0.3, trial
    assert 1.2 < np.mean(nees) < 3.0, np.mean(nees)
    # 36 m travelled; the estimate is much better than a single 2 m fix
    assert np.sqrt(np.mean(np.square(errs))) < 2.0


# --------------------------------------------------------------------- modes (3.1.3)
def _beacons(p, n: int, std: float = 0.3):
    ring = PENTAGON[:n] if n <= 5 else None
    return [(b, float(np.hypot(*(b - np.asarray(p)))), std) for b in ring]


def test_modes_lost_return_home_and_back():
    """Thesis 3.1.3: LOST below three beacon neighbours, RETURN_HOME at the third miss,
    NORMAL again as soon as a trilateration succeeds (``home_position_std`` 0: the
    thesis's rule, whatever the estimate's uncertainty)."""
    loc = Localizer(LocalizationConfig(home_position_std=0.0), (0.0, 0.0), home=(5.0, 5.0))
    p = (1.0, 1.0)
    assert loc.localize(3.0, _beacons(p, 3)) == Mode.NORMAL
    assert loc.localize(6.0, _beacons(p, 2)) == Mode.LOST
    assert loc.localize(9.0, []) == Mode.LOST
    assert loc.missed_localizations == 2
    assert loc.localize(12.0, _beacons(p, 2)) == Mode.RETURN_HOME
    assert loc.localize(15.0, _beacons(p, 1)) == Mode.RETURN_HOME
    np.testing.assert_allclose(loc.home, (5.0, 5.0))
    assert loc.localize(18.0, _beacons(p, 4)) == Mode.NORMAL
    assert loc.missed_localizations == 0
    # Every tick with ranges updated the filter with them (iterated EKF); those with
    # one or two beacons are misses all the same (3.1.3).
    assert loc.stats == {'localizations': 2, 'misses': 4, 'rejected': 0, 'gated': 0,
                         'relocalizations': 0, 'partial': 0, 'range_updates': 5,
                         'secondary': 0, 'uncertain': 0}
    np.testing.assert_allclose(loc.position, p, atol=0.2)


def _drive(loc: Localizer, bias, ticks: int, beacons, rng, period: float = 3.0,
           velocity=(0.4, 0.1)) -> tuple[list[float], list[Mode]]:
    """A robot driving at constant ``velocity`` from the origin, its IMU biased by
    ``bias`` with 0.01 m/s^2 of noise at 10 Hz, ranges of 0.3 m to ``beacons`` at every
    tick; the error and the mode after each tick."""
    errors, modes, t = [], [], 0.0
    for _ in range(ticks):
        for _ in range(int(round(period / 0.1))):
            t += 0.1
            loc.predict(t, np.asarray(bias) + rng.normal(0.0, 0.01, 2))
        truth = np.asarray(velocity) * t
        ranges = [(b, float(np.hypot(*(b - truth))) + rng.normal(0.0, 0.3), 0.3)
                  for b in beacons]
        modes.append(loc.localize(t, ranges))
        errors.append(float(np.hypot(*(loc.position - truth))))
    return errors, modes


def test_two_beacons_keep_a_lost_agent_on_track():
    """Two beacon neighbours are too few for a trilateration (a miss, LOST), but their
    ranges still bound the dead-reckoning error: 120 s at 0.4 m/s with the full 0.1 mg
    IMU bias drifts by 0.5 b t^2 = 7 m on the IMU alone (the thesis's filter, which
    only uses trilaterations, goes home after three misses, 5 m off by the end), while
    the range updates keep it within a metre and the agent drives on, LOST, to its
    goal."""
    beacons = [np.array([-5.0, 25.0]), np.array([60.0, 20.0])]
    bias = np.array([0.7, -0.7]) * 0.1 * MG
    config = LocalizationConfig(initial_position_std=0.3)
    errors, modes = _drive(Localizer(config, (0.0, 0.0), initial_velocity=(0.4, 0.1)),
                           bias, 40, beacons, np.random.default_rng(3))
    assert set(modes) == {Mode.LOST}
    assert max(errors) < 1.0, max(errors)
    thesis = dataclasses.replace(config, range_updates=False, home_position_std=0.0)
    errors, modes = _drive(Localizer(thesis, (0.0, 0.0), initial_velocity=(0.4, 0.1)),
                           bias, 40, beacons, np.random.default_rng(3))
    assert modes[2:] == [Mode.RETURN_HOME] * 38
    assert errors[-1] > 5.0, errors[-1]


def test_an_agent_without_ranges_goes_home_once_its_estimate_is_uncertain():
    """No beacon at all: LOST, and RETURN_HOME (3.1.3) once three ticks are missed and
    the estimate's worst axis is less certain than ``home_position_std`` (1 m), which
    dead reckoning with the bias allowance reaches after about 40 s."""
    loc = Localizer(LocalizationConfig(initial_position_std=0.3), (0.0, 0.0))
    _, modes = _drive(loc, np.zeros(2), 30, [], np.random.default_rng(5))
    first_home = modes.index(Mode.RETURN_HOME)
    assert 5 <= first_home < 25, first_home
    assert set(modes[:first_home]) == {Mode.LOST}
    assert set(modes[first_home:]) == {Mode.RETURN_HOME}


def test_bad_measurements_count_as_misses_never_raise():
    loc = Localizer(LocalizationConfig(home_position_std=0.0), (0.0, 0.0))
    nan = [(PENTAGON[0], np.nan, 0.3), (PENTAGON[1], 5.0, 0.0)] + _beacons((0, 0), 2)
    assert loc.localize(3.0, nan) == Mode.LOST       # only two usable
    line = [(np.array([x, 0.0]), 3.0, 0.3) for x in (0.0, 0.0, 0.0)]
    assert loc.localize(6.0, line) == Mode.LOST       # identical beacons
    far = [(b, 100.0, 0.3) for b in PENTAGON]         # inconsistent ranges
    assert loc.localize(9.0, far) == Mode.RETURN_HOME
    assert loc.stats['rejected'] == 2 and loc.stats['misses'] == 3


def test_gps_fix_restores_normal_mode():
    loc = Localizer(LocalizationConfig(home_position_std=0.0), (0.0, 0.0))
    for t in (3.0, 6.0, 9.0):
        loc.localize(t, [])
    assert loc.mode == Mode.RETURN_HOME
    loc.gps_update(10.0, (1.0, 2.0), 2.0)
    assert loc.mode == Mode.NORMAL and loc.missed_localizations == 0


def test_predict_integrates_the_imu_between_ticks():
    loc = Localizer(LocalizationConfig(), (0.0, 0.0), initial_velocity=(0.5, 0.0))
    for k in range(11):
        loc.predict(0.1 * k, (0.0, 0.2))
    np.testing.assert_allclose(loc.position, (0.5, 0.5 * 0.2 * 1.0 ** 2), atol=1e-12)
    np.testing.assert_allclose(loc.velocity, (0.5, 0.2), atol=1e-12)


def test_mirror_fix_is_gated_and_the_prior_side_chosen():
    """All beacons to the west of the agent: the ranges also fit the mirror image.

    With its prior the agent keeps the true side (trilateration picks the fit nearer
    the prior); a fix far outside the filter's uncertainty is gated at most
    ``max_gated`` times in a row; when the next one agrees with them, the filter was
    the one wrong and relocalizes.
    """
    beacons = np.array([[-3.0, 0.5], [-1.0, -2.6], [-3.2, -2.0]])
    truth = np.array([1.8, -0.75])
    ranges = np.linalg.norm(beacons - truth, axis=1)
    fix = trilaterate(beacons, ranges, initial=truth + [0.3, 0.2], range_std=0.3)
    np.testing.assert_allclose(fix.position, truth, atol=1e-6)

    loc = Localizer(LocalizationConfig(initial_position_std=0.3), truth)
    far = [(b, r, 0.3) for b, r in zip(beacons, np.linalg.norm(beacons - [-6.0, 6.0], axis=1))]
    for k in range(loc.config.max_gated):
        assert loc.localize(3.0 * (k + 1), far) == Mode.NORMAL
        np.testing.assert_allclose(loc.position, truth, atol=1e-9)
    assert loc.stats['gated'] == loc.config.max_gated
    loc.localize(3.0 * (loc.config.max_gated + 1), far)
    assert np.hypot(*(loc.position - truth)) > 1.0, 'a persistent fix must win in the end'
    assert loc.stats['relocalizations'] == 1


RING = np.array([[12.0 * np.cos(a), 12.0 * np.sin(a)] for a in (0.3, 2.4, 4.4)])


def _ring_fix(p, std: float = 0.5):
    return [(b, float(np.hypot(*(b - np.asarray(p)))), std) for b in RING]


def test_scattered_fixes_never_move_a_confident_filter():
    """Gated fixes that disagree with each other are noise, not evidence.

    The filter sits at the truth (0.3 m). Fixes 25-25.4 m away in ever different
    directions, good geometry (0.5 m ranges: each fix about 0.4 m): every one is far
    outside the chi-square gate, and any two are farther apart than a robot at 1 m/s
    drives between them (at least 22 m in at most 9 s), so over 12 ticks none is taken,
    however many are gated in a row.
    """
    truth = np.array([1.0, -2.0])
    loc = Localizer(LocalizationConfig(initial_position_std=0.3), truth)
    for k in range(12):
        a = 2.4 * k
        wrong = truth + (25.0 + 0.2 * (k % 3)) * np.array([np.cos(a), np.sin(a)])
        assert loc.localize(3.0 * (k + 1), _ring_fix(wrong)) == Mode.NORMAL
    assert loc.stats['gated'] == 12 and loc.stats['relocalizations'] == 0
    np.testing.assert_allclose(loc.position, truth, atol=1e-9)


def test_consistent_fixes_reinitialize_a_wrong_filter_without_moving_its_velocity():
    """The filter is 15 m off (dead reckoning gone wrong) and confident (0.3 m).

    The agent really drives east at 0.5 m/s, the filter knows that speed from the IMU,
    and the fixes follow the true track, each within a robot's reach of the others.
    After ``max_gated`` gated fixes the next reinitializes the filter: the position is
    the fix's, the velocity is still 0.5 m/s east (a Kalman update with a 15 m
    innovation would have moved it through the position-velocity correlation: the
    thesis's robot would then drive off), and the following fixes are taken again.
    """
    config = LocalizationConfig(initial_position_std=0.3)
    velocity = np.array([0.5, 0.0])
    loc = Localizer(config, (15.0, 0.0), initial_velocity=velocity)
    loc.kf.P[2:4, 2:4] = np.eye(2) * 0.01 ** 2
    rng = np.random.default_rng(4)
    t = 0.0
    for tick in range(1, config.max_gated + 4):
        for _ in range(30):
            t += 0.1
            loc.predict(t, rng.normal(0.0, 0.01, 2))
        truth = velocity * t
        ranges = [(b, r + rng.normal(0.0, 0.3), 0.3) for b, r, _ in _ring_fix(truth)]
        loc.localize(t, ranges)
        if tick <= config.max_gated:
            assert np.hypot(*(loc.position - truth)) > 14.0
        if tick == config.max_gated + 1:
            assert np.hypot(*(loc.velocity - velocity)) < 0.01
    # The tick after the reinitialization trilaterates (its prior, with the velocity's
    # precision given up, is too wide for range updates); the next takes the ranges.
    assert loc.stats == {'localizations': 3, 'misses': 0, 'rejected': 0,
                         'gated': config.max_gated, 'relocalizations': 1, 'partial': 0,
                         'range_updates': 1, 'secondary': 0, 'uncertain': 0}
    assert np.hypot(*(loc.position - velocity * t)) < 1.0
    assert np.hypot(*(loc.velocity - velocity)) < 0.15


def _runaway(max_gated: int, ticks: int = 12) -> tuple[float, float]:
    """A standing robot whose filter believes, precisely, that it drives at 0.5 m/s."""
    config = LocalizationConfig(initial_position_std=0.3, max_gated=max_gated)
    loc = Localizer(config, (0.0, 0.0), initial_velocity=(0.5, 0.0))
    loc.kf.P[2:, 2:] = np.eye(4) * 1e-6
    rng = np.random.default_rng(7)
    t = 0.0
    for _ in range(ticks):
        for _ in range(30):
            t += 0.1
            loc.predict(t, rng.normal(0.0, 0.01, 2))
        loc.localize(t, [(b, r + rng.normal(0.0, 0.3), 0.3) for b, r, _ in _ring_fix((0, 0))])
    return float(np.hypot(*loc.position)), float(np.hypot(*loc.velocity))


def test_a_runaway_filter_is_caught_by_the_fixes():
    """The failure seen through ROS: velocity (or bias) wrong while the covariance stays
    small, dead reckoning runs away, every fix is gated and the estimate ends hundreds
    of metres off. Fixes that agree with each other restart the filter, and within 12
    ticks (36 s) it is back on the standing robot; gating forever leaves it 17 m off
    and still driving."""
    error, speed = _runaway(LocalizationConfig().max_gated)
    assert error < 1.0 and speed < 0.15, (error, speed)
    error, speed = _runaway(max_gated=10 ** 6)
    assert error > 15.0 and speed > 0.4, (error, speed)


def test_fix_across_a_beacon_line_updates_along_the_line_only():
    """Three beacons nearly in a row (5 cm off a 22 m line) and the agent 0.1 m off
    it: the ranges fix the position along the line to 0.2 m but leave it across the
    line to 14 m (beyond ``max_fix_std``, where the linearised fix no
    longer describes the mirror and fold solutions). The filter, 2 m off in both axes
    with a 3 m deviation, takes the along-line component only: x is corrected to the
    fix's precision, y stays where the IMU put it. The estimate is still 3 m uncertain
    across the line, beyond ``localized_max_std``: the tick is not a localization and
    the agent stays LOST (3.1.3).
    """
    beacons = np.array([[-10.0, 0.0], [-2.0, 0.05], [12.0, -0.05]])
    truth = np.array([4.0, 0.1])
    ranges = np.linalg.norm(beacons - truth, axis=1)
    fix = trilaterate(beacons, ranges, initial=truth, range_std=0.3)
    worst = float(np.sqrt(np.linalg.eigvalsh(fix.covariance)[-1]))
    assert worst > 2.5 * LocalizationConfig().max_fix_std

    loc = Localizer(LocalizationConfig(initial_position_std=3.0), truth + [2.0, 2.0])
    assert loc.localize(3.0, [(b, r, 0.3) for b, r in zip(beacons, ranges)]) == Mode.LOST
    assert loc.stats['partial'] == 1 and loc.stats['localizations'] == 0
    assert loc.stats['uncertain'] == 1 and loc.missed_localizations == 1
    assert abs(loc.position[0] - truth[0]) < 0.1
    assert abs(loc.position[1] - (truth[1] + 2.0)) < 0.1
    assert np.sqrt(loc.kf.P[0, 0]) < 0.2 and np.sqrt(loc.kf.P[1, 1]) > 2.9


def _standing_still_run(estimate_bias: bool, seed: int) -> tuple[float, float]:
    """NEES of the final position and the bias estimation error of one 300 s run."""
    rng = np.random.default_rng(seed)
    bias = rng.choice([-1.0, 1.0], 2) * 0.1 * MG
    kf = KalmanFilter((0.0, 0.0), position_std=0.5, velocity_std=0.01,
                      accel_noise_std=0.01, accel_bias_std=0.1 * MG,
                      estimate_bias=estimate_bias)
    for k in range(1, 3001):
        kf.predict(0.1, bias + rng.normal(0.0, 0.01, 2))
        if k % 30 == 0:
            kf.update_position(rng.normal(0.0, 0.5, 2), np.eye(2) * 0.25)
    e = kf.x[:2]
    return float(e @ np.linalg.solve(kf.P[:2, :2], e)), float(np.abs(kf.bias - bias).max())


def test_bias_state_keeps_a_long_run_consistent():
    """Full 0.1 mg bias, 10 Hz IMU, fixes of 0.5 m every 3 s, 300 s standing still.

    A constant bias drifts dead reckoning by 0.5 b t^2 (44 m in 300 s). The thesis's
    four-state filter books it as white noise and underestimates its own error; with
    the bias in the state the normalised error is that of a consistent filter (NEES
    near 2, the position dimension) and the bias's sign and size are recovered.
    """
    runs = {flag: [_standing_still_run(flag, seed) for seed in range(12)]
            for flag in (True, False)}
    nees = {flag: np.mean([r[0] for r in rs]) for flag, rs in runs.items()}
    assert 1.0 < nees[True] < 3.5, nees  # mean of 12 chi-square(2): 2 +- 0.6
    assert nees[False] > 1.3 * nees[True], nees
    assert max(r[1] for r in runs[True]) < 0.5 * 0.1 * MG


def test_set_state_replaces_the_estimate_for_camera_poses():
    """Hardware: a camera pose and its displacement are the estimate (no IMU)."""
    loc = Localizer(LocalizationConfig(), (0.0, 0.0))
    loc.localize(3.0, [])
    assert loc.mode == Mode.LOST
    loc.set_state((1.0, 2.0), (0.1, 0.0), 0.01, 0.04)
    np.testing.assert_allclose(loc.position, (1.0, 2.0))
    np.testing.assert_allclose(loc.velocity, (0.1, 0.0))
    np.testing.assert_allclose(np.diag(loc.covariance), [1e-4, 1e-4, 1.6e-3, 1.6e-3])
    assert loc.mode == Mode.NORMAL
    loc.gps_update(3.5, (1.02, 2.0), 0.01)   # and the filter still takes fixes
    assert abs(loc.position[0] - 1.01) < 1e-3


def _parked_run(stand_still: bool, seed: int) -> tuple[float, float]:
    """300 s of a parked robot: the largest velocity estimate and position error.

    Its fixes carry the slowly varying error of the beacons' own estimates (2 m GPS
    noise filtered by the beacons: about 1 m with a 14 s correlation time, as measured
    through ROS), not the white noise the filter assumes (0.5 m).
    """
    rng = np.random.default_rng(seed)
    loc = Localizer(LocalizationConfig(), (0.0, 0.0))
    bias = rng.uniform(-1.0, 1.0, 2) * 0.1 * MG
    decay = np.exp(-3.0 / 14.0)
    error = rng.normal(0.0, 1.0, 2)
    worst_speed = worst_error = 0.0
    t = 0.0
    for _ in range(100):
        for k in range(30):
            t += 0.1
            loc.predict(t, bias + rng.normal(0.0, 0.01, 2))
            if stand_still and k % 5 == 4:      # the agent's 2 Hz outer loop
                loc.stand_still()
        error = decay * error + np.sqrt(1.0 - decay ** 2) * rng.normal(0.0, 1.0, 2)
        loc.kf.update_position(error, np.eye(2) * 0.5 ** 2)
        if t > 30.0:
            worst_speed = max(worst_speed, float(np.hypot(*loc.velocity)))
            worst_error = max(worst_error, float(np.hypot(*loc.position)))
    return worst_speed, worst_error


def test_a_parked_robot_knows_it_stands_still():
    """Correlated fix errors read as motion: without the zero-velocity update the
    parked robot's velocity estimate reaches 0.12 m/s on average (what drove robots
    off their goals through ROS: the estimate runs off, the parking hysteresis is
    exceeded, the robot chases its own error). With it the estimate stays within
    0.02 m/s of zero and the position error shrinks by half."""
    free = np.array([_parked_run(False, seed) for seed in range(6)])
    held = np.array([_parked_run(True, seed) for seed in range(6)])
    assert free[:, 0].mean() > 0.08, free
    assert held[:, 0].max() < 0.02, held
    assert held[:, 1].mean() < 0.6 * free[:, 1].mean(), (held, free)


def test_range_update_is_the_maximum_a_posteriori_estimate():
    """The iterated EKF's fixed point is the minimum of the prior's and the ranges'
    negative log-likelihood (Gauss-Newton on it): checked against scipy's least squares
    on the whitened residuals, for a prior 2 m off, two beacons 6-9 m away (the range
    circles bend visibly over the prior's deviation) and the agent's own motion since
    the ranges were measured."""
    from scipy.optimize import least_squares

    kf = KalmanFilter((2.0, -1.0), velocity=(0.3, 0.0), position_std=1.5)
    kf.P[0, 2] = kf.P[2, 0] = 0.01           # position-velocity correlation
    beacons = np.array([[8.0, 1.0], [-4.0, 5.0]])
    offset = np.array([0.4, 0.1])
    truth = np.array([0.5, 0.5])
    ranges = np.linalg.norm(truth - offset - beacons, axis=1) + [0.2, -0.1]
    variances = np.array([0.09, 0.16])
    x0, whiten = kf.x.copy(), np.linalg.inv(np.linalg.cholesky(kf.P))

    def residuals(x):
        h = np.linalg.norm(x[:2] - offset - beacons, axis=1)
        return np.concatenate([whiten @ (x - x0), (ranges - h) / np.sqrt(variances)])

    best = least_squares(residuals, x0, xtol=1e-12, ftol=1e-12, gtol=1e-12).x
    kf.update_ranges(beacons, ranges, variances, offset, iterations=20)
    np.testing.assert_allclose(kf.x, best, atol=1e-6)
    assert np.linalg.norm(kf.x[:2] - truth) < np.linalg.norm(x0[:2] - truth)
    assert np.all(np.linalg.eigvalsh(kf.P) > 0)


def test_a_widened_prior_lets_the_first_fix_place_a_restarted_robot():
    """A process restarted mid-run starts from the deployment prior while its robot has
    driven 6 m: with the 0.3 m prior the fix 6 m away is gated (the filter keeps its
    wrong estimate); widened to the distance it can have driven, the first fix places
    it."""
    truth = np.array([6.0, 0.0])

    def first_error(widen: float | None) -> float:
        loc = Localizer(LocalizationConfig(initial_position_std=0.3), (0.0, 0.0))
        if widen is not None:
            loc.widen(widen)
            assert loc.worst_std == pytest.approx(widen)
        loc.localize(3.0, _beacons(truth, 5))
        return float(np.hypot(*(loc.position - truth)))

    assert first_error(None) > 5.0
    assert first_error(20.0) < 0.3
    loc = Localizer(LocalizationConfig(initial_position_std=0.3), (0.0, 0.0))
    loc.widen(0.1)                        # narrower than the prior: nothing changes
    assert loc.worst_std == pytest.approx(0.3)


def test_a_restarted_agent_learns_the_velocity_its_robot_drives_at():
    """``restarted(t)``: the body may be mid-drive, so the velocity prior widens to
    ``max_speed`` along with the position's. A robot driving at 0.5 m/s, its agent
    restarted 12 s into the run: two exact fixes 3 s apart give the filter its velocity
    (the IMU reads no acceleration), and its dead reckoning 3 s on stays within 0.2 m.
    With the position alone widened the velocity stays the standing robot's
    0 +/- 0.01 m/s and the estimate falls 1.5 m behind by the next tick."""
    v = np.array([0.5, 0.0])

    def error_after(restart) -> float:
        loc = Localizer(LocalizationConfig(initial_position_std=0.3), (0.0, 0.0))
        restart(loc)
        for k in range(91):                       # IMU at 10 Hz, no acceleration
            t = k / 10.0
            loc.predict(t, (0.0, 0.0))
            if k in (30, 60):
                loc.localize(t, _beacons(np.array([6.0, 0.0]) + v * t, 5, std=0.05))
        return float(np.hypot(*(loc.position - (np.array([6.0, 0.0]) + v * 9.0))))

    assert error_after(lambda loc: loc.restarted(12.0)) < 0.2
    assert error_after(lambda loc: loc.widen(12.0)) > 1.0


def test_filter_kernels_compiled_agree_with_their_source():
    """The prediction of a stack of filters and the Joseph-form update
    (``kalman._propagate``, ``_update``) compiled give the numbers of their Python source
    to rounding (the compiled matrix products add in another order), with and without
    consider parameters."""
    from swarm_agent.kalman import _propagate, _update
    from swarm_common import jit
    rng = np.random.default_rng(5)
    for _ in range(200):
        a = rng.normal(size=(6, 6))
        p = a @ a.T + np.eye(6)
        x, cross = rng.normal(size=6), rng.normal(size=(6, 2 * int(rng.integers(0, 4))))
        h = rng.normal(size=(int(rng.integers(1, 4)), 6))
        f = np.eye(6)
        f[:2, 2:4] = 0.02 * np.eye(2)
        for kernel, args in ((_update, (x, p, cross, h, rng.normal(size=len(h)),
                                        0.3 * np.eye(len(h)))),
                             (_propagate, (f, rng.normal(size=(6, 2)), 1e-4 * np.eye(6),
                                           np.stack([x, -x]), np.stack([p, 2.0 * p]),
                                           np.stack([cross, 0.5 * cross]),
                                           rng.normal(size=(2, 2)), 0.99))):
            jit.use_python(True)
            source = kernel(*args)
            jit.use_python(False)
            for got, want in zip(kernel(*args), source):
                assert got.shape == want.shape
                np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_filters_predicted_together_are_predicted_as_each_alone(kernels):
    """``kalman.predict_all`` over filters of mixed models and consider widths (one
    kernel call per model and width) gives each filter, bit for bit, what its own
    ``predict`` gives; a filter that has not been ranged keeps no consider columns."""
    from swarm_agent.kalman import KalmanFilter, predict_all
    rng = np.random.default_rng(8)
    for _ in range(20):
        alone, together = [], []
        for k in range(12):
            kw = dict(position=rng.normal(size=2), accel_noise_std=0.01 * (1 + k % 2),
                      consider_time_s=30.0 if k % 3 else np.inf, estimate_bias=k != 5)
            cross = rng.normal(size=(4 if k == 5 else 6, 2 * int(rng.integers(0, 3))))
            for filters in (alone, together):
                filters.append(KalmanFilter(**kw))
                filters[-1].cross = cross.copy()
        dts = [0.02 if k != 7 else 0.0 for k in range(12)]
        accels = rng.normal(size=(12, 2))
        for _ in range(3):
            for kf, dt, a in zip(alone, dts, accels):
                kf.predict(dt, a)
            predict_all(together, dts, accels)
        for a, b in zip(alone, together):
            assert a.x.tobytes() == b.x.tobytes() and a.P.tobytes() == b.P.tobytes()
            assert a.cross.tobytes() == b.cross.tobytes() and a.cross.shape == b.cross.shape
