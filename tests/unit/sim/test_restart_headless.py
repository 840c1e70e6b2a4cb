"""HeadlessSwarm.restart (issue 24): an agent's brain dropped and a fresh one booted at
t, the body staying; the restarted agent is back in every neighbour's route table within
3 DSDV periods (swarm_eval.rejoin_study), and its sequence numbers start above its old
ones from the simulated boot time, reproducibly."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_agent.dsdv import BOOT_RATE, boot_sequence, seq_newer
from swarm_agent.localization import LocalizationConfig
from swarm_eval.rejoin_study import measure_rejoin
from swarm_eval.scenario import build_scenario, ScenarioSpec
from swarm_sim.headless import HeadlessSwarm, restart_event, ScenarioError

# 8 robots within 8 m: every robot hears most others (radio range 10 m).
SPEC = ScenarioSpec(agents=8, beacons=3, shape='circle_314', shape_scale=0.3, duration=30)


def test_a_restarted_agent_is_back_within_three_dsdv_periods():
    seed = 1
    restart_s = 8.0 + 0.7 * seed           # off the 2 s dump grid of the first boots
    r = measure_rejoin(SPEC, seed, seed, restart_s, horizon_s=8.0, half_size=8.0)
    assert r.neighbours >= 3
    assert r.new_sequence == boot_sequence(restart_s)
    assert seq_newer(r.new_sequence, r.old_sequence)
    # It grew 2 a dump (every 2 s) in its first life; the clock 2 * BOOT_RATE a second.
    assert r.old_sequence <= restart_s + 2
    assert r.new_sequence >= 2 * BOOT_RATE * 8.0
    assert r.rejoin_s <= 3 * r.dsdv_period_s
    assert r == measure_rejoin(SPEC, seed, seed, restart_s, horizon_s=8.0, half_size=8.0)


def test_from_zero_the_neighbours_wait_for_an_outbid():
    """The old behaviour: numbers from 0 again are older than the old run's; the
    neighbours take the new run only once it has heard a dump advertising its old
    number and outbid it (DSDV's own rule), later than at the first heartbeat."""
    zero = measure_rejoin(SPEC, 0, 0, 8.7, horizon_s=8.0, from_zero=True, half_size=8.0)
    boot = measure_rejoin(SPEC, 0, 0, 8.7, horizon_s=8.0, half_size=8.0)
    assert zero.new_sequence == 0 and not seq_newer(zero.new_sequence, zero.old_sequence)
    assert boot.rejoin_s < zero.rejoin_s <= 3 * zero.dsdv_period_s


def test_restart_keeps_the_body_and_gives_the_mission_goals():
    scenario = build_scenario(SPEC, 0)
    scenario.half_size = 8.0
    scenario.duration_s = 6.0
    seen = {}

    def before(swarm, t):
        seen['brain'] = swarm.brains[4]
        seen['position'] = swarm.world.backend.positions()[4].copy()

    def after(swarm, t):
        brain = swarm.brains[4]
        seen['new'] = brain is not seen['brain']
        seen['moved'] = float(abs(swarm.world.backend.positions()[4]
                                  - seen['position']).max())
        seen['goals'] = (brain.goal_version, swarm.mission.goal_version)

    scenario.events = [(4.0, before), (4.0, restart_event([4])), (4.0, after)]
    record = HeadlessSwarm(scenario).run()
    assert seen['new'] and seen['moved'] == 0.0
    assert seen['goals'][0] == seen['goals'][1] >= 1
    assert 't=4.0 s: agent 4 restarted' in record.events
    with pytest.raises(ScenarioError, match='not in the fleet'):
        HeadlessSwarm(build_scenario(SPEC, 0)).restart(1.0, [99])


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_a_restarted_brain_places_its_body_where_it_drove(seed):
    """The restarted brain's prior is the fleet position with the distance the body can
    have driven since (``max_speed * t``) as deviation, and a velocity of up to
    ``max_speed`` (``Localizer.restarted``): the body is mid-drive. Every agent that
    trilaterates (beacons take GPS fixes instead) restarts at once, 15.3 s into the
    run, 16 agents and 4 beacons in a 30 m arena. Its ranges place it: its estimate
    beats the deployment position the body has left, and five localization periods
    later every restarted agent is within 2 x ``localized_max_std`` (1 m) of its robot,
    the median within 0.5 m. A prior that keeps the standing robot's velocity (0 +/-
    0.01 m/s) dead-reckons a robot driving at 0.5 m/s as standing and leaves agents 5 m
    off at the end of these runs."""
    spec = ScenarioSpec(agents=16, beacons=4, shape='circle_314', shape_scale=0.6,
                        duration=30)
    scenario = build_scenario(spec, seed)
    scenario.half_size = 15.0
    scenario.duration_s = scenario.min_duration_s = 30.0
    swarm = HeadlessSwarm(scenario)
    agents = [r.id for r in swarm.fleet if not r.is_beacon]
    restart_s = 15.3
    scenario.events = [(restart_s, restart_event(agents))]
    record = swarm.run()
    at = int(np.searchsorted(record.times, restart_s))
    after = record.times >= restart_s + scenario.localization_period_s
    final = []
    for agent in agents:
        i = swarm.index[agent]
        error = np.linalg.norm(record.estimates[:, i] - record.positions[:, i], axis=1)
        moved = np.linalg.norm(record.positions[at, i] - [swarm.fleet[i].x, swarm.fleet[i].y])
        if moved > 4.0:
            assert error[after].max() < moved, agent
        final.append(error[-1])
    limit = LocalizationConfig().localized_max_std
    assert max(final) < 2.0 * limit, final
    assert np.median(final) < limit, final
