"""Localization of one agent with lost / return-to-home modes (thesis 3.1.1-3.1.4).

``predict`` runs at the IMU rate, ``localize`` at every localization tick (3 s in the
thesis): with at least three beacon neighbours the agent localizes (NORMAL); otherwise
it counts a miss: LOST at the first, RETURN_HOME after three in a row (3.1.3), back to
NORMAL as soon as it localizes again. Beacons update from their GPS fixes instead. Bad
measurements (NaN, degenerate geometry) count as a miss; nothing raises into the agent
loop.

A localization is a bounded error, not only three ranges: every range is weighed by its
own deviation (the range noise and its anchor's advertised position error), so the
posterior covariance carries the anchors' errors and their geometry (a narrow sector,
or anchors nearly in line with the agent, leave the position poorly determined across
them). A tick whose measurements leave the worst axis above ``localized_max_std`` still
updates the filter but is a miss: the agent stays LOST (3.1.3) until its error is
bounded (``Localizer._localized``).

Beyond the thesis, while the filter's prior is narrow enough for the range circles to
be linearised over it, the ranges update the filter directly (iterated EKF,
``KalmanFilter.update_ranges``) instead of through a trilaterated fix: the prior then
weighs in where the beacons' geometry leaves the fix poorly determined, and one or two
beacon neighbours still correct the dead reckoning of a LOST agent (the mode stays
LOST: a tick without three beacons is a miss, as in 3.1.3). With a wide prior (the
first fix, or after a long stretch without beacons) the agent trilaterates as the
thesis does.

Secondary anchors (beyond the thesis; Kilobot swarms self-assemble by robots localizing
from already localized neighbours). An agent whose tick finds fewer than
``min_beacons`` beacons, or that is moving (no zero-velocity update since its last tick,
``anchors_while_moving``), ranges also to *secondary anchors*: neighbours that are parked,
whose worst-axis deviation is below ``anchor_max_std``, and whose estimate has come from
beacons alone since their last fix of three beacons or more (``beacon_only``). Their
advertised deviation adds to the range noise as a beacon's does (the brain weighs
them). The hierarchy has two levels, so there is no feedback loop: an anchor has
anchored on no agent since its last fix from beacons alone, and an agent that anchors on
one is not an anchor until such a fix, which a parked agent with enough beacons takes
(it ignores anchors then). Parked anchors have had their zero-velocity updates and
are typically known to 0.1-0.5 m, moving beacons (2 m GPS) to 0.5-1.5 m, and they
surround an agent inside the formation where the beacons may all stand on one side.
A tick with enough anchors counts as a localization, as one with enough beacons does.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
import enum
import logging
import math
from typing import Any

import numpy as np
from scipy.special import chdtri

from swarm_agent.anchors import (
    Anchor,
    AnchorRange,
    consider_terms,
    fix_covariance,
    range_covariance,
    ranges_only,
    Row,
    usable_rows,
)
from swarm_agent.kalman import KalmanFilter, predict_all
from swarm_agent.trilateration import DegenerateGeometryError, trilaterate
from swarm_common.parameters import tunable

LOG = logging.getLogger(__name__)
MG = 9.80665e-3  # m/s^2 per milli-g
GATE_1DOF = 10.83  # chi-square (1 dof, 99.9 %)
# A range's Jacobian is the unit vector to its beacon, known within about one deviation
# of the prior over the range (radians): a range update needs it within 0.25 rad.
BEARING_TOLERANCE = 0.25


class Mode(enum.IntEnum):
    """Localization modes; numbers equal swarm_msgs/AgentState MODE_*."""

    NORMAL = 0
    LOST = 1
    RETURN_HOME = 2


@dataclass
class LocalizationConfig:
    """Thesis 4.2 defaults."""

    period_s: float = 3.0                 # s (agent_node parameter localization_period_s)
    accel_noise_std: float = tunable(
        0.01, "IMU acceleration noise of the filter's model, m/s^2 (3.1.4)", low=1e-6, high=10.0)
    accel_bias_max: float = tunable(
        0.1 * MG, "Accelerometer bias bound of the filter's model, m/s^2 (4.2: 0.1 mg)",
        low=0.0, high=1.0)
    min_beacons: int = tunable(3, 'Beacon neighbours a localization tick needs (3.1.1)',
                               low=3, high=64, live=True)
    misses_before_home: int = tunable(3, 'Missed ticks before RETURN_HOME (3.1.3)',
                                      low=1, high=1000, live=True)
    home_position_std: float = tunable(
        1.0, 'RETURN_HOME only when the worst-axis std exceeds this, m (0: the thesis rule)',
        low=0.0, high=100.0, live=True)
    initial_position_std: float = 1.0     # m (agent_node parameter placement_std_m)
    initial_velocity_std: float = tunable(
        0.01, 'Velocity uncertainty at deployment, m/s (robots are deployed standing)',
        low=0.0, high=10.0)
    max_residual: float = tunable(3.0, 'Trilaterations with a worse residual are rejected, m',
                                  low=0.01, high=100.0, live=True)
    max_fix_std: float = tunable(5.0, 'Fix axes less certain than this are not used, m',
                                 low=0.01, high=100.0, live=True)
    gate: float = tunable(13.8, 'Innovation gate, chi-square 2 dof (13.8: 99.9 %)',
                          low=1.0, high=1000.0, live=True)
    max_gated: int = tunable(3, 'Gated fixes in a row after which agreeing ones reinitialize',
                             low=1, high=100, live=True)
    max_speed: float = tunable(1.0, "The robots' reach between two fixes, m/s",
                               low=0.01, high=10.0, live=True)
    zero_velocity_std: float = tunable(
        0.01, "A parked robot's velocity std in its zero-velocity updates, m/s",
        low=1e-4, high=1.0, live=True)
    range_updates: bool = tunable(
        True, 'TOA ranges update the filter directly while its prior is narrow (IEKF)',
        live=True)
    # A beacon's own estimate error persists over 20-40 s (its autocorrelation from one
    # 3 s tick to the next is 0.85-0.92 in the shape study), so a filter taking it
    # as white noise at every tick counts one error several times and grows confident
    # in it. Its variance is inflated: on three shapes of the study the maximum errors
    # were 1.5-1.6 m with 4, 1.8-2.6 m without, 1.4-2.3 m with 8.
    beacon_variance_inflation: float = tunable(
        4.0, "Factor on a beacon's advertised variance (its error persists 20-40 s)",
        low=1.0, high=100.0, live=True)
    secondary_anchors: bool = tunable(
        True, 'Range to parked neighbours localized from beacons when beacons are too few',
        live=True)
    anchor_max_std: float = tunable(
        0.5, 'An agent serves as a secondary anchor only below this worst-axis std, m',
        low=0.01, high=10.0, live=True)
    # 1.5 m / 3: the 99 % error ellipse (chi-square 2 dof: 3.03 deviations) of a fix
    # whose worst axis is at most this lies within 1.5 m.
    localized_max_std: float = tunable(
        0.5, 'A tick localizes (NORMAL) only if it leaves the worst-axis std below this, m',
        low=0.01, high=100.0, live=True)
    anchors_while_moving: bool = tunable(
        True, 'A moving agent ranges to secondary anchors even with enough beacons',
        live=True)
    # An anchor's error persists over 20-40 s (module docstring). Above 0 it is a
    # consider parameter of the filter, first-order Gauss-Markov with this time
    # constant; 0 takes it as white with the variance inflated (beacon_variance_inflation),
    # which on the 60 shapes of the shape study left the maximum errors lower
    # (docs/localization.md).
    anchor_error_time_s: float = tunable(
        0.0, "Time constant of an anchor's persistent position error, s (0: white)",
        low=0.0, high=1000.0)


def _chi2_999(dof: int) -> float:
    """99.9 % quantile of chi-square with ``dof`` degrees of freedom."""
    return float(chdtri(dof, 0.001))


def anchor_ranges(ranges: Sequence[tuple[int, float, float]], neighbours: Mapping[int, Any],
                  ranges_at: float, inflation: float, use_anchors: bool
                  ) -> tuple[list[Anchor], list[Anchor]]:
    """(beacons, secondary anchors) of a tick: an ``AnchorRange`` (position, range, std;
    the anchor's own std and id) for each range (id, metres, std) to a neighbour heard
    (``neighbours``: id -> its last heartbeat's ``info`` and ``heard_at``) that is a
    localized beacon, or, with ``use_anchors``, an agent advertising itself as a
    secondary anchor.

    Where the anchor was when the range was measured: its last heartbeat extrapolated
    with its own velocity estimate. Its own position uncertainty adds to the range
    noise: as advertised when the filter holds it as a consider parameter, inflated by
    ``inflation`` (``beacon_variance_inflation``) when it is taken as white noise
    (``anchor_error_time_s`` 0), the inflation standing in for its persistence.
    """
    beacons: list[Anchor] = []
    anchors: list[Anchor] = []
    for anchor_id, rng_m, std in ranges:
        heard = neighbours.get(anchor_id)
        if heard is None:
            continue
        info = heard.info
        if info.is_beacon and info.mode == Mode.NORMAL:
            into = beacons
        elif use_anchors and info.anchor and not info.is_beacon:
            into = anchors
        else:
            continue
        where = np.asarray(info.position) + (ranges_at - heard.heard_at) * np.asarray(
            info.velocity)
        into.append(AnchorRange(where, rng_m, std, info.position_std, anchor_id, inflation))
    return beacons, anchors


class Localizer:
    """Kalman filter + trilateration + modes for one agent."""

    def __init__(self, config: LocalizationConfig, initial_position,
                 initial_velocity=(0.0, 0.0), home=None) -> None:
        self.config = config
        self.kf = KalmanFilter(initial_position, initial_velocity,
                               position_std=config.initial_position_std,
                               velocity_std=config.initial_velocity_std,
                               accel_noise_std=config.accel_noise_std,
                               accel_bias_std=config.accel_bias_max,
                               consider_time_s=config.anchor_error_time_s)
        self.mode = Mode.NORMAL
        self.missed_localizations = 0
        self.home = np.asarray(home if home is not None else initial_position, float)
        self._t: float | None = None
        self.stats = {'localizations': 0, 'misses': 0, 'rejected': 0, 'gated': 0,
                      'relocalizations': 0, 'partial': 0, 'range_updates': 0,
                      'secondary': 0, 'uncertain': 0}
        # The estimate has come from beacons alone since the last fix of min_beacons
        # beacons (module docstring, "Secondary anchors"); a deployment prior has not.
        self.beacon_only = False
        # Fixes gated in a row: (fix, its covariance, its time).
        self._gated: list[tuple[np.ndarray, np.ndarray, float]] = []
        # A zero-velocity update since the last tick: the robot stands parked.
        self._standing = False
        self._still: tuple = (None, None, None)   # stand_still's (std, z, R)
        # When each anchor held as a consider parameter was last ranged to.
        self._anchor_used: dict[Any, float] = {}

    @property
    def position(self) -> np.ndarray:
        return self.kf.x[:2]

    @property
    def velocity(self) -> np.ndarray:
        return self.kf.x[2:4]

    @property
    def position_std(self) -> float:
        """Standard deviation of the position estimate (m, mean of the two axes)."""
        p = self.kf.P
        return float(np.sqrt(max(0.5 * (p[0, 0] + p[1, 1]), 0.0)))

    @property
    def covariance(self) -> np.ndarray:
        return self.kf.P[:4, :4]

    def is_anchor(self, parked_for: float | None, stand_still_after_s: float) -> bool:
        """Serves as a secondary anchor (module docstring): parked for ``parked_for`` s
        (None: moving), at least ``stand_still_after_s`` (its zero-velocity updates have
        begun), beacon-only and confident. Beacons are primary anchors: the caller
        excludes them."""
        return (self.config.secondary_anchors and self.beacon_only
                and parked_for is not None and parked_for >= stand_still_after_s
                and self.worst_std <= self.config.anchor_max_std)

    @property
    def worst_std(self) -> float:
        """Standard deviation of the position along its least certain axis (m)."""
        # The larger eigenvalue of the 2 x 2 position block in closed form (a tenth of
        # the time of eigvalsh, asked at every heartbeat and localization tick).
        a, b, c = float(self.kf.P[0, 0]), float(self.kf.P[1, 0]), float(self.kf.P[1, 1])
        return math.sqrt(max(0.5 * (a + c) + math.hypot(0.5 * (a - c), b), 0.0))

    def predict(self, t: float, accel) -> None:
        """IMU sample at time ``t`` (map-frame acceleration, m/s^2)."""
        Localizer.predict_all(t, (self,), np.asarray(accel, float).reshape(1, 2))

    @staticmethod
    def predict_all(t: float, localizers: Sequence[Localizer], accels: np.ndarray) -> None:
        """``predict`` for each of ``localizers`` with its row of ``accels`` (n, 2), in one
        call for all (``kalman.predict_all``)."""
        predict_all([loc.kf for loc in localizers],
                    [0.0 if loc._t is None else t - loc._t for loc in localizers], accels)
        for loc in localizers:
            loc._t = t

    def set_state(self, position, velocity, position_std: float,
                  velocity_std: float) -> None:
        """Overwrite the estimate with a direct measurement of it (hardware: camera poses).

        Without an IMU there is no prediction step; the overhead camera measures the
        position to about a centimetre and its displacement gives the velocity.
        """
        kf = self.kf
        kf.x = np.zeros_like(kf.x)
        kf.x[:2] = np.asarray(position, float)
        kf.x[2:4] = np.asarray(velocity, float)
        variances = np.zeros(len(kf.x))
        variances[:2] = position_std ** 2
        variances[2:4] = velocity_std ** 2
        variances[4:] = kf.P.diagonal()[4:]
        kf.P = np.diag(variances)
        kf.forget_consider()
        self.mode = Mode.NORMAL
        self.missed_localizations = 0

    def hold(self, position_std: float, velocity_std: float) -> None:
        """No measurement for a while (hardware: the camera has lost the robot).

        The estimate stays where the last measurement put it, with the grown
        uncertainty the caller gives (how far the robot can have driven since), and the
        agent counts as LOST: it cannot localize (3.1.3).
        """
        self.set_state(self.position.copy(), self.velocity.copy(), position_std,
                       velocity_std)
        self.mode = Mode.LOST

    def widen(self, position_std: float, velocity_std: float = 0.0) -> None:
        """The robot may be up to about ``position_std`` (m) from the estimate and move at
        up to about ``velocity_std`` (m/s): each deviation becomes at least that, its
        correlations dropped, so the first trilateration places the robot (3.1.1)
        instead of being gated as far from a confident prior, and consecutive fixes
        give its velocity instead of a standing robot's dead reckoning."""
        p = self.kf.P.copy()
        widened = False
        for block, std in ((slice(0, 2), position_std), (slice(2, 4), velocity_std)):
            if std ** 2 > np.linalg.eigvalsh(p[block, block])[-1]:
                p[block, :] = 0.0
                p[:, block] = 0.0
                p[block, block] = np.eye(2) * std ** 2
                widened = True
        if not widened:
            return
        self.kf.P = p
        self.kf.forget_consider()
        self.beacon_only = False

    def restarted(self, t: float) -> None:
        """This agent's process started at run time ``t`` (s), its robot's body possibly
        driving since t = 0: from the deployment prior it may have driven ``max_speed``
        * t and it may be moving at up to ``max_speed`` (``widen``)."""
        speed = self.config.max_speed
        self.widen(speed * t, speed)

    def stand_still(self) -> None:
        """Zero-velocity update: the robot is parked (no force, held by dry friction).

        Beyond the thesis, the classic zero-velocity update of inertial navigation. The
        fixes carry slowly varying errors (a beacon's own estimate wanders by a metre
        over tens of seconds under 2 m GPS noise), which a filter that only knows white
        measurement noise reads as motion: a parked robot's velocity estimate then
        reaches 0.1 m/s, its position runs off by metres between fixes, the parking
        hysteresis is exceeded and the robot drives after its own error. A robot that
        commands no force and has had time to stop knows it stands still.
        """
        std = self.config.zero_velocity_std
        if self._still[0] != std:      # z and R made once per setting (2 Hz per robot)
            self._still = (std, np.zeros(2), np.eye(2) * std ** 2)
        self.kf.update_velocity(self._still[1], self._still[2])
        self._standing = True

    def stood_still(self) -> bool:
        """Zero-velocity update of a body judged standing from its accelerometer alone
        (``swarm_agent.stall``), taken only if the filter's velocity agrees: its squared
        Mahalanobis distance from zero within ``gate``. A body that slides along an
        obstacle at constant speed reads as one that stands; its filter has integrated
        no stop and still holds that speed, and forcing it to zero would also move the
        position back along the whole stretch the velocity was correlated over (a
        robot sliding at 0.45 m/s after 20 s without a fix: 9 m). True if taken."""
        std = self.config.zero_velocity_std
        v, p_vv = self.kf.x[2:4], self.kf.P[2:4, 2:4] + np.eye(2) * std ** 2
        if float(v @ np.linalg.solve(p_vv, v)) > self.config.gate:
            return False
        self.stand_still()
        return True

    def gps_update(self, t: float, position, std: float) -> None:
        """Absolute fix (beacons; camera poses on hardware)."""
        self.kf.update_position(position, np.eye(2) * std ** 2)
        self.mode = Mode.NORMAL
        self.missed_localizations = 0

    def localize(self, t: float, beacons: Sequence[tuple[np.ndarray, float, float]],
                 displacement=(0.0, 0.0),
                 secondary: Sequence[tuple[np.ndarray, float, float]] = ()) -> Mode:
        """Localization tick: (beacon position, range, range std) per beacon neighbour,
        and the same per secondary anchor (used when the beacons are fewer than
        ``min_beacons``; module docstring).

        The ranges may be older than the tick (TOA ranging runs at its own rate):
        ``displacement`` is the agent's own dead-reckoned motion since they were
        measured, so the fix is solved where the agent was and moved to where it is.
        Between two fixes the IMU integration drifts by millimetres (3.1.4), while a
        robot at 0.5 m/s moves a metre in two seconds.
        """
        shift = np.asarray(displacement, dtype=float)
        consider = self.config.anchor_error_time_s > 0
        usable = usable_rows(beacons, consider=consider)
        enough = len(usable) >= self.config.min_beacons
        moving = self.config.anchors_while_moving and not self._standing
        self._standing = False
        extra = usable_rows(secondary, shared=True, consider=consider) \
            if secondary and (moving or not enough) else []
        before = self._updates()
        mode = self._tick(t, usable + extra, shift)
        if self._updates() != before:
            if extra:
                self.beacon_only = False
                self.stats['secondary'] += 1
            elif enough:
                self.beacon_only = True
        return mode

    def _updates(self) -> tuple[int, ...]:
        s = self.stats
        return (s['localizations'], s['range_updates'], s['partial'], s['relocalizations'],
                s['uncertain'])

    def _tick(self, t: float, usable: list[Row], shift: np.ndarray) -> Mode:
        """``localize`` with the anchors chosen and checked."""
        tight = self._range_update(usable, shift) if usable else None
        enough = len(usable) >= self.config.min_beacons
        if enough:
            pos = np.array([u.position for u in usable])
            rng = np.array([u.range for u in usable])
            std = np.array([u.std for u in usable])
        if enough and tight is not None:
            if tight:
                self._gated.clear()
                self._localized()
                return self.mode
            # Ranges inconsistent with the filter: judge them by a fix of their own.
            free = ranges_only(usable, None)
            if free is not None and free.residual <= self.config.max_residual:
                self._gate(t, free.position + shift, free.covariance)
                return self.mode
            self.stats['rejected'] += 1
        elif tight is False:
            self.stats['gated'] += 1    # one or two ranges the filter does not believe
        elif enough:
            try:
                fix = trilaterate(pos, rng, initial=self.position - shift, range_std=std)
                fix = replace(fix, covariance=fix_covariance(fix, usable))
            except (DegenerateGeometryError, ValueError, np.linalg.LinAlgError) as exc:
                LOG.debug('trilateration rejected: %s', exc)
                self.stats['rejected'] += 1
            else:
                z = fix.position + shift
                variances, axes = np.linalg.eigh(fix.covariance)   # ascending
                if fix.residual > self.config.max_residual:
                    self.stats['rejected'] += 1
                elif variances[-1] > self.config.max_fix_std ** 2:
                    self._update_along_beacon_line(z, axes[:, 0], float(variances[0]))
                    return self.mode
                elif self.kf.innovation_distance(z, fix.covariance) > self.config.gate:
                    # Judge a suspicious fix by the ranges alone: from the prior, the
                    # trilateration keeps the prior's side of a mirror ambiguity, and
                    # the prior is what may be wrong (a filter locked on the mirror
                    # image of the robot would only ever be confirmed).
                    free = ranges_only(usable, fix)
                    self._gate(t, free.position + shift, free.covariance)
                    return self.mode
                else:
                    self._gated.clear()
                    self.kf.update_position(z, fix.covariance)
                    self._localized()
                    return self.mode
        return self._miss()

    def _miss(self) -> Mode:
        """A tick without a localization: LOST, RETURN_HOME after ``misses_before_home``
        in a row (3.1.3)."""
        self.missed_localizations += 1
        self.stats['misses'] += 1
        # 3.1.3 sends an agent home because without trilaterations its estimate drifts;
        # one whose ranges to one or two beacons keep it within ``home_position_std``
        # (along its worst axis) drives on to its goal, LOST.
        home = (self.missed_localizations >= self.config.misses_before_home
                and self.worst_std > self.config.home_position_std)
        self.mode = Mode.RETURN_HOME if home else Mode.LOST
        return self.mode

    def _range_update(self, usable: list[Row], shift: np.ndarray) -> bool | None:
        """Update the filter with the ranges themselves (iterated EKF).

        None when it does not apply: range updates are off, or the prior is too wide for
        a range circle to be linearised over it (the circle of radius r bends away from
        its tangent by s^2 / (2 r) over a distance s; that must stay below the range's
        deviation sigma over one deviation s of the prior, and the direction to the
        beacon, s / r uncertain, within ``BEARING_TOLERANCE``), or, with three beacons or
        more, for any one of them (the thesis's trilateration then gives the fix). With
        fewer than three, the ranges that qualify are used. False when the ranges are
        inconsistent with the filter (normalised innovation beyond chi-square 99.9 %):
        nothing is updated. True when the filter took them.
        """
        if not self.config.range_updates:
            return None
        variance = float(np.linalg.eigvalsh(self.kf.P[:2, :2])[-1])
        linear = [u for u in usable if variance <= 2.0 * u.range * u.std
                  and variance <= (BEARING_TOLERANCE * u.range) ** 2]
        if not linear or (len(usable) >= self.config.min_beacons and len(linear) < len(usable)):
            return None
        beacons = np.array([u.position for u in linear])
        ranges = np.array([u.range for u in linear])
        at = self.position - shift
        consider = None
        if self.config.anchor_error_time_s > 0:
            keys, slot, cov, b = consider_terms(linear, at)
            consider = (keys, slot, b) if keys else None
        else:
            cov = range_covariance(linear, at)
        if self.kf.range_nis(beacons, ranges, cov, shift, consider) > _chi2_999(len(linear)):
            return False
        self.kf.update_ranges(beacons, ranges, cov, shift, consider=consider)
        self.stats['range_updates'] += 1
        if consider is not None:
            self._held(consider[0])
        return True

    def _held(self, keys) -> None:
        """The anchors just ranged to are held as consider parameters; those not ranged
        to for three time constants (their errors 95 % decorrelated) are dropped."""
        t = self._t if self._t is not None else 0.0
        for key in keys:
            self._anchor_used[key] = t
        horizon = 3.0 * self.config.anchor_error_time_s
        self._anchor_used = {k: ti for k, ti in self._anchor_used.items() if t - ti <= horizon}
        self.kf.forget_consider(self._anchor_used)

    def _localized(self) -> None:
        """The filter took the tick's measurements. It is a localization (NORMAL) only
        when they leave the estimate within ``localized_max_std`` along its worst axis:
        anchors in a narrow sector or nearly in line with the agent determine it poorly
        across them (their geometric dilution of precision), and their own errors weigh
        in through their advertised deviations, so the posterior covariance bounds the
        error the fix leaves. A poorer fix still updates the filter, but the agent is
        not localized yet: the tick is a miss and the agent stays LOST (3.1.3)."""
        if self.worst_std > self.config.localized_max_std:
            self.stats['uncertain'] += 1
            self._miss()
            return
        self.mode = Mode.NORMAL
        self.missed_localizations = 0
        self.stats['localizations'] += 1

    def _update_along_beacon_line(self, z: np.ndarray, u: np.ndarray, var: float) -> None:
        """A fix determined along one direction only: use that direction alone.

        Beacons nearly in line as seen from the agent barely constrain the position
        across that line. The fix's covariance is the linearisation at the solution,
        valid while the range circles' curvature over one deviation d stays below the
        range noise, d^2 / (2 r) < sigma: 4-7 m for 10-25 m ranges and 1 m of noise.
        Beyond ``max_fix_std`` the solution across the line can sit on a fold or on the
        mirror image of the agent, with a covariance that does not describe it, so only
        the well-determined component along the line updates the filter (gated at
        chi-square 1 dof, 99.9 %); the IMU carries the other. ``u`` is that axis (the
        covariance's eigenvector of least variance) and ``var`` its variance.
        """
        innovation = float(u @ (z - self.position))
        if innovation ** 2 / (float(u @ self.kf.P[:2, :2] @ u) + var) > GATE_1DOF:
            self.stats['gated'] += 1
            return
        self.kf.update_along(u, float(u @ z), var)
        self.stats['partial'] += 1
        self._localized()

    def _gate(self, t: float, z: np.ndarray, cov: np.ndarray) -> None:
        """A fix far outside the filter's and its own uncertainty.

        Either the fix is wrong (a mirror solution, a beacon that moved unannounced)
        or the filter is: a velocity or bias estimate gone wrong makes dead reckoning
        run away while the filter's covariance, which only knows the IMU's white noise,
        stays small, and then every later fix is gated too. One fix cannot tell;
        fixes that keep agreeing with each other can. After ``max_gated`` gated fixes
        in a row, one that agrees with all of them reinitializes the filter.

        Agreement must not lean on the filter (its dead-reckoned displacement is what
        may be wrong), so it is physical: two fixes taken dt apart agree when their
        distance is within the robot's reach, ``max_speed`` * dt, plus the chi-square
        gate on their summed covariances. Fixes that scatter farther never move the
        filter: they are noise, and the agent dead-reckons on.
        """
        reach = [self.config.max_speed * (t - ti) for _, _, ti in self._gated]
        consistent = all(
            max(float(np.hypot(*(z - zi))) - r, 0.0) ** 2
            <= self.config.gate * float(np.linalg.eigvalsh(cov + ci)[-1])
            for (zi, ci, _), r in zip(self._gated, reach))
        if len(self._gated) >= self.config.max_gated and consistent:
            self._gated.clear()
            self._reinitialize(z, cov)
            return
        self.stats['gated'] += 1
        self._gated.append((z.copy(), np.asarray(cov, float).copy(), t))
        del self._gated[:-self.config.max_gated]

    def _reinitialize(self, z: np.ndarray, cov: np.ndarray) -> None:
        """Restart the filter at the fix: position and covariance from the fix; velocity
        and bias keep their values but not their claimed precision (the divergence
        shows they may be wrong), so the next fixes correct them. A plain Kalman update
        with a tens-of-metres innovation would instead move the velocity through the
        position-velocity correlation and drive a standing robot across the field.
        """
        kf = self.kf
        kf.x = kf.x.copy()
        kf.x[:2] = z
        variances = np.zeros(len(kf.x))
        variances[2:4] = np.maximum(kf.P.diagonal()[2:4], (0.5 * self.config.max_speed) ** 2)
        variances[4:] = np.maximum(kf.P.diagonal()[4:], self.config.accel_bias_max ** 2)
        p = np.diag(variances)
        p[:2, :2] = cov
        kf.P = p
        kf.forget_consider()
        self.stats['relocalizations'] += 1
        self._localized()
