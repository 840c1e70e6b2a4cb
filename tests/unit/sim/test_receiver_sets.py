"""``reception.ReceiverSets``: the receivers of each set of addresses a transmission
reaches, worked out once (issue 23), never stale: a removed brain gets no more frames, a
restarted one gets them in place of the brain it replaced."""

from __future__ import annotations

from swarm_agent.reception import Receivers, ReceiverSets
from swarm_eval.scenario import build_scenario, ScenarioSpec
from swarm_sim.headless import HeadlessSwarm

SPEC = ScenarioSpec(agents=8, beacons=3, shape='circle_314', shape_scale=0.3, duration=12)


class _Brain:
    def __init__(self, agent_id: int) -> None:
        self.auth, self.router = None, _Router(agent_id)


class _Router:
    def __init__(self, agent_id: int) -> None:
        self.id = agent_id


def test_one_receivers_per_set_of_addresses_without_the_absent():
    brains = {1: _Brain(1), 2: _Brain(2), 3: None}
    built = []
    sets = ReceiverSets(lambda a: (built.append(a), brains.get(a))[1])
    heard = sets([1, 2, 3])
    assert isinstance(heard, Receivers) and heard.brains == [brains[1], brains[2]]
    assert heard.opening is None                     # unauthenticated: each opens alone
    assert sets((1, 2, 3)) is heard and built == [1, 2, 3]   # by content, built once
    assert sets([3]) is None and sets([3, 9]) is None
    sets.clear()
    assert sets([1, 2, 3]) is not heard and built[-3:] == [1, 2, 3]


def test_removed_and_restarted_brains_get_the_frames_they_should():
    scenario = build_scenario(SPEC, 0)
    scenario.half_size = 8.0
    swarm = HeadlessSwarm(scenario)
    gone, restarted = swarm.ids[2], swarm.ids[5]
    dropped = {}

    def drop(t: float, k: int, change) -> None:
        dropped[k] = (swarm.brains[k], dict(swarm.brains[k].router.stats))
        change(t)

    swarm.world.schedule(4.0, lambda t: drop(t, 2, lambda t: swarm._remove(t, [gone])))
    swarm.world.schedule(6.0, lambda t: drop(t, 5, lambda t: swarm.restart(t, [restarted])))
    swarm.run()
    # Both had heard frames, and nothing after they were dropped: their counts stay.
    for brain, stats in dropped.values():
        assert stats.get('delivered', 0) > 0
        assert dict(brain.router.stats) == stats
    new = swarm.brains[5]
    assert new is not dropped[5][0] and swarm.brains[2] is None
    assert new.router.stats.get('delivered', 0) > 0 and len(new.router.heard) >= 3
