"""Seeded rough terrain for the pybullet world (the thesis's rough 3-D territory, 4.1).

The thesis runs its swarm on "a rough 3D territory" of +/-50 m (4.1, Fig. 4.2) but gives
no statistics of it. We model it as a Gaussian random field: white noise on a regular
grid, low-pass filtered with a Gaussian kernel of ``feature`` metres (the typical bump
width), scaled to a root-mean-square height of ``roughness`` metres. The result is pure
numpy, reproducible from the seed, and periodic (the FFT filter wraps), which the walls
hide.

Slopes matter more than heights: a robot stands still on a slope only while
tan(slope) < mu_1 (0.18..0.21 in Table 4.1, i.e. 10..12 degrees), so the defaults
(0.15 m RMS over 3 m bumps: heights within about +/-0.45 m) keep the RMS slope near
2.6 degrees and the steepest cell near 7 degrees, under the friction
angle; ``HeightMap.max_slope_deg`` reports it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DEFAULT_ROUGHNESS = 0.15   # m, RMS height
DEFAULT_FEATURE = 3.0      # m, Gaussian filter width (bump size)
DEFAULT_CELL = 0.5         # m, grid spacing


class TerrainError(ValueError):
    """Terrain parameters that cannot make a height map."""


@dataclass(frozen=True)
class HeightMap:
    """Heights ``z[iy, ix]`` (m) at ``x = -half_size + ix * cell``, likewise y."""

    z: np.ndarray
    half_size: float
    cell: float

    @property
    def shape(self) -> tuple[int, int]:
        """(rows along y, columns along x)."""
        return self.z.shape

    def slopes_deg(self) -> np.ndarray:
        """Slope magnitude of every grid node (degrees), by central differences."""
        gy, gx = np.gradient(self.z, self.cell)
        return np.degrees(np.arctan(np.hypot(gx, gy)))

    @property
    def max_slope_deg(self) -> float:
        """The steepest slope of the map (degrees)."""
        return float(self.slopes_deg().max())

    def height_at(self, xy) -> np.ndarray:
        """Bilinear height at planar points (M, 2); Bullet's triangles differ by mm."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        n_y, n_x = self.z.shape
        fx = np.clip((xy[:, 0] + self.half_size) / self.cell, 0.0, n_x - 1.000001)
        fy = np.clip((xy[:, 1] + self.half_size) / self.cell, 0.0, n_y - 1.000001)
        ix, iy = fx.astype(int), fy.astype(int)
        tx, ty = fx - ix, fy - iy
        z = self.z
        return ((1 - tx) * (1 - ty) * z[iy, ix] + tx * (1 - ty) * z[iy, ix + 1]
                + (1 - tx) * ty * z[iy + 1, ix] + tx * ty * z[iy + 1, ix + 1])


def rough_terrain(half_size: float, seed: int, *, roughness: float = DEFAULT_ROUGHNESS,
                  feature: float = DEFAULT_FEATURE, cell: float = DEFAULT_CELL) -> HeightMap:
    """A seeded Gaussian random field over +/-``half_size`` (see the module docstring)."""
    for name, value in (('half_size', half_size), ('feature', feature), ('cell', cell)):
        if not (np.isfinite(value) and value > 0):
            raise TerrainError(f'terrain {name} must be a positive number of metres, '
                               f'got {value!r}')
    if not (np.isfinite(roughness) and roughness >= 0):
        raise TerrainError(f'terrain roughness must be >= 0 m RMS, got {roughness!r}')
    n = int(round(2.0 * half_size / cell)) + 1
    if n < 3:
        raise TerrainError(f'terrain cell {cell} m is too coarse for a +/-{half_size} m '
                           'workspace; use a cell below half the half size')
    cell = 2.0 * half_size / (n - 1)
    rng = np.random.default_rng(seed)
    noise = rng.standard_normal((n, n))
    k = 2.0 * np.pi * np.fft.fftfreq(n, d=cell)
    kk = k[:, None] ** 2 + k[None, :] ** 2
    z = np.real(np.fft.ifft2(np.fft.fft2(noise) * np.exp(-0.5 * kk * feature ** 2)))
    z -= z.mean()
    std = z.std()
    z = z * (roughness / std) if std > 0 else np.zeros_like(z)
    return HeightMap(z=z, half_size=float(half_size), cell=float(cell))
