"""The anchors of a localization tick: their ranges, their errors and how the errors are
shared (thesis 3.1.1, eqs. 3.8-3.27, and what ``swarm_agent.localization`` adds).

An anchor is a beacon (GPS-fed, thesis 3.1) or a secondary anchor (a parked agent
localized from beacons alone). A range to it is off by its TOA noise and by the
anchor's own position error seen along the line of sight. The own error is not white:
a beacon's estimate (2 m GPS at 1 Hz) is off by about 0.5 m for 20-40 s, and secondary
anchors localized from the same few beacons carry those beacons' errors. Two things
follow, both carried here:

- within one tick, secondary anchors share one displacement (``range_covariance``);
- from one tick to the next, an anchor's error persists: the agent's filter holds it as
  a *consider* parameter (Schmidt-Kalman, ``KalmanFilter.update_ranges``): the
  covariance of the anchor's error with the agent's state is tracked, the error itself
  is not estimated. ``consider_terms`` splits a tick's range covariance into the white
  part (TOA noise) and the anchors' errors, keyed by anchor id.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from dataclasses import replace
import math
from typing import NamedTuple

import numpy as np

from swarm_agent.trilateration import DegenerateGeometryError, trilaterate

# (position, range, std) of a range to an anchor, optionally followed by the part of
# that std which is the anchor's own position error (m); an ``AnchorRange`` also
# carries the anchor's id, for its error as a consider parameter.
Anchor = tuple


class AnchorRange(tuple):
    """A range to an anchor as the trilateration takes it, (position, range, std), that
    also knows the part ``own`` of the std which is the anchor's own position error (m),
    the anchor's ``key``, and, for its error as a consider parameter, the range's TOA
    ``noise`` and the anchor's ``advertised`` deviation (m; ``own`` is that inflated,
    ``localization.anchor_ranges``)."""

    own: float
    key: Hashable
    noise: float
    advertised: float

    def __new__(cls, position: np.ndarray, rng: float, noise: float, advertised: float,
                key: Hashable, inflation: float = 1.0) -> AnchorRange:
        own = advertised * math.sqrt(inflation)
        row = super().__new__(cls, (position, rng, math.hypot(noise, own)))
        row.own, row.key, row.noise, row.advertised = own, key, noise, advertised
        return row


class Row(NamedTuple):
    """One usable range: anchor position (m), range (m), its deviation (m), the part of
    it a secondary anchor shares with the others (m, 0 for beacons), the anchor's own
    position deviation (m) and its id (None: no consider parameter)."""

    position: np.ndarray
    range: float
    std: float
    shared: float
    own: float = 0.0
    key: Hashable | None = None


def usable_rows(anchors: Sequence[Anchor], shared: bool = False,
                consider: bool = False) -> list[Row]:
    """The anchors whose numbers are finite, std positive, as ``Row``; the shared std is
    the anchor's own position error for secondary anchors (``shared``), 0 for beacons,
    whose GPS errors are their own. With ``consider`` an ``AnchorRange``'s error enters
    with its advertised deviation, uninflated, and its key: the filter carries its
    persistence; otherwise with the inflated one and no key (white)."""
    rows = []
    for anchor in anchors:
        p, r, s, *extra = anchor
        own = float(extra[0]) if extra else float(getattr(anchor, 'own', 0.0))
        key = None
        if consider and isinstance(anchor, AnchorRange):
            own, key = anchor.advertised, anchor.key
            s = math.hypot(anchor.noise, own)
        if not (np.all(np.isfinite(p)) and np.isfinite(r) and np.isfinite(s) and s > 0
                and np.isfinite(own)):
            continue
        own = min(max(own, 0.0), float(s))
        rows.append(Row(np.asarray(p, float), float(r), float(s),
                        own if shared else 0.0, own, key))
    return rows


def range_covariance(rows: Sequence[Row], at) -> np.ndarray:
    """Covariance of the rows' range errors seen from ``at`` (m^2).

    A beacon's range error is its own (range noise and its GPS-fed estimate). Secondary
    anchors localized from the same few beacons share those beacons' errors: a common
    displacement d of every anchor, which changes the range to anchor k by u_k . d (u_k
    the unit vector from the agent to it). Any error they all share is at most the
    smallest one's, so d is taken with that variance, c^2 = min_k c_k^2, on every axis:
    R = diag(s_k^2 - c^2 [k anchor]) + c^2 U U^T over the anchors, each range's own
    variance s_k^2 unchanged. Averaging more anchors then cannot bring the fix below
    c across any axis, as their common error does not average out.
    """
    variances = np.array([u.std ** 2 for u in rows])
    shared = [k for k, u in enumerate(rows) if u.shared > 0.0]
    cov = np.diag(variances)
    if len(shared) < 2:
        return cov
    c2 = min(rows[k].shared for k in shared) ** 2
    d = np.array([rows[k].position for k in shared]) - np.asarray(at, float)
    unit = d / np.maximum(np.linalg.norm(d, axis=1), 1e-9)[:, None]
    block = np.ix_(shared, shared)
    cov[block] += c2 * (unit @ unit.T - np.eye(len(shared)))
    return cov


def consider_terms(rows: Sequence[Row], at) -> tuple[list[Hashable], np.ndarray,
                                                      np.ndarray, np.ndarray]:
    """The rows' range errors split for a Schmidt-Kalman update: (keys, slot, white, B).

    ``keys`` are the anchors with an id, one consider parameter each (its 2-D position
    error); ``slot[k]`` is row k's index in ``keys`` (-1: no id, its whole error white).
    ``white`` is the covariance of the rest (TOA noise, m^2): ``range_covariance`` of the
    rows seen from ``at`` with the keyed anchors' own parts taken out. ``B`` (2q x 2q) is
    the anchors' error covariance: own variance on each axis, and between secondary
    anchors the shared displacement's c^2 (``range_covariance``), so H_b B H_b^T + white
    is ``range_covariance`` of the rows.
    """
    keys: list[Hashable] = []
    slot = np.full(len(rows), -1)
    white_rows = []
    for k, u in enumerate(rows):
        if u.key is None or u.own <= 0.0:
            white_rows.append(u)
            continue
        if u.key not in keys:
            keys.append(u.key)
        slot[k] = keys.index(u.key)
        white_rows.append(Row(u.position, u.range, math.sqrt(max(u.std ** 2 - u.own ** 2,
                                                                 1e-12)), 0.0))
    q = len(keys)
    b = np.zeros((2 * q, 2 * q))
    shared = [k for k in range(len(rows)) if slot[k] >= 0 and rows[k].shared > 0.0]
    c2 = min(rows[k].shared for k in shared) ** 2 if len(shared) > 1 else 0.0
    for k in shared:
        for j in shared:
            a, c = 2 * slot[k], 2 * slot[j]
            b[a:a + 2, c:c + 2] = c2 * np.eye(2)
    for k in np.flatnonzero(slot >= 0):
        a = 2 * slot[k]
        b[a:a + 2, a:a + 2] = rows[k].own ** 2 * np.eye(2)
    return keys, slot, range_covariance(white_rows, at), b


def fix_covariance(fix, rows: Sequence[Row]) -> np.ndarray:
    """Covariance of a fix weighed by the rows' own deviations when their errors are
    ``range_covariance``: the sandwich A J^T W R W J A, A = (J^T W J)^-1, W = diag(1 /
    s_k^2) (equal to A when the errors are independent)."""
    pos = np.array([u.position for u in rows])
    d = fix.position - pos
    jac = d / np.maximum(np.linalg.norm(d, axis=1), 1e-9)[:, None]
    wj = jac / np.array([u.std ** 2 for u in rows])[:, None]
    a = fix.covariance
    return a @ wj.T @ range_covariance(rows, fix.position) @ wj @ a


def ranges_only(rows: Sequence[Row], fallback):
    """The fix from the ranges alone (eqs. 3.8-3.17 and Gauss-Newton, no prior), its
    covariance with the anchors' shared error (``range_covariance``)."""
    try:
        free = trilaterate(np.array([u.position for u in rows]),
                           np.array([u.range for u in rows]),
                           range_std=np.array([u.std for u in rows]))
        free = replace(free, covariance=fix_covariance(free, rows))
    except (DegenerateGeometryError, ValueError, np.linalg.LinAlgError):
        return fallback
    return free if np.all(np.isfinite(free.covariance)) else fallback
