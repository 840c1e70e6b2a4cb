"""Trilateration from TOA ranges to beacons (thesis 3.1.1, eqs. 3.8-3.27).

Subtracting the last beacon's range equation from the others linearises the problem
(eqs. 3.8-3.12): A p = b with A_k = 2 (p_n - p_k) and b_k = r_k^2 - r_n^2 - |p_k|^2 +
|p_n|^2. Three beacons give the unique solution, more give least squares (eq. 3.17,
numpy.linalg.lstsq). Gauss-Newton on the original range residuals (eqs. 3.20-3.27)
refines the estimate, and starts from the propagated estimate when A is rank
deficient. Ranges of unequal quality (an anchor's own position error adds to its range
noise) are weighed by their inverse variances in Gauss-Newton and in the covariance,
the weighted least squares of eq. 3.17; the linear solution is only its start. When all
beacons lie to one side of the agent, the ranges fit a mirror image of its position
almost as well as the position itself and the linear solution may land on either; with
a prior, Gauss-Newton also starts from it and, between two fits within two range-noise
deviations of each other, the one nearer the prior wins. Degenerate geometry
(coincident or collinear beacons without a prior) raises ``DegenerateGeometryError``
instead of returning garbage.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


class DegenerateGeometryError(ValueError):
    """Beacons placed so that the position is not determined by their ranges."""


@dataclass(frozen=True)
class TrilaterationResult:
    """Position (m), its covariance (m^2), the method used and the RMS range residual."""

    position: np.ndarray
    covariance: np.ndarray
    method: str
    residual: float


def _check(beacons: np.ndarray, ranges: np.ndarray) -> None:
    if beacons.ndim != 2 or beacons.shape[1] != 2 or len(beacons) != len(ranges):
        raise ValueError(f'need (n,2) beacons and n ranges, got {beacons.shape} and '
                         f'{ranges.shape}')
    if not (np.all(np.isfinite(beacons)) and np.all(np.isfinite(ranges))):
        raise ValueError('beacon positions and ranges must be finite (NaN/inf given)')
    if np.any(ranges < 0):
        raise ValueError('ranges must be non-negative')


def geometry_rank(beacons: np.ndarray, tol: float = 1e-3) -> int:
    """Rank of the linearised system's matrix: 2 when the beacons span the plane."""
    if len(beacons) < 2:
        return 0
    a = 2.0 * (beacons[-1] - beacons[:-1])
    s = np.linalg.svd(a, compute_uv=False)
    return int(np.sum(s > tol * max(1.0, s[0] if len(s) else 1.0)))


def gauss_newton(beacons: np.ndarray, ranges: np.ndarray, start: np.ndarray,
                 iterations: int = 10, stds: np.ndarray | None = None) -> np.ndarray:
    """Eqs. 3.20-3.27: minimise sum ((|p - p_k| - r_k) / s_k)^2 from ``start`` (s_k the
    range deviations ``stds``; equal weights without them)."""
    p = np.asarray(start, dtype=float).copy()
    w = np.ones(len(ranges)) if stds is None else 1.0 / np.asarray(stds, dtype=float)
    for _ in range(iterations):
        diff = p - beacons
        dist = np.maximum(np.linalg.norm(diff, axis=1), 1e-9)
        jac = diff / dist[:, None]
        res = dist - ranges
        step, *_ = np.linalg.lstsq(jac * w[:, None], -res * w, rcond=None)
        p = p + step
        if np.hypot(*step) < 1e-6:
            break
    return p


def _rms_residual(beacons: np.ndarray, ranges: np.ndarray, p: np.ndarray) -> float:
    return float(np.sqrt(np.mean((np.linalg.norm(p - beacons, axis=1) - ranges) ** 2)))


def trilaterate(beacons, ranges, initial=None, range_std=0.3) -> TrilaterationResult:
    """Position from ranges to >= 3 beacons; see the module docstring. ``range_std`` is
    one deviation for every range or one per range (m)."""
    beacons = np.asarray(beacons, dtype=float).reshape(-1, 2)
    ranges = np.asarray(ranges, dtype=float).reshape(-1)
    _check(beacons, ranges)
    stds = np.asarray(range_std, dtype=float)
    if stds.ndim and stds.shape != ranges.shape:
        raise ValueError(f'need one range_std or one per range ({len(ranges)}), got '
                         f'{stds.shape}')
    stds = np.broadcast_to(stds, ranges.shape)
    if not np.all(np.isfinite(stds) & (stds > 0)):
        raise ValueError('range deviations must be finite and positive')
    typical = float(np.sqrt(np.mean(stds ** 2)))
    if len(beacons) < 3 and initial is None:
        raise DegenerateGeometryError(f'{len(beacons)} beacons cannot fix a 2-D position; '
                                      'at least 3 are needed')
    rank = geometry_rank(beacons)
    if rank < 2:
        if initial is None:
            raise DegenerateGeometryError(
                'beacons are coincident or collinear: the position is ambiguous; '
                'provide a prior estimate or wait for better-spread beacons')
        p = gauss_newton(beacons, ranges, np.asarray(initial, dtype=float), stds=stds)
        method = 'gauss-newton (rank-deficient)'
    else:
        a = 2.0 * (beacons[-1] - beacons[:-1])
        b = (ranges[:-1] ** 2 - ranges[-1] ** 2 - np.sum(beacons[:-1] ** 2, axis=1)
             + np.sum(beacons[-1] ** 2))
        p, *_ = np.linalg.lstsq(a, b, rcond=None)
        method = 'linear' if len(beacons) == 3 else 'least-squares'
        p = gauss_newton(beacons, ranges, p, stds=stds)
        method += '+gauss-newton'
        if initial is not None:
            prior = np.asarray(initial, dtype=float)
            q = gauss_newton(beacons, ranges, prior, stds=stds)
            rp, rq = _rms_residual(beacons, ranges, p), _rms_residual(beacons, ranges, q)
            nearer = np.hypot(*(q - prior)) < np.hypot(*(p - prior))
            # Three ranges fit a mirror image about as well as the truth (one redundant
            # range): keep the prior's side unless the other fit is clearly better.
            if rq < rp - 2.0 * typical or (nearer and rq <= rp + 2.0 * typical):
                p = q
                method = 'gauss-newton (from prior)'
    diff = p - beacons
    dist = np.maximum(np.linalg.norm(diff, axis=1), 1e-9)
    jac = diff / dist[:, None]
    info = jac.T @ jac
    if np.linalg.matrix_rank(info) < 2:
        # All beacons in one direction from the estimate (e.g. identical beacons): the
        # ranges leave a direction unconstrained, whatever the prior was.
        raise DegenerateGeometryError(
            'the beacons all lie in one direction from the estimate (coincident beacons?): '
            'the position is undetermined across it; wait for better-spread beacons')
    cov = np.linalg.inv((jac / stds[:, None] ** 2).T @ jac)
    residual = float(np.sqrt(np.mean((dist - ranges) ** 2)))
    return TrilaterationResult(p, cov, method, residual)


def crlb(beacons, position, range_std) -> np.ndarray:
    """Cramer-Rao lower bound (2x2) of any unbiased position estimate from the ranges
    (``range_std``: one deviation for all, or one per range)."""
    beacons = np.asarray(beacons, dtype=float).reshape(-1, 2)
    diff = np.asarray(position, dtype=float) - beacons
    u = diff / np.maximum(np.linalg.norm(diff, axis=1), 1e-9)[:, None]
    w = np.broadcast_to(np.asarray(range_std, dtype=float) ** -2.0, (len(u),))
    return np.linalg.inv((u * w[:, None]).T @ u)
