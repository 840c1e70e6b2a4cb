"""What the brain (``swarm_agent.brain``) remembers of a neighbour and what it gives out:
the output of a step and a snapshot of its belief. Frozen records, read by the nodes,
the headless evaluator and the metrics."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarm_agent.mesh_messages import NeighbourInfo
from swarm_agent.packet import Packet


@dataclass(frozen=True)
class Neighbour:
    """Last heartbeat information from a direct neighbour."""

    info: NeighbourInfo
    heard_at: float


@dataclass(frozen=True)
class BrainOutput:
    """What one call of ``step`` produces (read-only: the arrays are the brain's own)."""

    packets: list[Packet]
    force: np.ndarray              # N, map frame (to the simulator)
    velocity_setpoint: np.ndarray  # m/s, map frame (to hardware)


@dataclass(frozen=True)
class Snapshot:
    """Introspection of the brain: estimate, mode and assignment (swarm_msgs/AgentState)."""

    agent_id: int
    agent_type: int
    is_beacon: bool
    mode: int
    position: np.ndarray
    velocity: np.ndarray
    covariance: np.ndarray
    goal_id: int                   # -1 when none
    goal_version: int
    assignment_round: int
    assignment_digest: int
    rows_used: int
    settled: bool
    localized: bool = False        # has had a trilateration fix of its own
