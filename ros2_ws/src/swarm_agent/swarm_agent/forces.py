"""Artificial forces method (thesis 3.2.1.1, eqs. 3.80-3.93) with the buffer zone.

The contour integrals are evaluated over equally spaced boundary samples z_k (the
discrete forms of eqs. 3.81, 3.84, 3.90, 3.93), vectorised with numpy: one agent's
force over 10^4 samples costs a few array operations. Each sum is taken as a discrete
integral (times the sample spacing) so the forces do not depend on the sampling step;
attraction and transition are divided by the contour length l(C) as the thesis does.

Buffer zone: instead of switching on the winding number n(C, z_i) (0 or 1), the gains
blend linearly across a band of ``buffer`` metres around the boundary, which removes
the chattering the thesis describes for agents crossing the contour.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ForceParams:
    """Gains of thesis 4.3 and the numerical guards of the singular terms."""

    k_a: float = 250.0      # attractive (outside)
    k_r: float = 150.0      # repulsive from the boundary (inside)
    k_m: float = 1500.0     # inter-member
    k_t: float = 1000.0     # transition (outside, near the boundary)
    k_o: float = 5000.0     # obstacles
    buffer: float = 0.5     # m, width of the blending band around the boundary
    min_gap: float = 0.05   # m, floor of the (d - d_o) and (d - d_c) denominators
    member_range: float = 6.0  # m, neighbours farther than this exert no force


def _signed_distance(position: np.ndarray, samples: np.ndarray, inside: bool) -> float:
    d = float(np.min(np.linalg.norm(samples - position, axis=1)))
    return d if inside else -d


def formation_force(position, velocity, inside: bool, boundary_samples, neighbours,
                    neighbour_radii, own_radius: float, obstacle_samples,
                    params: ForceParams) -> np.ndarray:
    """Total artificial force on one agent (N): eqs. 3.81 + 3.84 + 3.88 + 3.90 + 3.93."""
    z = np.asarray(position, dtype=float)
    samples = np.asarray(boundary_samples, dtype=float).reshape(-1, 2)
    force = np.zeros(2)
    if len(samples) >= 2:
        seg = np.linalg.norm(np.diff(samples, axis=0), axis=1)
        dz = float(np.median(seg)) if len(seg) else 0.0
        length = dz * len(samples)
        s = _signed_distance(z, samples, inside)
        w_in = float(np.clip(0.5 + s / (2.0 * params.buffer), 0.0, 1.0))  # buffer zone
        rel = samples - z                          # z_k - z_i
        dist = np.maximum(np.linalg.norm(rel, axis=1), 1e-6)
        if w_in < 1.0:
            attract = params.k_a / length * rel.sum(axis=0) * dz                 # eq. 3.81
            transit = params.k_t / length * (rel / dist[:, None]).sum(axis=0) * dz  # eq. 3.90
            force += (1.0 - w_in) * (attract + transit)
        if w_in > 0.0:
            force += w_in * params.k_r * (-rel / dist[:, None] ** 3).sum(axis=0) * dz  # 3.84
    if neighbours is not None and len(neighbours):
        nb = np.asarray(neighbours, dtype=float).reshape(-1, 2)
        off = z - nb
        d = np.linalg.norm(off, axis=1)
        d_o = own_radius + np.asarray(neighbour_radii, dtype=float)             # eq. 3.87
        near = (d < params.member_range) & (d > 1e-9)
        gap = np.maximum(d[near] - d_o[near], params.min_gap)
        force += params.k_m * (off[near] / d[near, None] / gap[:, None] ** 2).sum(axis=0)  # 3.88
    if obstacle_samples is not None and len(obstacle_samples):
        obs = np.asarray(obstacle_samples, dtype=float).reshape(-1, 2)
        off = z - obs
        d = np.linalg.norm(off, axis=1)
        step = float(np.median(np.linalg.norm(np.diff(obs, axis=0), axis=1))) if len(obs) > 1 \
            else 1.0
        gap = np.maximum(d - own_radius, params.min_gap)
        near = gap < 3.0
        force += params.k_o * (off[near] / gap[near, None] ** 4).sum(axis=0) * step  # eq. 3.93
    return force
