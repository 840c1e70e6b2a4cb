"""sim_node's pacing (swarm_sim.pacing): real time and the agents' lockstep, wall times given."""

from __future__ import annotations

import numpy as np

from swarm_sim.pacing import Pacer, STEPS_PER_TICK, UNLIMITED

DT = 0.01
ALIVE = np.ones(3, dtype=bool)


def _pacer(rtf=0.0, lag=0.2) -> Pacer:
    return Pacer(3, DT, rtf, lag, wait_for_agents_s=60.0, agent_stall_s=10.0, now=100.0)


def test_the_world_runs_at_most_the_lag_ahead_of_the_slowest_agent():
    pacer = _pacer()
    # Nobody heard yet, within the start-up window: all stand at t = 0, 0.2 s = 20 steps.
    assert pacer.steps_allowed(0.0, ALIVE, 101.0) == 20
    assert pacer.steps_for_tick(0.0, ALIVE, 101.0) == STEPS_PER_TICK
    for i in range(3):
        pacer.heard(i, 0.5, 102.0)
    assert pacer.steps_allowed(0.6, ALIVE, 102.0) == 10            # 0.5 + 0.2 - 0.6
    assert pacer.all_answered(0.5, ALIVE, 102.0)
    pacer.heard(2, 0.3, 102.0)                                       # one lags behind
    assert not pacer.all_answered(0.5, ALIVE, 102.0)
    assert pacer.steps_allowed(0.6, ALIVE, 102.0) == 0
    # Dead or silent for agent_stall_s: no longer waited for.
    assert pacer.steps_allowed(0.6, np.array([True, True, False]), 102.0) == 10
    assert pacer.steps_allowed(0.6, ALIVE, 112.5) == UNLIMITED
    assert _pacer(lag=0.0).steps_allowed(5.0, ALIVE, 101.0) == UNLIMITED


def test_real_time_pacing_follows_the_wall_clock():
    pacer = _pacer(rtf=2.0, lag=0.0)
    assert pacer.steps_for_tick(0.0, ALIVE, 100.125) == 25           # 0.25 s of sim time
    assert pacer.steps_for_tick(0.0, ALIVE, 110.0) == 50             # capped per tick
    pacer.set_rtf(1.0, 3.0, 200.0)
    assert pacer.steps_for_tick(3.0, ALIVE, 200.0625) == 6           # 6.25 steps due


def test_the_hold_names_the_agent_waited_for():
    pacer = _pacer()
    pacer.heard(0, 1.0, 110.0)
    pacer.heard(1, 0.4, 110.0)
    assert pacer.holder(ALIVE, 110.5) is None                        # not a second yet
    assert pacer.holder(ALIVE, 111.5) == 1
    assert 'stamped 0.40 s and came 1.5 s (wall) ago' in pacer.describe(1, 111.5)


def test_with_a_lag_of_one_control_period_every_tick_is_one_period():
    # Composed agents answer every 0.02 s step (launch plan: lag = 1 / control rate):
    # the world steps 2 physics steps as soon as all have answered, never 10, so their
    # 50 Hz inner loop holds each force for one period, as headless and on a robot.
    pacer = _pacer(lag=0.02)
    t = 0.0
    for _ in range(5):
        for i in range(3):
            pacer.heard(i, t, 101.0)
        assert pacer.all_answered(t, ALIVE, 101.0)
        steps = pacer.steps_for_tick(t, ALIVE, 101.0)
        assert steps == 2
        t += steps * DT
    pacer.heard(0, t, 101.0)             # two agents have not answered t yet
    assert not pacer.all_answered(t, ALIVE, 101.0)
    assert pacer.steps_for_tick(t, ALIVE, 101.0) == 0
