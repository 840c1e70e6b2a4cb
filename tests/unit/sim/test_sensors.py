"""Sensor noise models of thesis 3.1.4 / 4.2: statistics match the configured values.

Thesis 3.1.4 adds to the true acceleration "a random bias and a white noise with zero
mean and sigma_acc standard deviation" and Gaussian noise of sigma_meas to positions;
4.2 gives the values: bias up to 0.1 mg, white noise 0.01 m/s^2, position noise 2 m.
Sample sizes are chosen so that each check is several standard errors wide yet still
catches a wrong constant.
"""

from __future__ import annotations

import numpy as np
import pytest

from swarm_sim.sensors import GpsModel, ImuModel, MG


def test_imu_bias_lies_in_a_disc_of_0_1_mg_and_fills_it_uniformly():
    n = 20000
    imu = ImuModel(n, np.random.default_rng(0))
    radius = np.linalg.norm(imu.bias, axis=1)
    bias_max = 0.1 * MG
    assert radius.max() <= bias_max * (1 + 1e-12)
    # Uniform in a disc: r^2 / R^2 is uniform on [0, 1] (mean 1/2, std 0.289).
    u = (radius / bias_max) ** 2
    assert u.mean() == pytest.approx(0.5, abs=4 * 0.289 / np.sqrt(n))
    assert np.abs(imu.bias.mean(axis=0)).max() < 4 * bias_max / 2 / np.sqrt(n)


def test_imu_white_noise_has_zero_mean_and_0_01_std_per_axis():
    n_robots, samples = 4, 20000
    imu = ImuModel(n_robots, np.random.default_rng(1))
    truth = np.array([[0.0, 0.0], [1.0, -2.0], [0.3, 0.1], [-5.0, 5.0]])
    readings = np.stack([imu.measure(truth) for _ in range(samples)])   # (S, N, 2)
    noise = readings - truth - imu.bias
    sigma = 0.01
    # Standard error of the mean sigma / sqrt(S) = 7e-5; of the std sigma / sqrt(2 S).
    assert np.abs(noise.mean(axis=0)).max() < 5 * sigma / np.sqrt(samples)
    np.testing.assert_allclose(noise.std(axis=0), sigma, rtol=5 / np.sqrt(2 * samples))
    # The per-robot bias is what the mean reading reveals (0.1 mg is 1e-3 m/s^2).
    np.testing.assert_allclose(readings.mean(axis=0) - truth, imu.bias,
                               atol=5 * sigma / np.sqrt(samples))
    # White: consecutive samples are uncorrelated.
    x = noise[:, 0, 0]
    assert abs(np.corrcoef(x[:-1], x[1:])[0, 1]) < 5 / np.sqrt(samples)


def test_gps_noise_is_gaussian_with_2_m_per_axis():
    samples = 20000
    gps = GpsModel(np.random.default_rng(2))
    truth = np.array([12.5, -30.0])
    fixes = np.array([gps.measure(truth)[0] for _ in range(samples)])
    err = fixes - truth
    assert np.abs(err.mean(axis=0)).max() < 5 * 2.0 / np.sqrt(samples)
    np.testing.assert_allclose(err.std(axis=0), 2.0, rtol=5 / np.sqrt(2 * samples))
    # Gaussian: about 68.3 % within one sigma, 95.4 % within two.
    inside = np.abs(err) < 2.0
    assert inside.mean() == pytest.approx(0.6827, abs=0.01)
    assert (np.abs(err) < 4.0).mean() == pytest.approx(0.9545, abs=0.006)
    assert gps.measure(truth)[1] == 2.0


def test_configured_values_are_honoured_and_runs_are_reproducible():
    gps = GpsModel(np.random.default_rng(3), std=0.5)
    err = np.array([gps.measure([0.0, 0.0])[0] for _ in range(5000)])
    assert err.std() == pytest.approx(0.5, rel=0.05)
    imu = ImuModel(3, np.random.default_rng(4), bias_max=0.0, noise_std=0.2)
    assert np.all(imu.bias == 0.0)
    noise = np.stack([imu.measure(np.zeros((3, 2))) for _ in range(5000)])
    assert noise.std() == pytest.approx(0.2, rel=0.05)
    a = ImuModel(5, np.random.default_rng(9)).measure(np.ones((5, 2)))
    b = ImuModel(5, np.random.default_rng(9)).measure(np.ones((5, 2)))
    np.testing.assert_array_equal(a, b)
