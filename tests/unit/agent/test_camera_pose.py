"""CameraPoseWindow: camera poses by capture stamp, predicted over the latency (thesis 5.1;
constant-velocity prediction of the filter of 3.1.4 without an accelerometer)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarm_agent.camera_pose import CameraPoseWindow

V = np.array([0.035, -0.02])      # m/s: the boards' top speed (config/hw_agent.yaml)
W = 0.4                           # rad/s


def drive(window: CameraPoseWindow, latency: float, jitter: np.ndarray, rate_hz: float = 10.0,
          frames: int = 20) -> float:
    """Poses of a robot at constant velocity V and yaw rate W, captured every 1/rate_hz s
    and arriving ``latency`` + jitter later; returns the last arrival time."""
    arrival = 0.0
    for i in range(frames):
        t = 100.0 + i / rate_hz
        x, y = V * (t - 100.0)
        arrival = t + latency + jitter[i]
        assert window.add(t, arrival, x, y, math.remainder(W * (t - 100.0), math.tau))
    return arrival


def test_the_pose_is_predicted_over_the_latency_with_the_velocity_of_capture_stamps():
    rng = np.random.default_rng(1)
    window = CameraPoseWindow(0.5, 0.3)
    # 50 ms camera latency plus up to 40 ms of tracker/transport jitter on arrival
    now = drive(window, 0.05, rng.uniform(0.0, 0.04, 20))
    est = window.estimate(now)
    truth_t = now - 100.0
    np.testing.assert_allclose(est.velocity, V, atol=1e-9)     # from stamps: exact
    np.testing.assert_allclose(est.position, V * truth_t, atol=1e-9)
    assert est.rate == pytest.approx(W)
    assert est.yaw == pytest.approx(math.remainder(W * truth_t, math.tau))
    assert 0.05 <= est.age <= 0.09
    assert window.compensated == 20 and window.restamped == 0


def test_velocity_from_arrival_times_would_be_off_by_the_jitter():
    """Why capture stamps: the same poses timed by arrival (unset stamps) give a velocity
    off by the jitter over the window (here 40 ms in 0.5 s: up to 8 %)."""
    jitter = np.where(np.arange(20) % 2 == 0, 0.0, 0.04)
    window = CameraPoseWindow(0.5, 0.3)
    arrival = 0.0
    for i in range(20):
        t = 100.0 + i / 10.0
        arrival = t + 0.05 + jitter[i]
        window.add(0.0, arrival, *(V * (t - 100.0)), 0.0)
    est = window.estimate(arrival)
    assert window.restamped == 20
    assert np.linalg.norm(est.velocity - V) > 0.05 * np.linalg.norm(V)
    np.testing.assert_allclose(est.position, V * 1.9, atol=1e-12), 'no prediction'


@pytest.mark.parametrize('stamp', [0.0, math.nan, 200.0, 99.0])
def test_an_unset_future_or_too_old_stamp_is_the_arrival_time(stamp):
    window = CameraPoseWindow(0.5, 0.3)
    assert window.add(stamp, 100.0, 1.0, 2.0, 0.5)
    assert window.last_stamp == 100.0 and window.restamped == 1
    est = window.estimate(100.2)
    np.testing.assert_allclose(est.position, (1.0, 2.0))   # no velocity yet: as measured
    assert est.age == pytest.approx(0.2)


def test_reordered_and_non_finite_poses_are_dropped_and_the_age_is_capped():
    window = CameraPoseWindow(0.5, 0.3)
    assert window.add(100.0, 100.05, 0.0, 0.0, 0.0)
    assert window.add(100.1, 100.15, 0.01, 0.0, 0.0)
    assert not window.add(100.05, 100.16, 5.0, 5.0, 0.0)      # older than the last
    assert not window.add(100.2, 100.25, math.nan, 0.0, 0.0)
    est = window.estimate(110.0)                                # ten seconds later
    assert est.age == pytest.approx(0.3)
    np.testing.assert_allclose(est.position, (0.01 + 0.1 * 0.3, 0.0))
    with pytest.raises(ValueError):
        CameraPoseWindow(0.0, 0.3)
    with pytest.raises(ValueError):
        CameraPoseWindow(0.5, 0.3).estimate(0.0)
