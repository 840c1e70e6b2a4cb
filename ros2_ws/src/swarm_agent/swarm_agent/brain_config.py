"""The brain's per-agent parameters (``BrainConfig``), checked when built.

Every field is a ``swarm_common.parameters.tunable``: the agent nodes declare them as ROS
parameters with their descriptions and ranges (generated, never listed by hand). Rates
follow thesis 4: the 2 Hz outer loop, the 3 s localization period.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from swarm_agent.dsdv import DsdvConfig
from swarm_agent.forces import ForceParams
from swarm_agent.localization import LocalizationConfig
from swarm_agent.setpoint import SetpointParams
from swarm_common.parameters import tunable
from swarm_common.robot_types import load_robot_types

METHODS = ('bubble', 'fractal', 'forces')


class BrainConfigError(ValueError):
    """A brain parameter that cannot be used."""


@dataclass
class BrainConfig:
    """Per-agent parameters. Rates follow thesis 4 (2 Hz outer loop, 3 s localization)."""

    agent_id: int
    agent_type: int
    is_beacon: bool = False
    method: str = 'bubble'
    outer_period_s: float = tunable(
        0.5, 'Period of the outer loop (setpoint, forces), s (thesis 2 Hz)', low=0.01,
        high=10.0)
    # Cost rows are flooded once per consensus round: every robot's row to every robot
    # is O(N^2) frames, so rounds are slower than the 2 Hz setpoint loop (measured on the
    # 50-agent thesis scenario: 0.5 s rounds made routing 90 % of the evaluator's time).
    consensus_period_s: float = tunable(
        2.0, 'Period of cost reports and Hungarian assignment rounds, s', low=0.01,
        high=60.0)
    settle_speed: float = tunable(0.01, 'Below this speed a robot counts as settled, m/s '
                                  '(eq. 4.1)', low=0.0, high=1.0, live=True)
    neighbour_stale_s: float = tunable(3.0, 'Neighbour info older than this is ignored, s',
                                       low=0.1, high=60.0, live=True)
    range_stale_s: float = tunable(2.0, 'TOA ranges older than this are not used, s',
                                   low=0.01, high=60.0, live=True)
    proximity_stale_s: float = tunable(0.5, 'Proximity scans older than this are not used, s',
                                       low=0.01, high=10.0, live=True)
    forces_contour_step: float = tunable(
        0.05, 'Boundary sample spacing of the forces method, m', low=0.005, high=5.0)
    hold_radius: float = tunable(0.3, 'Within this distance of its goal the robot parks, m',
                                 low=0.001, high=10.0, live=True)
    resume_radius: float = tunable(0.8, 'A parked robot moves again beyond this distance, m',
                                   low=0.001, high=20.0, live=True)
    # A parked robot (zero force) has stopped after this long (dry friction stops one at
    # 0.5 m/s within a second); from then on its velocity is known to be zero.
    stand_still_after_s: float = tunable(
        2.0, 'A parked robot has stopped after this long: zero-velocity updates, s',
        low=0.0, high=60.0, live=True)
    # swarm_agent.stall: a free robot at its force limit accelerates at 2.8-4.5 m/s^2
    # (Table 4.1 types, 7 deg slope), so a second of it under 0.5 m/s^2 is a body held
    # by something; its filter decides whether it stands.
    stall_window_s: float = tunable(
        1.0, 'Force at its limit this long with no acceleration: the body is held, s '
        '(0: never)', low=0.0, high=60.0, live=True)
    stall_accel: float = tunable(
        0.5, 'Mean acceleration under a force at its limit below which the body is held, '
        'm/s^2', low=0.0, high=10.0, live=True)
    stall_sidestep_s: float = tunable(
        2.0, 'A blocked robot turns its setpoint 90 deg counter-clockwise this long, s',
        low=0.0, high=60.0, live=True)
    localization: LocalizationConfig = field(default_factory=LocalizationConfig)
    dsdv: DsdvConfig = field(default_factory=DsdvConfig)
    setpoint: SetpointParams = field(default_factory=SetpointParams)
    forces: ForceParams = field(default_factory=ForceParams)
    type_radii: dict[int, float] = field(default_factory=lambda: {
        t: r.coverage_radius for t, r in load_robot_types().items()})

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise BrainConfigError(
                f'unknown formation method {self.method!r}; use one of {", ".join(METHODS)}')
        if not 0 <= self.agent_id < 0xFFFF:
            raise BrainConfigError(f'agent_id must be in 0..65534, got {self.agent_id}')
        if self.outer_period_s <= 0:
            raise BrainConfigError('outer_period_s must be positive')
        if self.consensus_period_s < self.outer_period_s:
            raise BrainConfigError(
                f'consensus_period_s ({self.consensus_period_s}) must be at least '
                f'outer_period_s ({self.outer_period_s})')
        if not 0.0 < self.hold_radius < self.resume_radius:
            raise BrainConfigError(
                f'hold_radius ({self.hold_radius} m) must be positive and below '
                f'resume_radius ({self.resume_radius} m)')
