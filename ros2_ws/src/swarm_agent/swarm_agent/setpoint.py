"""Velocity setpoint generator of the outer loop (thesis 3.2.4, Fig. 3.32).

The setpoint points along the path to the goal (the next waypoint of the visibility
graph path) with a magnitude proportional to the remaining path length, saturated at
``v_max`` (0.5 m/s in the thesis); collision-avoidance terms push away from neighbours
whose coverage circles come closer than a safety margin, and from nearby obstacle
samples, and the sum is saturated again.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class SetpointParams:
    """Outer-loop parameters (YAML defaults in swarm_agent/config/control.yaml)."""

    gain: float = 0.4            # 1/s: setpoint speed per metre of remaining path
    v_max: float = 0.5           # m/s, thesis 3.2.4
    avoid_gain: float = 0.3      # m/s at the contact distance
    avoid_margin: float = 0.3    # m beyond the summed coverage radii
    arrive_radius: float = 0.02  # m: closer than this, command zero


def _saturate(v: np.ndarray, v_max: float) -> np.ndarray:
    speed = float(np.hypot(*v))
    return v * (v_max / speed) if speed > v_max else v


def velocity_setpoint(position, goal, params: SetpointParams, *, waypoints=None,
                      neighbours=None, neighbour_radii=None, own_radius: float = 0.0,
                      obstacle_samples=None) -> np.ndarray:
    """The 2-D velocity setpoint in m/s (map frame)."""
    position = np.asarray(position, dtype=float)
    goal = np.asarray(goal, dtype=float)
    if waypoints is not None and len(waypoints) > 2:
        pts = np.asarray(waypoints, dtype=float)
        remaining = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
        target = pts[1]
    else:
        remaining = float(np.hypot(*(goal - position)))
        target = goal
    direction = target - position
    dist = float(np.hypot(*direction))
    v = np.zeros(2)
    if remaining > params.arrive_radius and dist > 1e-9:
        v = direction / dist * min(params.v_max, params.gain * remaining)
    if neighbours is not None and len(neighbours):
        offsets = position - np.asarray(neighbours, dtype=float).reshape(-1, 2)
        d = np.linalg.norm(offsets, axis=1)
        safe = own_radius + np.asarray(neighbour_radii, dtype=float) + params.avoid_margin
        close = (d < safe) & (d > 1e-9)
        if close.any():
            push = (safe[close] - d[close]) / params.avoid_margin
            v = v + params.avoid_gain * (offsets[close] / d[close, None] * push[:, None]).sum(0)
    if obstacle_samples is not None and len(obstacle_samples):
        offsets = position - np.asarray(obstacle_samples, dtype=float)
        d = np.linalg.norm(offsets, axis=1)
        safe = own_radius + params.avoid_margin
        close = (d < safe) & (d > 1e-9)
        if close.any():
            push = (safe - d[close]) / params.avoid_margin
            v = v + params.avoid_gain * (offsets[close] / d[close, None] * push[:, None]).mean(0)
    return _saturate(v, params.v_max)
