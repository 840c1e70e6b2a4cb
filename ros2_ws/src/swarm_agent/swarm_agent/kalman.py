"""Kalman filter of the local positioning system (thesis 3.1.4, eqs. 3.28-3.44).

The thesis's state is x = [x, y, vx, vy] in the map frame with the accelerometer as the
input of the propagation (eq. 3.30): x+ = F x + G u, F = [[I, dt I], [0, I]],
G = [[dt^2/2 I], [dt I]], and its white noise (0.01 m/s^2) in Q = sigma_a^2 G G^T.
Position fixes (trilateration, or GPS for beacons) update it with their own covariance R
(eqs. 3.34-3.44, Joseph form).

Beyond the thesis, the accelerometer bias (up to 0.1 mg, 4.2) is estimated as two more
states, x = [x, y, vx, vy, bx, by] with u - b as the acceleration. A constant bias
treated as white noise makes the filter overconfident: over a 300 s run 0.1 mg drifts
the dead-reckoned position by 0.5 b t^2 = 44 m, the covariance still shrinks with every
fix, and the filter ends up ignoring (or gating) the fixes that would correct it. With
the bias in the state the fixes estimate it. ``estimate_bias=False`` gives the thesis's
four-state filter.

Beyond the thesis, the anchors' position errors are *consider* parameters (the
Schmidt-Kalman filter; Tapley, Schutz and Born, Statistical Orbit Determination, 2004,
ch. 6): a range to an anchor whose advertised position is off by beta is off by
-u . beta (u the unit vector from the anchor to the agent), and beta persists from one
tick to the next. The filter keeps the covariance ``cross`` of its state error with the
beta of every anchor it has ranged to, propagates it (beta first-order Gauss-Markov with
time constant ``consider_time_s``: C <- exp(-dt / tau) F C) and updates it, but never
estimates beta itself. A second range to the same anchor then no longer counts its error
as new: the state already carries it.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
import math

import numpy as np

from swarm_common.jit import kernel


class KalmanFilter:
    """Position, velocity (and accelerometer bias) filter with the IMU as input."""

    def __init__(self, position, velocity=(0.0, 0.0), position_std: float = 1.0,
                 velocity_std: float = 0.1, accel_noise_std: float = 0.01,
                 accel_bias_std: float = 0.001, estimate_bias: bool = True,
                 bias_walk_std: float = 1e-5, consider_time_s: float = math.inf) -> None:
        self.estimate_bias = estimate_bias
        n = 6 if estimate_bias else 4
        self.x = np.zeros(n)
        self.x[:2] = np.asarray(position, float)
        self.x[2:4] = np.asarray(velocity, float)
        variances = [position_std ** 2] * 2 + [velocity_std ** 2] * 2
        if estimate_bias:
            variances += [accel_bias_std ** 2] * 2
            self.q = accel_noise_std ** 2
        else:
            # The thesis's filter: the bias allowance can only enter as white noise.
            self.q = accel_noise_std ** 2 + accel_bias_std ** 2
        self.P = np.diag(variances)
        self.bias_walk = bias_walk_std ** 2  # (m/s^2)^2 per second
        self._h = np.zeros((2, n))
        self._h[0, 0] = self._h[1, 1] = 1.0
        self._h_velocity = np.roll(self._h, 2, axis=1)   # H = [0 I 0]
        self._dt: float | None = None  # the IMU period is fixed: F and Q built once per dt
        self.consider_time_s = consider_time_s
        self.consider_keys: list[Hashable] = []      # two consider parameters each
        self.cross = np.zeros((n, 0))                # cov(truth - x, beta), (n, 2 keys)

    def _model(self, dt: float) -> None:
        n = len(self.x)
        i2 = np.eye(2)
        f = np.eye(n)
        f[:2, 2:4] = dt * i2
        g = np.zeros((n, 2))
        g[:2] = 0.5 * dt * dt * i2
        g[2:4] = dt * i2
        q = self.q * (g @ g.T)
        if self.estimate_bias:
            f[:4, 4:6] = -g[:4]           # the bias is subtracted from the input
            q[4:6, 4:6] = self.bias_walk * dt * i2
        self._f, self._g, self._q, self._dt = f, g, q, dt
        tau = self.consider_time_s
        self._decay = math.exp(-dt / tau) if tau > 0 else 0.0
        # Filters with equal keys hold equal F, G, Q and decay (``predict_all``).
        self._model_key = (dt, self.q, self.bias_walk, self.estimate_bias, tau)

    @property
    def bias(self) -> np.ndarray:
        """Estimated accelerometer bias (m/s^2); zeros for the four-state filter."""
        return self.x[4:6] if self.estimate_bias else np.zeros(2)

    def predict(self, dt: float, accel) -> None:
        """Propagate by ``dt`` seconds with the measured acceleration (eqs. 3.30-3.33)."""
        predict_all((self,), (dt,), np.asarray(accel, float).reshape(1, 2))

    def innovation_distance(self, z, R) -> float:
        """Squared Mahalanobis distance of a position fix from the prediction.

        Chi-square with 2 degrees of freedom when the filter and the fix are consistent
        (99.9 % of consistent fixes fall below 13.8).
        """
        s = self.P[:2, :2] + np.asarray(R, float)
        y = np.asarray(z, float) - self.x[:2]
        return float(y @ np.linalg.solve(s, y))

    def update(self, h: np.ndarray, z, R) -> None:
        """Linear measurement z = H x + v, v ~ N(0, R) (eqs. 3.34-3.44, Joseph form)."""
        self.x, self.P, self.cross = _update(
            self.x, self.P, self.cross, np.atleast_2d(np.asarray(h, float)),
            np.atleast_1d(np.asarray(z, float)), np.atleast_2d(np.asarray(R, float)))

    def update_position(self, z, R) -> None:
        """Measurement update with a position fix z (2,) of covariance R."""
        self.update(self._h, z, R)

    def update_along(self, direction, z: float, var: float) -> None:
        """Update with the position's component along the unit vector ``direction``.

        A fix that constrains one direction only (H = u^T [I 0]), leaving the other
        direction to the IMU.
        """
        self.update(np.asarray(direction, float) @ self._h, z, var)

    def range_model(self, x: np.ndarray, beacons: np.ndarray, offset) -> tuple[
            np.ndarray, np.ndarray]:
        """Predicted ranges h(x) = |p - offset - b_k| and their Jacobian H (m, n).

        ``offset`` is the agent's own motion since the ranges were measured: they
        were taken at p - offset.
        """
        d = x[:2] - np.asarray(offset, float) - beacons
        ranges = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)
        h = np.zeros((len(beacons), len(x)))
        h[:, :2] = d / ranges[:, None]
        return ranges, h

    def range_nis(self, beacons, ranges, variances, offset=(0.0, 0.0),
                  consider: Consider | None = None) -> float:
        """Normalised innovation squared of a set of ranges at the prediction
        (``variances``: one per range, or their covariance matrix when they share errors;
        ``consider``: the anchors' persistent errors, ``update_ranges``).

        Chi-square with len(ranges) degrees of freedom when the filter, the beacons'
        positions and the ranges are consistent (and the linearisation holds).
        """
        predicted, h = self.range_model(self.x, np.asarray(beacons, float), offset)
        c0, b = self._consider_prior(consider)
        hb = _consider_jacobian(h, consider, b)
        s = h @ self.P @ h.T + _noise(variances) + hb @ b @ hb.T \
            + h @ c0 @ hb.T + hb @ c0.T @ h.T
        y = np.asarray(ranges, float) - predicted
        return float(y @ np.linalg.solve(s, y))

    def update_ranges(self, beacons, ranges, variances, offset=(0.0, 0.0),
                      iterations: int = 5, consider: Consider | None = None) -> None:
        """Iterated extended Kalman update with TOA ranges (Gauss-Newton on the prior
        and the ranges, the maximum a posteriori estimate; Joseph form at the end).
        ``variances``: one per range, or their covariance matrix (the white part of the
        errors when ``consider`` is given).

        The linearisation is taken at the current iterate, not at the prediction, so
        the curvature of the range circles costs nothing once the iteration converges.

        ``consider`` = (keys, slot, B): range k is to anchor ``keys[slot[k]]`` (slot -1:
        no consider parameter), whose position errors have covariance B (2q x 2q). The
        Schmidt-Kalman update: with H_b the ranges' dependence on the anchors' errors
        (-u_k^T in anchor k's slot) and C the state's covariance with them,
        S = H P H^T + H C H_b^T + H_b C^T H^T + H_b B H_b^T + R, K = (P H^T + C H_b^T)
        S^-1, C <- C - K (H C + H_b B); the anchors' errors are not estimated.
        """
        beacons = np.asarray(beacons, float)
        z = np.asarray(ranges, float)
        r = _noise(variances)
        x0, p0 = self.x.copy(), self.P
        cols = self._columns(consider[0]) if consider is not None else np.zeros(0, int)
        c0, b = self._consider_prior(consider)
        self.cross[:, cols] = c0
        x = x0
        for _ in range(iterations):
            predicted, h = self.range_model(x, beacons, offset)
            hb = _consider_jacobian(h, consider, b)
            pht = p0 @ h.T + c0 @ hb.T
            s = h @ pht + hb @ (c0.T @ h.T + b @ hb.T) + r
            k = pht @ np.linalg.inv(s)
            step = x0 + k @ (z - predicted - h @ (x0 - x))
            converged = float(np.hypot(*(step[:2] - x[:2]))) < 1e-4
            x = step
            if converged:
                break
        ikh = np.eye(len(x)) - k @ h
        mixed = ikh @ c0 @ hb.T @ k.T
        self.x = x
        p = ikh @ p0 @ ikh.T - mixed - mixed.T + k @ (hb @ b @ hb.T + r) @ k.T
        self.P = 0.5 * (p + p.T)
        self.cross = ikh @ self.cross
        if len(cols):
            self.cross[:, cols] -= k @ hb @ b

    def _columns(self, keys: Sequence[Hashable]) -> np.ndarray:
        """The columns of ``cross`` of ``keys`` (two each), new keys added with none."""
        new = [key for key in dict.fromkeys(keys) if key not in self.consider_keys]
        if new:
            self.consider_keys.extend(new)
            self.cross = np.hstack([self.cross, np.zeros((len(self.x), 2 * len(new)))])
        index = {key: j for j, key in enumerate(self.consider_keys)}
        return np.array([2 * index[key] + a for key in keys for a in (0, 1)], dtype=int)

    def _consider_prior(self, consider: Consider | None) -> tuple[np.ndarray, np.ndarray]:
        """(C, B) of ``update_ranges``: the state's covariance with the anchors' errors
        (zero for anchors not held yet) and theirs. The joint covariance [[P, C], [C^T,
        B]] must be positive semi-definite, i.e. P - C B^-1 C^T too; an anchor's
        advertised error shrinks between two ranges to it (it was localized again), so
        C is scaled down, all its correlations alike, until that holds."""
        if consider is None:
            return np.zeros((len(self.x), 0)), np.zeros((0, 0))
        keys, _, b = consider
        b = np.asarray(b, float)
        index = {key: j for j, key in enumerate(self.consider_keys)}
        c0 = np.zeros((len(self.x), 2 * len(keys)))
        for j, key in enumerate(keys):
            if key in index:
                c0[:, 2 * j:2 * j + 2] = self.cross[:, 2 * index[key]:2 * index[key] + 2]
        if not np.any(c0):
            return c0, b
        vals, vecs = np.linalg.eigh(self.P)
        w = (vecs / np.sqrt(np.maximum(vals, 1e-18))).T @ c0      # P^-1/2 C
        top = float(np.linalg.eigvalsh(w @ np.linalg.solve(b, w.T))[-1])
        if top > CORRELATION_LIMIT:
            c0 *= math.sqrt(CORRELATION_LIMIT / top)
        return c0, b

    def forget_consider(self, keep: Sequence[Hashable] = ()) -> None:
        """Drop the consider parameters not in ``keep`` (anchors long out of use, or all
        of them when the state is set anew)."""
        keep = set(keep)
        held = [j for j, key in enumerate(self.consider_keys) if key in keep]
        self.cross = self.cross[:, [2 * j + a for j in held for a in (0, 1)]]
        self.consider_keys = [self.consider_keys[j] for j in held]

    def update_velocity(self, z, R) -> None:
        """Measurement update with a velocity z (2,) of covariance R (H = [0 I 0])."""
        self.update(self._h_velocity, z, R)


def predict_all(filters: Sequence[KalmanFilter], dts: Sequence[float],
                accels: np.ndarray) -> None:
    """Propagate each filter by its ``dt`` (s) with its row of ``accels`` (n, 2), the
    measured accelerations (eqs. 3.30-3.33; ``dt`` <= 0: left as it is).

    One function for one filter (``KalmanFilter.predict``, an agent alone) or many (the
    agents of a process, at one IMU sample): the filters of one model (equal F, G, Q and
    consider decay) holding as many consider columns are stacked and propagated in one
    kernel call. Each gets rows of new arrays, as one call each would give it new arrays.
    """
    groups: dict[tuple, list[int]] = {}
    for i, (kf, dt) in enumerate(zip(filters, dts)):
        if dt <= 0:
            continue
        if kf._dt is None or abs(dt - kf._dt) > 1e-9:
            kf._model(dt)
        groups.setdefault((kf._model_key, kf.cross.shape[1]), []).append(i)
    for rows in groups.values():
        kfs = [filters[i] for i in rows]
        model = kfs[0]
        xs, ps, crosses = _propagate(
            model._f, model._g, model._q, np.array([kf.x for kf in kfs]),
            np.array([kf.P for kf in kfs]), np.array([kf.cross for kf in kfs]),
            accels[rows] if len(rows) < len(accels) else accels, model._decay)
        for kf, x, p, cross in zip(kfs, xs, ps, crosses):
            kf.x, kf.P, kf.cross = x, p, cross


_N, _M = np.zeros(6), np.zeros((6, 6))


@kernel(_M, np.zeros((6, 2)), _M, _N[None], _M[None], np.zeros((1, 6, 2)), np.zeros((1, 2)),
        1.0)
def _propagate(f: np.ndarray, g: np.ndarray, q: np.ndarray, xs: np.ndarray, ps: np.ndarray,
               crosses: np.ndarray, accels: np.ndarray, decay: float) -> tuple[
                   np.ndarray, np.ndarray, np.ndarray]:
    """The prediction (eqs. 3.30-3.33) of filters of one model: each row's x, P and
    consider covariance ``cross`` propagated by F, G, Q with its measured acceleration
    (``predict_all``)."""
    xs_out, ps_out = np.empty_like(xs), np.empty_like(ps)
    crosses_out = np.empty_like(crosses) if crosses.shape[2] > 0 else crosses
    for i in range(xs.shape[0]):
        xs_out[i] = f @ xs[i] + g @ accels[i]
        ps_out[i] = f @ ps[i] @ f.T + q
        if crosses.shape[2] > 0:
            crosses_out[i] = (f @ crosses[i]) * decay
    return xs_out, ps_out, crosses_out


@kernel(_N, _M, np.zeros((6, 2)), np.zeros((2, 6)), np.zeros(2), np.eye(2))
def _update(x: np.ndarray, p: np.ndarray, cross: np.ndarray, h: np.ndarray, z: np.ndarray,
            r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Linear measurement z = H x + v, v ~ N(0, R) (eqs. 3.34-3.44, Joseph form):
    x, P and ``cross`` updated (``KalmanFilter.update``); z does not depend on the
    consider parameters, so their covariance with the state only shrinks by (I - KH)."""
    s = h @ p @ h.T + r
    k = p @ h.T @ np.linalg.inv(s)
    x = x + k @ (z - h @ x)
    ikh = np.eye(x.shape[0]) - k @ h
    p = ikh @ p @ ikh.T + k @ r @ k.T
    if cross.shape[1] > 0:
        cross = ikh @ cross
    return x, p, cross


# (anchor keys, each range's index into them or -1, the anchors' error covariance)
Consider = tuple[Sequence[Hashable], Sequence[int], np.ndarray]
# The largest eigenvalue of P^-1/2 C B^-1 C^T P^-1/2 kept: the anchors' errors can
# explain at most this share of the state's error in any direction.
CORRELATION_LIMIT = 0.99


def _consider_jacobian(h: np.ndarray, consider: Consider | None, b: np.ndarray) -> np.ndarray:
    """H_b: range k depends on its anchor's error beta by -u_k . beta (``h``'s position
    columns are u_k^T); zero rows for ranges without a consider parameter."""
    hb = np.zeros((len(h), len(b)))
    if consider is not None:
        for row, j in enumerate(consider[1]):
            if j >= 0:
                hb[row, 2 * j:2 * j + 2] = -h[row, :2]
    return hb


def _noise(variances) -> np.ndarray:
    """Measurement covariance from per-measurement variances (1-D) or a full matrix."""
    v = np.asarray(variances, float)
    return np.diag(v) if v.ndim == 1 else v
