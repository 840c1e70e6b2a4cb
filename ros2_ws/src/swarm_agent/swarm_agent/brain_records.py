"""What the brain (``swarm_agent.brain``) remembers of a neighbour and what it gives out:
the output of a step and a snapshot of its belief. Frozen records, read by the nodes,
the headless evaluator and the metrics, and where the neighbours are by their records."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from swarm_agent.mesh_messages import NeighbourInfo
from swarm_agent.packet import Packet


@dataclass(frozen=True)
class Neighbour:
    """Last heartbeat information from a direct neighbour."""

    info: NeighbourInfo
    heard_at: float


def broadcast_offsets(neighbours: Iterable[Neighbour], position: np.ndarray,
                      type_radii: Mapping[int, float],
                      own_radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Neighbours' broadcast positions minus ``position`` (k, 2, m) and their cover radii
    by type (k,; an unknown type: ``own_radius``)."""
    infos = [n.info for n in neighbours]
    if not infos:
        return np.zeros((0, 2)), np.zeros(0)
    pos = np.array([n.position for n in infos], dtype=float)
    radii = np.array([type_radii.get(n.agent_type, own_radius) for n in infos])
    return pos - position, radii


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
