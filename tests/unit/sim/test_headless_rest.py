"""Event-driven stepping of the headless evaluator (issue 23): a parked agent with nothing
due is not stepped (``AgentBrain.rest``), and the run is the same as stepping it."""

from __future__ import annotations

import pathlib

import numpy as np

from swarm_agent.agent_factory import make_brain
from swarm_agent.brain import AgentBrain
from swarm_common.shapes import load_shape
from swarm_sim.headless import HeadlessSwarm, Scenario

SQUARE = pathlib.Path(__file__).resolve().parents[2] / 'data' / 'square_8m.json'


def _run(monkeypatch, skip: bool):
    if not skip:
        monkeypatch.setattr(AgentBrain, 'rest', lambda self, t: False)
    scenario = Scenario(shape=load_shape(str(SQUARE)), type_counts={1: 5, 2: 4, 3: 3},
                        n_beacons=3, half_size=15.0, seed=1, duration_s=40.0)
    return HeadlessSwarm(scenario).run()


def test_skipping_resting_agents_changes_nothing(monkeypatch):
    skipped = _run(monkeypatch, skip=True)
    stepped = _run(monkeypatch, skip=False)
    for key in ('positions', 'velocities', 'estimates', 'goal_ids', 'digests', 'modes'):
        assert np.array_equal(getattr(skipped, key), getattr(stepped, key)), key
    counts = skipped.metrics['brain_steps']
    # 12 agents at 50 Hz over the run: every living agent-step is taken or skipped.
    samples = len(skipped.times)
    assert counts['steps'] == stepped.metrics['brain_steps']['steps']
    assert counts['steps'] == counts['active'] + counts['resting']
    assert abs(counts['steps'] - 12 * 50 * skipped.times[-1]) <= 12 * 2, samples
    assert stepped.metrics['brain_steps']['resting'] == 0
    assert counts['resting'] > 0.1 * counts['steps']   # parked agents do rest


def test_a_brain_rests_only_when_parked_with_nothing_due():
    """A lone agent without goals parks at once; over 4 s (200 steps at 50 Hz) only its
    timers wake it, all on one 0.5 s grid: outer loop and heartbeats every 0.5 s, full
    route dumps every 2 s, localization at 3 s. 8 active steps of 200."""
    brain = make_brain(agent_id=3, agent_type=1)
    brain.set_shape(load_shape('circle_314'), 1)
    assert not brain.rest(0.0)         # not parked yet, every timer due
    active = []
    for k in range(200):
        t = 0.02 * k
        if not brain.rest(t):
            active.append(t)
            assert not brain.step(t).force.any()
    assert brain._parked
    assert np.allclose(active, 0.5 * np.arange(8))
    assert not brain.rest(brain._next_outer)      # the 2 Hz outer loop is due
    brain.on_proximity(t, np.zeros((0, 2)), np.zeros(0))
    assert not brain.rest(t + 0.02)               # a proximity scan to act on
