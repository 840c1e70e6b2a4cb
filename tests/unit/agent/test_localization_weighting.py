"""Fixes weighed by their anchors' deviations and bounded by their geometry
(swarm_agent.trilateration, swarm_agent.localization: weighted least squares, eq. 3.17;
``localized_max_std``; secondary anchors while moving)."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_agent.localization import LocalizationConfig, Localizer, Mode
from swarm_agent.trilateration import crlb, trilaterate

RING = 12.0 * np.array([[np.cos(a), np.sin(a)] for a in np.radians([0, 72, 144, 216, 288])])


def _ranges(anchors, p):
    return np.linalg.norm(np.asarray(anchors) - np.asarray(p), axis=1)


def test_weighted_fix_reaches_the_crlb_of_unequal_ranges():
    """Three ranges of 0.1 m and two of 1 m: Gauss-Newton weighed by 1 / s_k^2 is the
    ML estimate, so its RMS error meets the Cramer-Rao bound of these deviations
    (within four standard errors, sqrt(2 tr C^2 / n) / (2 tr C) of the ratio), and its
    reported covariance is that bound. One deviation for all (their RMS) gives the
    least-squares estimate, whose covariance is the sandwich
    (J^T J)^-1 J^T S J (J^T J)^-1 with S the true range covariance: 2.5 times the bound
    in trace on this ring, and the Monte Carlo error of the weighted fix is below it."""
    rng = np.random.default_rng(5)
    truth = np.array([1.0, -2.0])
    stds = np.array([0.1, 1.0, 0.1, 1.0, 0.1])
    n = 2000
    weighted, equal = [], []
    for _ in range(n):
        r = _ranges(RING, truth) + rng.normal(0.0, stds)
        weighted.append(trilaterate(RING, r, range_std=stds).position - truth)
        equal.append(trilaterate(RING, r, range_std=float(np.sqrt(np.mean(stds ** 2))))
                     .position - truth)
    weighted, equal = np.array(weighted), np.array(equal)
    bound = crlb(RING, truth, stds)
    ratio = float(np.sqrt(np.mean(np.sum(weighted ** 2, axis=1)) / np.trace(bound)))
    standard_error = float(np.sqrt(2.0 * np.trace(bound @ bound) / n) / (2.0 * np.trace(bound)))
    assert abs(ratio - 1.0) <= 4.0 * standard_error
    fix = trilaterate(RING, _ranges(RING, truth), range_std=stds)
    np.testing.assert_allclose(fix.covariance, bound, rtol=1e-6)
    d = truth - RING
    j = d / np.linalg.norm(d, axis=1)[:, None]
    inv = np.linalg.inv(j.T @ j)
    sandwich = inv @ j.T @ np.diag(stds ** 2) @ j @ inv
    assert np.trace(sandwich) > 2.0 * np.trace(bound)
    assert np.mean(np.sum(equal ** 2, axis=1)) == pytest.approx(np.trace(sandwich), rel=0.1)


def test_range_deviations_must_match_the_ranges():
    with pytest.raises(ValueError, match='one per range'):
        trilaterate(RING, _ranges(RING, (0.0, 0.0)), range_std=[0.3, 0.3])
    with pytest.raises(ValueError, match='finite and positive'):
        trilaterate(RING[:3], _ranges(RING[:3], (0.0, 0.0)), range_std=[0.3, 0.0, 0.3])


def test_a_fix_is_a_localization_only_once_its_error_is_bounded():
    """Three beacons 20-24 m away within a 20 degree sector fix the range along the
    sector but leave the position across it to several metres (their dilution of
    precision; the bound's worst axis is above 1 m): the filter takes the ranges, but
    the agent is not localized and stays LOST (3.1.3). Beacons around it then bound
    the error (worst axis below ``localized_max_std``) and the tick localizes."""
    truth = np.array([0.0, 0.0])
    sector = np.array([[20 * np.cos(a), 20 * np.sin(a)] for a in np.radians([-10, 0, 10])])
    sector[1] *= 1.2
    assert np.sqrt(np.linalg.eigvalsh(crlb(sector, truth, 0.3))[-1]) > 1.0
    config = LocalizationConfig(initial_position_std=3.0)
    loc = Localizer(config, truth + [1.0, 1.0])
    assert loc.localize(3.0, [(b, r, 0.3) for b, r in zip(sector, _ranges(sector, truth))]
                        ) == Mode.LOST
    assert loc.stats['localizations'] == 0 and loc.stats['uncertain'] == 1
    assert loc.worst_std > config.localized_max_std
    assert abs(loc.position[0] - truth[0]) < 0.3     # along the sector: corrected
    ring = RING[[0, 2, 3]]
    assert loc.localize(6.0, [(b, r, 0.3) for b, r in zip(ring, _ranges(ring, truth))]
                        ) == Mode.NORMAL
    assert loc.stats['localizations'] == 1 and loc.worst_std <= config.localized_max_std
    assert np.hypot(*(loc.position - truth)) < 0.3


def _moving_agent_error(anchors_while_moving: bool) -> tuple[float, Localizer]:
    """Three beacons almost in line with the agent (two east, one west) and four parked
    anchors north and south of it; the agent's dead-reckoned estimate is 1.5 m north of
    the truth (deviation 1 m) and it drives, so no zero-velocity update precedes its
    ticks. Noise-free ranges, five ticks."""
    truth = np.array([0.0, 0.0])
    beacons = np.array([[20.0, 1.0], [18.0, -1.0], [-15.0, 0.5]])
    anchors = np.array([[3.0, 15.0], [-4.0, 14.0], [2.0, -16.0], [-3.0, -13.0]])
    config = LocalizationConfig(initial_position_std=1.0,
                                anchors_while_moving=anchors_while_moving)
    loc = Localizer(config, truth + [0.0, 1.5])
    for k in range(1, 6):
        beacon_ranges = [(b, r, 0.6) for b, r in zip(beacons, _ranges(beacons, truth))]
        anchor_ranges = [(a, r, 0.5) for a, r in zip(anchors, _ranges(anchors, truth))]
        loc.localize(3.0 * k, beacon_ranges, secondary=anchor_ranges)
    return float(np.hypot(*(loc.position - truth))), loc


def test_a_moving_agent_ranges_to_anchors_even_with_enough_beacons():
    """The nearly collinear beacons barely observe the north-south axis, so the
    estimate keeps most of its 1.5 m error across their line; the anchors around the
    agent fix that axis, and the noise-free ranges bring the estimate to the truth.
    Having leaned on agents, it is not beacon-only (no anchor until a beacon-only fix)."""
    alone, _ = _moving_agent_error(False)
    together, loc = _moving_agent_error(True)
    assert alone > 0.5
    assert together < 0.05
    assert loc.stats['secondary'] == 5 and not loc.beacon_only


def _sector_nees(shared: bool, n: int = 600) -> float:
    """Mean NEES of the first fix of an agent (10 m prior) from 12 secondary anchors
    14-22 m away in a 70 degree sector, every anchor off by one common displacement
    d ~ N(0, c^2 I), c = 0.4 m (what anchors localized from the same beacons share), and
    0.3 m of range noise each. ``shared``: the anchors advertise c as their own
    position error (4-tuples), else only the summed deviation (3-tuples)."""
    rng = np.random.default_rng(3)
    c, noise = 0.4, 0.3
    angles = np.radians(np.linspace(-35.0, 35.0, 12))
    dist = np.linspace(14.0, 22.0, 12)
    anchors = np.c_[dist * np.cos(angles), dist * np.sin(angles)]
    total = float(np.hypot(noise, c))
    nees = []
    for _ in range(n):
        advertised = anchors + rng.normal(0.0, c, 2)
        r = _ranges(anchors, (0.0, 0.0)) + rng.normal(0.0, noise, len(anchors))
        rows = [(a, float(x), total, c) if shared else (a, float(x), total)
                for a, x in zip(advertised, r)]
        loc = Localizer(LocalizationConfig(initial_position_std=10.0), (0.0, 0.0))
        loc.localize(3.0, [], secondary=rows)
        e = loc.position
        nees.append(float(e @ np.linalg.solve(loc.kf.P[:2, :2], e)))
    return float(np.mean(nees))


def test_anchors_sharing_an_error_are_not_averaged_as_independent():
    """Twelve anchors off by one common displacement: taken as independent, the fix
    claims their error averages out (a mean NEES far above the 2 of a consistent 2-D
    estimate); with the shared part in their range covariance
    (``localization.range_covariance``) the fix's covariance is the true one, mean NEES
    2 within four standard errors (chi-square 2 dof: variance 4, so 2 / sqrt(n))."""
    n = 600
    assert abs(_sector_nees(True, n) - 2.0) <= 4.0 * 2.0 / np.sqrt(n)
    assert _sector_nees(False, n) > 4.0
