"""How far sim_node may step the world: real-time pacing and the agents' lockstep.

The world runs at ``real_time_factor`` (0: as fast as possible) and never more than
``max_agent_lag_s`` of sim time ahead of the slowest living agent, the stamp of its last
force command on its own clock: a closed loop whose controllers fall behind the plant
is not the system under test. Robots not heard yet count as standing at t = 0 while the
start-up window ``wait_for_agents_s`` (wall) lasts; an agent silent for
``agent_stall_s`` (wall) is no longer waited for. Pure: wall times are passed in.
"""

from __future__ import annotations

import math

import numpy as np

# Running as fast as possible, the world advances by at most this many physics steps at
# a time (0.1 s at 100 Hz), and by no more than ``max_agent_lag_s`` allows: the agents'
# timers fire once per clock advance (rcl skips missed periods), so a tick is the
# longest the agents' inner loop holds one force. A lag of one control period (what
# the launch plan gives composed agents, which answer every step) keeps the 50 Hz loop.
STEPS_PER_TICK = 10
# Paced to real time, at most this many physics steps per tick (a late tick catches up).
MAX_STEPS_PER_TICK = 50
UNLIMITED = 1 << 30


class Pacer:
    """Physics steps a tick may take; see the module docstring."""

    def __init__(self, n: int, dt: float, real_time_factor: float, max_agent_lag_s: float,
                 wait_for_agents_s: float, agent_stall_s: float, now: float) -> None:
        self.dt = dt
        self.lag = float(max_agent_lag_s)
        self.wait_for_agents_s = float(wait_for_agents_s)
        self.agent_stall_s = float(agent_stall_s)
        self.started = now
        self.stamp = np.full(n, -math.inf)   # agent clock of each robot's last command
        self.wall = np.full(n, -math.inf)    # wall time it arrived
        self.set_rtf(real_time_factor, 0.0, now)

    def set_rtf(self, real_time_factor: float, t: float, now: float) -> None:
        """Pace to ``real_time_factor`` from sim time ``t`` at wall time ``now``."""
        self.rtf, self._sim0, self._wall0 = float(real_time_factor), t, now

    def heard(self, i: int, stamp: float, now: float) -> None:
        """Robot ``i``'s agent answered: a command stamped ``stamp`` on its clock."""
        self.stamp[i] = stamp
        self.wall[i] = now

    def steps_for_tick(self, t: float, alive: np.ndarray, now: float) -> int:
        """Physics steps to take now at sim time ``t``."""
        if self.rtf > 0:
            target = self._sim0 + (now - self._wall0) * self.rtf
            steps = max(0, min(int((target - t) / self.dt), MAX_STEPS_PER_TICK))
        else:
            steps = STEPS_PER_TICK
        return min(steps, self.steps_allowed(t, alive, now))

    def steps_allowed(self, t: float, alive: np.ndarray, now: float) -> int:
        """Physics steps possible without running ahead of the slowest living agent."""
        if self.lag <= 0.0:
            return UNLIMITED
        silent = ~np.isfinite(self.stamp)
        starting = silent & (now - self.started < self.wait_for_agents_s)
        waited = alive & (starting | (now - self.wall < self.agent_stall_s))
        if not waited.any():
            return UNLIMITED
        slowest = float(np.where(silent, 0.0, self.stamp)[waited].min())
        return max(0, int((slowest + self.lag - t) / self.dt + 1e-9))

    def all_answered(self, t: float, alive: np.ndarray, now: float) -> bool:
        """Running as fast as possible, every waited agent has answered time ``t``: the
        world may step at once instead of at its next tick."""
        return (self.rtf <= 0.0 and self.lag > 0
                and self.steps_allowed(t, alive, now) >= int(self.lag / self.dt + 1e-9))

    def holder(self, alive: np.ndarray, now: float) -> int | None:
        """The heard agent the world waits for, once it has waited a wall second for it
        (not in the first 5 s)."""
        waited = alive & np.isfinite(self.stamp)
        if not waited.any() or now - self.started < 5.0:
            return None
        i = int(np.flatnonzero(waited)[np.argmin(self.stamp[waited])])
        return i if now - self.wall[i] >= 1.0 else None

    def describe(self, i: int, now: float) -> str:
        """Robot ``i``'s last command, for the log line of a hold."""
        return (f'its last command is stamped {self.stamp[i]:.2f} s and came '
                f'{now - self.wall[i]:.1f} s (wall) ago')
