"""Anchors whose position errors persist from tick to tick (Schmidt-Kalman consider
parameters, ``swarm_agent.kalman``, ``swarm_agent.anchors``)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from swarm_agent.anchors import AnchorRange, consider_terms, range_covariance, usable_rows
from swarm_agent.kalman import KalmanFilter
from swarm_agent.localization import LocalizationConfig, Localizer

# The filter's prediction and update are kernels (swarm_agent.kalman): compiled and as source.
pytestmark = pytest.mark.usefixtures('kernels')

BEACONS = np.array([[12.0, 2.0], [10.0, -6.0], [14.0, 8.0]])   # all east of the agent
TOA = 0.3          # m, white range noise
OWN = 0.5          # m per axis, each beacon's own position error
TAU = 30.0         # s, the errors' time constant (LocalizationConfig.anchor_error_time_s)
PERIOD = 3.0       # s between ticks


def _mean_nees(anchor_error_time_s: float, trials: int = 300, ticks: int = 20) -> float:
    """A standing agent ranges every 3 s to three beacons on one side whose advertised
    positions are off by errors that persist (first-order Gauss-Markov, 30 s); the mean
    over trials of e^T P^-1 e after the last tick (2 for a consistent 2-D filter)."""
    rng = np.random.default_rng(7)
    cfg = dataclasses.replace(LocalizationConfig(), anchor_error_time_s=anchor_error_time_s)
    a = math.exp(-PERIOD / TAU)
    nees = []
    for _ in range(trials):
        loc = Localizer(cfg, rng.normal(0.0, 1.0, 2))      # the prior: 1 m per axis
        beta = rng.normal(0.0, OWN, BEACONS.shape)
        t = 0.0
        loc.predict(t, np.zeros(2))
        for _ in range(ticks):
            for _ in range(3):
                t += PERIOD / 3
                loc.predict(t, np.zeros(2))
            beta = a * beta + math.sqrt(1.0 - a * a) * rng.normal(0.0, OWN, BEACONS.shape)
            loc.localize(t, [AnchorRange(b + beta[k], float(np.hypot(*b)) + rng.normal(0.0, TOA),
                                         TOA, OWN, k) for k, b in enumerate(BEACONS)])
        e = loc.position
        nees.append(float(e @ np.linalg.solve(loc.kf.P[:2, :2], e)))
    return float(np.mean(nees))


def test_persistent_anchor_errors_are_not_counted_again_at_every_tick():
    """Twenty ticks to the same three beacons: taken as fresh noise at every tick, their
    persistent errors make the filter claim a precision it does not have (mean NEES
    6.2); held as consider parameters the filter stays consistent (mean NEES 1.8; the
    standard error of the mean of 300 chi-square(2) samples is 0.12)."""
    assert _mean_nees(TAU) == pytest.approx(2.0, abs=0.5)
    assert _mean_nees(0.0) > 4.0


def _rows(own: float = OWN, shared: bool = False):
    anchors = [AnchorRange(b, float(np.hypot(*b)), TOA, own, k) for k, b in enumerate(BEACONS)]
    return usable_rows(anchors, shared=shared, consider=True)


def test_the_inflation_stands_in_for_persistence_only_when_errors_are_white():
    """``beacon_variance_inflation`` widens an anchor's error taken as white noise; held
    as a consider parameter it enters as advertised."""
    anchor = AnchorRange(BEACONS[0], 12.0, TOA, OWN, 3, inflation=4.0)
    (white,) = usable_rows([anchor])
    (held,) = usable_rows([anchor], consider=True)
    assert white.std == pytest.approx(math.hypot(TOA, 2 * OWN)) and white.key is None
    assert held.std == pytest.approx(math.hypot(TOA, OWN)) and held.own == OWN
    assert held.key == 3


@pytest.mark.parametrize('shared', [False, True])
def test_consider_terms_split_the_range_covariance(shared):
    """White part plus H_b B H_b^T is the tick's whole range covariance, for beacons and
    for secondary anchors sharing a displacement."""
    rows = _rows(shared=shared)
    at = np.zeros(2)
    keys, slot, white, b = consider_terms(rows, at)
    assert keys == [0, 1, 2] and list(slot) == [0, 1, 2]
    np.testing.assert_allclose(np.diag(white), TOA ** 2)
    d = at - BEACONS
    u = d / np.linalg.norm(d, axis=1)[:, None]
    hb = np.zeros((3, 6))
    for k in range(3):
        hb[k, 2 * k:2 * k + 2] = -u[k]
    np.testing.assert_allclose(white + hb @ b @ hb.T, range_covariance(rows, at), atol=1e-12)


def test_a_first_range_to_an_anchor_is_the_plain_update():
    """Without covariance with the state yet, the Schmidt-Kalman update equals the
    extended Kalman update with the anchors' errors in the range noise (one iteration,
    both linearised at the prior)."""
    rows = _rows()
    keys, slot, white, b = consider_terms(rows, np.zeros(2))
    plain, consider = (KalmanFilter((0.0, 0.0), consider_time_s=TAU) for _ in range(2))
    ranges = [u.range + 0.2 for u in rows]
    plain.update_ranges(BEACONS, ranges, range_covariance(rows, np.zeros(2)), iterations=1)
    consider.update_ranges(BEACONS, ranges, white, iterations=1, consider=(keys, slot, b))
    np.testing.assert_allclose(consider.x, plain.x, atol=1e-9)
    np.testing.assert_allclose(consider.P, plain.P, atol=1e-9)
    assert consider.cross.shape == (6, 6) and np.abs(consider.cross).max() > 0.01
    consider.forget_consider([1])
    assert consider.consider_keys == [1] and consider.cross.shape == (6, 2)
