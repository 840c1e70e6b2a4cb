"""A forged-advert rogue against the headless swarm, with and without authentication.

The rogue (``swarm_sim.rogue.ForgedAdverts``) impersonates agent 1 and, every second
from t = 5 s, tells every robot and the mission's radio that it is one hop from
every agent, with sequence numbers far ahead of the real ones, in the frame format its
receivers expect (with a trailer whose tag it cannot compute when they authenticate).
Agents 4 and 9 are removed at 40 s; the mission declares them lost at 48 s.

With authentication (the default) its frames are dropped and counted as bad tags, and
nothing else changes: the run equals the clean run in every recorded number (the rogue
draws nothing from the medium's random stream). Without it the mission, told by the
rogue that agents 4 and 9 are one hop from agent 1, never declares them lost.
"""

from __future__ import annotations

import pathlib

import numpy as np
import pytest

from swarm_common.shapes import load_shape
from swarm_sim.headless import HeadlessSwarm, Scenario, ScenarioError
from swarm_sim.rogue import ForgedAdverts

SQUARE = pathlib.Path(__file__).resolve().parents[2] / 'data' / 'square_8m.json'
REMOVED = [4, 9]


def _run(auth: bool, rogue: bool) -> tuple[HeadlessSwarm, dict]:
    """12 robots entering an 8 m square (as test_mission_radio), 50 s."""
    scenario = Scenario(shape=load_shape(str(SQUARE)), type_counts={1: 5, 2: 4, 3: 3},
                        n_beacons=3, half_size=15.0, seed=1, duration_s=50.0,
                        settle_hold_s=50.0, removals=[(40.0, REMOVED)], auth=auth)
    swarm = HeadlessSwarm(scenario)
    if rogue:
        scenario.rogues = [ForgedAdverts(agent_ids=swarm.ids, source=swarm.ids[1], start_s=5.0,
                                           trailer=auth)]
    record = swarm.run()
    return swarm, record


def test_a_forged_advert_rogue_changes_nothing_with_authentication():
    clean_swarm, clean = _run(auth=True, rogue=False)
    swarm, attacked = _run(auth=True, rogue=True)
    rogue = swarm.scenario.rogues[0]
    assert rogue.frames_sent >= 45 * 2          # a dump of 12 adverts: 2 frames a second
    # Every forged frame is dropped by each living brain and by the mission's radio.
    rejected = attacked.metrics['frames_rejected']
    assert set(rejected) == {'auth_bad_tag'}
    assert rejected['auth_bad_tag'] >= rogue.frames_sent * 11
    assert clean.metrics['frames_rejected'] == {}
    assert swarm.mission.lost == clean_swarm.mission.lost == set(REMOVED)
    for key in ('positions', 'estimates', 'goal_ids', 'digests', 'modes'):
        np.testing.assert_array_equal(getattr(attacked, key), getattr(clean, key), key)
    assert attacked.metrics['medium'] == clean.metrics['medium']


def test_without_authentication_the_rogue_hides_the_removed_agents():
    swarm, record = _run(auth=False, rogue=True)
    assert record.metrics['auth'] is False and record.metrics['frames_rejected'] == {}
    assert swarm.mission.lost == set()            # 4 and 9 are gone, but "one hop away"
    assert set(REMOVED) <= swarm.mission.alive


def test_a_key_file_that_cannot_be_used_is_refused_before_the_run():
    scenario = Scenario(shape=load_shape(str(SQUARE)), type_counts={1: 3}, n_beacons=3,
                        swarm_key_file='/nonexistent/keys.yaml')
    with pytest.raises(ScenarioError, match='/nonexistent/keys.yaml') as err:
        scenario.validate()
    assert '\n' not in str(err.value)
    Scenario(shape=scenario.shape, type_counts={1: 3}, n_beacons=3, auth=False,
             swarm_key_file='/nonexistent/keys.yaml').validate()   # not read when off
