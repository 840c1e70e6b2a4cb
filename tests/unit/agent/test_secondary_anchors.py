"""Secondary anchors (swarm_agent.localization, "Secondary anchors"; issue 24).

An agent that hears fewer than three beacons ranges to parked neighbours localized
from beacons alone; the hierarchy has two levels, so an agent never anchors on one that
anchored on it.
"""

from __future__ import annotations

import numpy as np

from swarm_agent.agent_factory import make_brain
from swarm_agent.brain import Neighbour
from swarm_agent.localization import LocalizationConfig, Localizer, Mode
from swarm_agent.mesh_messages import NeighbourInfo

BEACONS = [np.array([0.0, 0.0]), np.array([20.0, 0.0])]
ANCHOR = np.array([10.0, 15.0])
TRUTH = np.array([9.0, 6.0])
STD = 0.3


def _ranges(points, p=TRUTH, rng=None, std=STD):
    noise = (lambda: 0.0) if rng is None else (lambda: float(rng.normal(0.0, std)))
    return [(q, float(np.hypot(*(q - p))) + noise(), std) for q in points]


def test_two_beacons_and_an_anchor_localize_and_leave_the_agent_no_anchor():
    """Two beacons are a miss (3.1.3); with a secondary anchor the tick is a fix
    (NORMAL) that lands within one range deviation of the truth (the Kalman update
    blends in the 3.6 m-off prior), and the agent's estimate now leans on an agent:
    it is not beacon-only until a fix from three beacons."""
    loc = Localizer(LocalizationConfig(), TRUTH + [3.0, -2.0])
    assert loc.localize(3.0, _ranges(BEACONS)) == Mode.LOST
    assert loc.localize(6.0, _ranges(BEACONS), secondary=_ranges([ANCHOR])) == Mode.NORMAL
    assert np.hypot(*(loc.position - TRUTH)) < STD
    assert loc.stats['secondary'] == 1 and not loc.beacon_only
    third = np.array([18.0, 16.0])
    assert loc.localize(9.0, _ranges(BEACONS + [third])) == Mode.NORMAL
    assert loc.beacon_only


def test_a_parked_agent_ignores_anchors_when_the_beacons_suffice():
    """A parked agent (zero-velocity updates since its last tick) with three beacons
    ignores the anchors: an anchor whose advertised position is 10 m off moves nothing,
    and the fix stays beacon-only, so the agent can serve as an anchor itself."""
    loc = Localizer(LocalizationConfig(), TRUTH)
    beacons = BEACONS + [np.array([18.0, 16.0])]
    wrong = _ranges([ANCHOR])[0]
    wrong = (wrong[0] + [10.0, 0.0], wrong[1], wrong[2])
    for k in range(1, 4):
        loc.stand_still()
        assert loc.localize(3.0 * k, _ranges(beacons), secondary=[wrong]) == Mode.NORMAL
    np.testing.assert_allclose(loc.position, TRUTH, atol=0.05)
    assert loc.beacon_only and loc.stats['secondary'] == 0


def test_a_deployment_prior_is_not_beacon_only():
    assert not Localizer(LocalizationConfig(), TRUTH).beacon_only


def test_an_uncertain_anchor_weighs_less():
    """The same biased anchor pulls a fix less when it advertises a larger deviation
    (its std adds to the range noise, as a beacon's does): over 200 noisy ticks the mean
    error toward the anchor's bias shrinks as its std grows."""
    def mean_error(anchor_std: float) -> float:
        rng = np.random.default_rng(5)
        errors = []
        for _ in range(200):
            loc = Localizer(LocalizationConfig(initial_position_std=0.5), TRUTH)
            anchor = (ANCHOR + [0.0, 1.0], float(np.hypot(*(ANCHOR - TRUTH))),
                      float(np.hypot(STD, anchor_std)))
            loc.localize(3.0, _ranges(BEACONS, rng=rng), secondary=[anchor])
            errors.append(float(np.hypot(*(loc.position - TRUTH))))
        return float(np.mean(errors))
    assert mean_error(2.0) < 0.8 * mean_error(0.1)


def _parked_brain(agent_id: int, beacon: bool = False):
    brain = make_brain(agent_id=agent_id, agent_type=1, is_beacon=beacon,
                       initial_position=TRUTH)
    brain._parked_since = 0.0          # parked since t = 0 (the brain's own record)
    brain._last_t = 10.0
    return brain


def test_only_a_parked_beacon_localized_agent_is_an_anchor():
    brain = _parked_brain(1)
    assert not brain._info().anchor                 # its estimate is a deployment prior
    beacons = BEACONS + [np.array([18.0, 16.0])]
    brain.localizer.localize(3.0, _ranges(beacons))
    assert brain.localizer.worst_std < 0.5
    info = NeighbourInfo.decode(brain._info().encode())
    assert info.anchor                               # the flag survives the wire
    brain._parked_since = None                       # driving: no anchor
    assert not brain._info().anchor
    brain._parked_since = 0.0
    brain.localizer.localize(6.0, _ranges(BEACONS), secondary=_ranges([ANCHOR]))
    assert not brain._info().anchor                  # anchored on an agent: not an anchor
    beacon = _parked_brain(2, beacon=True)
    beacon.localizer.localize(3.0, _ranges(beacons))
    assert not beacon._info().anchor                 # beacons are primary anchors


def test_an_anchor_does_not_anchor_on_others():
    """The loop guard: an agent that is an anchor localizes from beacons alone, so no
    agent ever anchors on one that anchored on it."""
    brain = _parked_brain(1)
    brain.localizer.localize(3.0, _ranges(BEACONS + [np.array([18.0, 16.0])]))
    assert brain._is_anchor(10.0)
    other = NeighbourInfo(1, False, int(Mode.NORMAL), tuple(ANCHOR), (0.0, 0.0),
                          True, 0.1, anchor=True)
    brain.neighbours[7] = Neighbour(other, 9.5)
    beacons = {3: BEACONS[0], 4: BEACONS[1]}
    for k, b in beacons.items():
        brain.neighbours[k] = Neighbour(NeighbourInfo(1, True, int(Mode.NORMAL), tuple(b),
                                                      (0.0, 0.0), True, 0.1), 9.5)
    brain.on_ranges(10.0, [(k, float(np.hypot(*(b - TRUTH))), STD)
                           for k, b in beacons.items()]
                    + [(7, float(np.hypot(*(ANCHOR - TRUTH))), STD)])
    brain._localize(10.0)
    assert brain.localizer.stats['secondary'] == 0 and brain._is_anchor(10.0)
    brain._parked_since = None                       # a driving agent uses the anchor
    brain._localize(10.0)
    assert brain.localizer.stats['secondary'] == 1 and not brain.localizer.beacon_only
