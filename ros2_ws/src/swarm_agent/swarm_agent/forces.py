"""Artificial forces method (thesis 3.2.1.1, eqs. 3.80-3.93) with the buffer zone.

The contour integrals are evaluated over equally spaced boundary samples z_k (the
discrete forms of eqs. 3.81, 3.84, 3.90, 3.93), vectorised with numpy: one agent's
force over 10^4 samples costs a few array operations. Each sum is taken as a discrete
integral (times the sample spacing) so the forces do not depend on the sampling step.
Only the attraction is divided by the contour length l(C), as the thesis does under
eq. 3.81; the transition force is the plain contour integral of eq. 3.89, so near the
contour it is l(C) times stronger than the attraction there and outweighs the
inter-member push of the agents already inside (it is what gets an agent across the
contour, also where the centroid that eq. 3.81 pulls towards lies outside a
non-convex shape, as in the notch of thesis_shape_2).

Buffer zone (thesis 3.2.1.1, after eq. 3.94): instead of switching on the winding number
n(C, z_i) (0 or 1), the gains blend linearly across a band of ``buffer`` metres just
inside the contour: attraction and transition are at their nominal values on and
outside the contour and fade to zero ``buffer`` metres inside it, the repulsion rises
from zero on the contour to its nominal value there. The band lies inside because
eq. 3.84 is singular on the contour: blended into the outside as well, it would push
an agent outwards with a 1/d^2 barrier right at the contour, and agents would park
just outside the shape.

Inter-member forces (eq. 3.88) act only within ``member_range`` and are shifted so that
they vanish there continuously: the brain sees its neighbours through the 3 m proximity
sensor, and a force cut at the sensor's range would jump by k_m / (3 - d_o)^2 (about
260 N) whenever a neighbour crosses it, at the spacing 50 agents take in 314 m^2.

From force to motion (``ForceParams.setpoint``): the thesis's agents are masses with
viscous and dry friction (eq. 3.75, Table 4.1) pushed by u_i = sum of the forces
(eq. 3.79). The brain commands a velocity, so it commands the steady velocity of such a
mass, v = (|F| - F_k) / b along F (``speed_per_newton`` is 1 / b, saturated at v_max),
and an agent at rest stays at rest until |F| exceeds the static friction F_s > F_k.
Without the friction an agent never stops: the force it computes fluctuates by about
13 N per axis at rest (2 cm proximity noise on neighbours about 500 N/m stiff, and
the jumps of its own position estimate), so F_s is several of those above F_k. 1 / b
keeps the loop gain 1 / b * K below about 1 / tau at the equilibrium spacing (K about
0.5-1.5 kN/m there, tau about 0.75 s: half the 2 Hz period plus the LQR loop's lag),
so the agents do not overshoot the balance point and chase it back and forth; far
from the shape the forces are still large enough to saturate at v_max.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarm_common.parameters import tunable


@dataclass
class ForceParams:
    """Gains of thesis 4.3, the numerical guards of the singular terms, and the virtual
    friction that turns the force into a velocity setpoint (see the module docstring)."""

    k_a: float = tunable(250.0, 'Attractive gain outside the shape (4.3)', low=0.0, high=1e6,
                         live=True)
    k_r: float = tunable(150.0, 'Repulsive gain from the boundary inside (4.3)', low=0.0,
                         high=1e6, live=True)
    k_m: float = tunable(1500.0, 'Inter-member gain (4.3)', low=0.0, high=1e6, live=True)
    k_t: float = tunable(1000.0, 'Transition gain outside, near the boundary (4.3)', low=0.0,
                         high=1e6, live=True)
    k_o: float = tunable(5000.0, 'Obstacle gain (4.3)', low=0.0, high=1e6, live=True)
    buffer: float = tunable(0.5, 'Width of the blending band just inside the boundary, m',
                            low=0.0, high=10.0, live=True)
    min_gap: float = tunable(0.05, 'Floor of the (d - d_o) and (d - d_c) denominators, m',
                             low=1e-4, high=1.0, live=True)
    member_range: float = tunable(
        3.0, 'Where the (shifted) inter-member force reaches zero, m', low=0.01, high=100.0,
        live=True)
    speed_per_newton: float = tunable(
        0.001, 'Setpoint speed per newton above the kinetic friction, m/s/N (1 / b)',
        low=0.0, high=1.0, live=True)
    kinetic_friction: float = tunable(
        40.0, 'F_k: a moving agent stops below this force, N', low=0.0, high=1e4, live=True)
    static_friction: float = tunable(
        120.0, 'F_s: an agent at rest starts above this force, N', low=0.0, high=1e4,
        live=True)

    def setpoint(self, force, v_max: float, at_rest: bool) -> np.ndarray:
        """Velocity setpoint (m/s) under ``force`` (N): the steady velocity of a mass with
        viscous friction 1 / speed_per_newton and dry friction (kinetic F_k, static F_s)
        pushed by it, saturated at ``v_max``; zero while the force cannot move the agent
        (``at_rest``: it stands still now)."""
        f = np.asarray(force, dtype=float)
        mag = float(np.hypot(f[0], f[1]))
        if mag <= (self.static_friction if at_rest else self.kinetic_friction):
            return np.zeros(2)
        speed = min(self.speed_per_newton * (mag - self.kinetic_friction), v_max)
        return f * (speed / mag)


def _signed_distance(position: np.ndarray, samples: np.ndarray, inside: bool) -> float:
    d = float(np.min(np.linalg.norm(samples - position, axis=1)))
    return d if inside else -d


def formation_force(position, velocity, inside: bool, boundary_samples, neighbours,
                    neighbour_radii, own_radius: float, obstacle_samples,
                    params: ForceParams) -> np.ndarray:
    """Total artificial force on one agent (N): eqs. 3.81 + 3.84 + 3.88 + 3.90 + 3.93.

    ``velocity`` is not used: the friction that damps the thesis's masses is in
    ``ForceParams.setpoint`` (the commanded velocity is already the viscous steady state;
    a -b v term here would only scale the force down and add the velocity estimate's
    noise)."""
    z = np.asarray(position, dtype=float)
    samples = np.asarray(boundary_samples, dtype=float).reshape(-1, 2)
    force = np.zeros(2)
    if len(samples) >= 2:
        seg = np.linalg.norm(np.diff(samples, axis=0), axis=1)
        dz = float(np.median(seg)) if len(seg) else 0.0
        length = dz * len(samples)
        s = _signed_distance(z, samples, inside)
        w_in = float(np.clip(s / params.buffer, 0.0, 1.0))  # buffer zone, inside only
        rel = samples - z                          # z_k - z_i
        dist = np.maximum(np.linalg.norm(rel, axis=1), 1e-6)
        if w_in < 1.0:
            attract = params.k_a / length * rel.sum(axis=0) * dz                 # eq. 3.81
            transit = params.k_t * (rel / dist[:, None]).sum(axis=0) * dz  # eq. 3.90
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
        # Eq. 3.88 minus its value at member_range: zero there, no jump.
        edge = np.maximum(params.member_range - d_o[near], params.min_gap)
        mag = np.maximum(1.0 / gap ** 2 - 1.0 / edge ** 2, 0.0)
        force += params.k_m * (off[near] / d[near, None] * mag[:, None]).sum(axis=0)  # 3.88
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
