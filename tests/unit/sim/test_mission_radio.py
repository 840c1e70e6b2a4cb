"""The mission learns which agents are alive over the radio (a node of the mesh), not
from the simulator's truth: a removed agent is declared lost once its neighbours'
broken-route adverts reach the mission's radio, a living one never is."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest

from swarm_agent.dsdv import DsdvConfig, DsdvRouter
from swarm_agent.mission_radio import MeshListener, MISSION_RADIO_ID
from swarm_common.fleet import RobotSpec
from swarm_common.shapes import load_shape
from swarm_sim.headless import HeadlessSwarm, Scenario, ScenarioError
from swarm_sim.medium import MediumConfig, RadioMedium
from swarm_sim.mission_mesh import MediumWithMission

SQUARE = pathlib.Path(__file__).resolve().parents[2] / 'data' / 'square_8m.json'
DSDV = DsdvConfig()


def _chain(loss: float = 0.0):
    """Agents 1-2-3 in a row 20 m apart (25 m radio), the mission 10 m from agent 1
    only: it hears agent 1 directly and 2 and 3 only through the adverts."""
    listener = MeshListener([1, 2, 3])
    medium = MediumWithMission(RadioMedium(MediumConfig(loss=loss),
                                           np.random.default_rng(1)),
                               listener, (-10.0, 0.0), np.random.default_rng(2))
    medium.update_positions([1, 2, 3], [[0.0, 0.0], [20.0, 0.0], [40.0, 0.0]])
    routers = {a: DsdvRouter(a, DSDV) for a in (1, 2, 3)}
    return listener, medium, routers


def _run(medium, routers, t0: float, t1: float, dt: float = 0.05) -> float:
    t = t0
    while t < t1:
        for router in routers.values():
            for packet in router.tick(t):
                medium.transmit(t, packet)
        for packet, receivers in medium.deliver_grouped(t):
            for r in receivers:
                routers[r].on_packet(t, packet)
        t += dt
    return t


def test_the_mission_hears_of_agents_beyond_its_range_and_of_their_loss():
    listener, medium, routers = _chain()
    # The agents never see the mission's radio among their links; it hears agent 1.
    assert medium.neighbours(1) == [2] and medium.neighbours(2) == [1, 3]
    ids, links = medium.adjacency()
    assert ids == [1, 2, 3] and links.shape == (3, 3)
    assert medium.reach.neighbours(MISSION_RADIO_ID) == [1]
    assert listener.alive() == []
    # Two full dumps (2 s each) carry agent 3's route to the mission two hops away.
    t = _run(medium, routers, 0.0, 2 * DSDV.full_dump_period_s + 0.5)
    assert listener.alive() == [1, 2, 3]
    # Agent 3 is gone: 2 times it out (2 s) and advertises the broken route at once.
    medium.remove(3)
    del routers[3]
    t = _run(medium, routers, t, t + DSDV.neighbour_timeout_s + 0.5)
    assert listener.alive() == [1, 2]


def test_the_mission_radio_sends_nothing_and_ignores_the_agents_data():
    listener, medium, routers = _chain()
    _run(medium, routers, 0.0, 5.0)
    assert listener.router.stats.get('packets_sent', 0) == 0
    assert MISSION_RADIO_ID not in routers[1].table
    assert listener.frames > 0


def test_an_agent_with_the_mission_radio_address_is_refused():
    with pytest.raises(ValueError, match="is the mission's radio address"):
        MeshListener([1, MISSION_RADIO_ID])
    fleet = [RobotSpec(MISSION_RADIO_ID, 1, True, 0.0, 0.0),
             RobotSpec(1, 1, True, 3.0, 0.0), RobotSpec(2, 1, True, 0.0, 3.0)]
    with pytest.raises(ScenarioError, match="mission's radio address"):
        HeadlessSwarm(Scenario(shape=load_shape(str(SQUARE)), fleet=fleet,
                               type_counts={1: 3}, n_beacons=3, half_size=15.0))


def _lost(loss: float, removals) -> tuple[HeadlessSwarm, list[str]]:
    """12 robots entering an 8 m square (as test_headless_collisions), 100 s."""
    scenario = Scenario(shape=load_shape(str(SQUARE)), type_counts={1: 5, 2: 4, 3: 3},
                        n_beacons=3, half_size=15.0, seed=1, duration_s=100.0,
                        settle_hold_s=100.0, medium=MediumConfig(loss=loss),
                        removals=removals)
    swarm = HeadlessSwarm(scenario)
    swarm.run()
    return swarm, [e for e in swarm.mission.events if 'lost' in e]


def test_no_living_agent_is_declared_lost_at_30_percent_loss():
    swarm, lost = _lost(0.3, ())
    assert lost == [] and swarm.mission.alive == set(swarm.ids)


def test_removed_agents_are_declared_lost_and_the_shape_repartitioned():
    """Removed at 40 s: heard of until their neighbours time them out (2 s) and the
    broken routes reach the mission (triggered updates; a full dump, 2 s, at most per
    hop), then declared lost after the mission's 6 s timeout. The truth would have told
    the mission at once: lost at 46.5 s (the first record past the timeout); over the
    radio they are lost at 48 s."""
    swarm, lost = _lost(0.0, [(40.0, [4, 9])])
    assert swarm.mission.lost == {4, 9}, lost
    times = [float(e.split('s:')[0].removeprefix('t=')) for e in lost]
    timeout = swarm.mission.config.agent_timeout_s
    assert all(40.0 + timeout + 0.5 * DSDV.neighbour_timeout_s < t
               <= 40.0 + timeout + DSDV.neighbour_timeout_s + 4.0 for t in times), lost
    assert len(swarm.mission.goals) == 10
