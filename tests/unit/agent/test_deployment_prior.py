"""The brain starts from a deployment prior (the configured position and the placement
error's deviation), never from the truth, and its own fixes then take over."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_agent.agent_factory import make_brain
from swarm_agent.brain_config import BrainConfigError
from swarm_agent.localization import Localizer, Mode
from swarm_agent.trilateration import trilaterate

PLACEMENT_STD = 0.3
RANGE_STD = 0.5
# Three beacons 12 m around the agents: each fix is about 0.42 m RMS.
RING = np.array([[12.0 * np.cos(a), 12.0 * np.sin(a)] for a in (0.3, 2.4, 4.4)])


def test_initial_estimate_is_the_prior_with_its_stated_covariance():
    brain = make_brain(agent_id=3, agent_type=2, initial_position=(4.0, -2.5),
                       initial_position_std=PLACEMENT_STD)
    np.testing.assert_array_equal(brain.localizer.position, (4.0, -2.5))
    np.testing.assert_allclose(brain.localizer.covariance[:2, :2],
                               np.eye(2) * PLACEMENT_STD ** 2)
    assert brain.localizer.position_std == pytest.approx(PLACEMENT_STD)
    # Without a stated uncertainty the localization config's stays.
    default = make_brain(agent_id=3, agent_type=2, initial_position=(4.0, -2.5))
    assert default.localizer.position_std == pytest.approx(
        default.config.localization.initial_position_std)


def test_a_bad_prior_deviation_is_refused_with_one_line():
    with pytest.raises(BrainConfigError, match='initial_position_std must be a finite'):
        make_brain(agent_id=0, agent_type=1, initial_position_std=float('nan'))


def test_the_first_fix_pulls_the_estimate_below_both_the_prior_and_the_fix_error():
    """300 agents stand N(0, 0.3^2) off their configured positions; each takes one
    trilateration fix from noisy ranges. The Kalman update weighs the prior (0.3 m)
    against the fix (about 0.42 m): the RMS error after it is below the RMS error of
    the prior and of the fix alone (1/0.3^2 + 1/0.42^2 gives 0.24 m), and the filter's
    stated deviation matches the error it makes (mean squared error / variance near 1,
    within 20 % for 600 components)."""
    config = make_brain(agent_id=0, agent_type=1,
                        initial_position_std=PLACEMENT_STD).config.localization
    rng = np.random.default_rng(11)
    prior_err, fix_err, post_err, post_var = [], [], [], []
    for _ in range(300):
        truth = rng.uniform(-4.0, 4.0, 2)
        configured = truth + rng.normal(0.0, PLACEMENT_STD, 2)
        ranges = np.linalg.norm(RING - truth, axis=1) + rng.normal(0.0, RANGE_STD, 3)
        loc = Localizer(config, configured)
        assert loc.localize(3.0, [(b, r, RANGE_STD) for b, r in zip(RING, ranges)]) \
            == Mode.NORMAL
        fix = trilaterate(RING, ranges, initial=configured, range_std=RANGE_STD)
        prior_err.append(configured - truth)
        fix_err.append(fix.position - truth)
        post_err.append(loc.position - truth)
        post_var.append(np.diag(loc.covariance[:2, :2]))
    rms = {name: float(np.sqrt(np.mean(np.square(e)))) for name, e in (
        ('prior', prior_err), ('fix', fix_err), ('posterior', post_err))}
    assert rms['posterior'] < rms['prior'] and rms['posterior'] < rms['fix'], rms
    assert rms['fix'] > 0.35, rms
    ratio = float(np.mean(np.square(post_err)) / np.mean(post_var))
    assert 0.8 < ratio < 1.2, ratio


def test_the_agents_prior_is_the_worlds_placement_error_by_default():
    """Agent nodes (alone or composed) state the uncertainty sim_node places with."""
    pytest.importorskip('rclpy')
    from swarm_agent.agent_node import PARAMETERS as AGENT
    from swarm_agent.composed_node import SHARED
    from swarm_common.fleet import PLACEMENT_STD_M
    from swarm_sim.sim_parameters import SimParameters

    assert AGENT['placement_std_m'][0] == SHARED['placement_std_m'][0] == \
        SimParameters().placement_std_m == PLACEMENT_STD_M
