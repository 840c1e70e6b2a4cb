"""The robot's brain: one pure object per agent, advanced by time given as an argument.

It combines the algorithms of thesis chapter 3 exactly as an agent runs them:

- DSDV mesh routing (3.1.2) through ``DsdvRouter``; every heartbeat carries this
  agent's ``NeighbourInfo`` (type, beacon flag, mode, estimated position, velocity).
- Localization (3.1.1, 3.1.4) through ``Localizer``: the IMU propagates the Kalman
  filter, a localization tick every period trilaterates against the beacons heard
  directly (their positions from their heartbeats), beacons take GPS fixes; lost and
  return-to-home modes of 3.1.3.
- Formation (3.2): with ``bubble``/``fractal`` goals, the agent computes its cost row
  to the goals of its type (visibility graph + Dijkstra in its free configuration
  space, 3.2.2.2; a beacon only to beacon goals and the others only to the rest,
  ``costs.class_costs``), floods it tagged with the consensus round (every
  ``consensus_period_s``), and at the next round solves the Hungarian assignment over
  the rows of the previous round. Agents holding the same rows compute the same
  assignment; the digest of the rows used is exposed so that agreement can be checked.
  With ``forces`` there are no goals: the artificial forces of 3.2.1.1 act directly.
- Control (3.2.4): a velocity setpoint (proportional to the distance, saturated at
  0.5 m/s) tracked by the LQR inner loop (eqs. 3.108-3.111).
- Collision avoidance (beyond the thesis): every command passes the safety filter of
  ``setpoint.avoid_collisions``, recomputed whenever the proximity sensor reports
  (10 Hz) or the outer loop runs. It acts on the neighbours' offsets measured by the
  proximity sensor while they are fresh, and on their broadcast estimates otherwise.
  A parked robot that a neighbour comes too close to yields, then returns to its goal;
  a robot held still short of its goal gives way (``setpoint.GiveWay``), one held far
  from it goes round the robots that hold it (``detour.Detour``).
- A body that does not accelerate under a force at its limit (``stall.StallDetector``)
  takes the zero-velocity update of a parked robot if its filter agrees that it stands
  (``Localizer.stood_still``), and sidesteps.

Radio frames are authenticated (``swarm_agent.frame_auth``) when the brain is given a
``FrameAuth``: every frame it sends is sealed, every frame it hears is opened first and
dropped, counted by kind in ``auth_stats``, when it fails.

Inputs: ``on_imu``, ``on_gps``, ``on_ranges``, ``on_proximity``, ``on_packet``,
``set_shape``, ``set_goals``. Output: ``step(t)`` returns the packets to send and the
force command; ``snapshot()`` the estimate, mode and assignment for introspection.
"""

from __future__ import annotations

from collections.abc import Sequence
import logging
import math
import zlib

import numpy as np
import shapely

from swarm_agent.assignment import assign
from swarm_agent.assignment import SHARED as SHARED_ASSIGNMENTS
from swarm_agent.brain_config import BrainConfig
from swarm_agent.brain_records import BrainOutput, broadcast_offsets, Neighbour, Snapshot
from swarm_agent.costs import class_costs, VisibilityGraph
from swarm_agent.detour import Detour
from swarm_agent.dsdv import Delivered, DsdvRouter
from swarm_agent.forces import formation_force
from swarm_agent.frame_auth import FrameAuth
from swarm_agent.free_space import grow_obstacles
from swarm_agent.localization import anchor_ranges, Localizer, Mode
from swarm_agent.lqr import LqrGains, VelocityLoop
from swarm_agent.mesh_messages import (
    CostRow,
    MeshMessageError,
    message_kind,
    MSG_COST_ROW,
    NeighbourInfo,
)
from swarm_agent.packet import Kind, Packet
from swarm_agent.reception import receive, Receivers
from swarm_agent.route_table import RouteStore
from swarm_agent.setpoint import (
    avoid_collisions,
    GiveWay,
    stays_parked_each,
    tracking_lag_s,
    velocity_setpoint,
)
from swarm_agent.stall import StallDetector
from swarm_common.goals import Goal, TypeGoals
from swarm_common.robot_types import RobotType
from swarm_common.shapes import Shape
from swarm_mission.contour import sample_boundary

LOG = logging.getLogger(__name__)
_HEARTBEAT = int(Kind.HEARTBEAT)   # compared as int (an Enum comparison per frame adds up)
_FIRST = np.zeros(1, dtype=np.int64)   # one scan's rows start at 0

def _next_tick(due: float, t: float, period: float) -> float:
    """The next due time after ``t`` on the grid ``due + k * period`` (no catch-up bursts)."""
    return due + period * (math.floor((t - due) / period) + 1)


def _inside(shape: Shape, point: np.ndarray) -> bool:
    return bool(shapely.contains_xy(shape.region, float(point[0]), float(point[1])))


class AgentBrain:
    """One agent's decision making; see the module docstring."""

    def __init__(self, config: BrainConfig, robot: RobotType, gains: LqrGains,
                 initial_position: Sequence[float], rng: np.random.Generator,
                 u_max: float | None = None, auth: FrameAuth | None = None,
                 boot_time_s: float = 0.0, route_store: RouteStore | None = None) -> None:
        """``auth`` seals and opens the radio frames; None: unauthenticated (only for
        comparisons and tests: ``agent_factory.make_brain`` gives every brain one).
        ``boot_time_s`` sets the first DSDV sequence number (``dsdv.boot_sequence``).
        ``route_store`` holds the route tables of the process's brains (one store: a
        frame's receivers are routed in one call); None: one of its own."""
        self.config = config
        self.auth = auth
        self.robot = robot
        self.rng = rng
        self.router = DsdvRouter(config.agent_id, config.dsdv, boot_time_s, route_store)
        self.router.set_heartbeat_info(lambda: self._info().encode())
        self._alone = Receivers((self,))     # what ``on_packet`` hands ``receive``
        self.localizer = Localizer(config.localization, np.asarray(initial_position, float))
        self.loop = VelocityLoop(gains, u_max=u_max)
        self.neighbours: dict[int, Neighbour] = {}
        self._ranges: list[tuple[int, float, float]] = []
        self._ranges_at = -math.inf
        self._position_at_ranges = np.asarray(initial_position, float)
        self._outbox: list[Packet] = []
        self._last_t: float | None = None
        self._next_outer = 0.0
        self._next_localization = config.localization.period_s
        self._setpoint = np.zeros(2)
        self._command = np.zeros(2)          # the setpoint after collision avoidance
        self._commanded = False              # whether _command is not zero
        self._avoid_due = True               # recompute _command at the next step
        self._proximity: tuple[np.ndarray, np.ndarray] | None = None
        self._proximity_at = -math.inf
        self._yielding = False
        self._give_way = GiveWay(config.setpoint, robot.coverage_radius)
        self._detour = Detour(config.setpoint, robot.coverage_radius)
        self._stall = StallDetector(u_max, config)
        self._goal_distance = math.inf       # m, at the last outer tick (inf: no goal)
        self._force = np.zeros(2)
        self._parked = False
        self._parked_since: float | None = None
        self._parked_goal: tuple[int, int] = (-1, -1)   # (goal version, goal id)
        # Shape and goals
        self.shape: Shape | None = None
        self.shape_version = 0
        self._graph: VisibilityGraph | None = None
        self._boundary: np.ndarray | None = None
        self._obstacle_samples: np.ndarray | None = None
        self.goals: list[Goal] = []
        self.goal_version = 0
        self._mine = TypeGoals.of((), config.agent_type)   # this type's goals, as arrays
        self._my_goals: Sequence[Goal] = ()
        # Consensus state
        self._rows: dict[int, dict[int, CostRow]] = {}     # round -> agent -> row
        self.goal_id = -1
        self._last_round = -1
        self.assignment_round = 0
        self.assignment_digest = 0
        self.rows_used = 0
        self.stats = {'bad_mesh_messages': 0, 'rows_sent': 0, 'rows_received': 0,
                      'assignments': 0}

    # ------------------------------------------------------------------ inputs
    def set_shape(self, shape: Shape, version: int) -> None:
        """Adopt a new formation shape (and its workspace obstacles)."""
        if version == self.shape_version and self.shape is not None:
            return
        self.shape = shape
        self.shape_version = version
        grown = grow_obstacles(list(shape.obstacles), self.robot.coverage_radius)
        self._graph = VisibilityGraph(grown)
        if self.config.method == 'forces':
            self._boundary = sample_boundary(shape.region, self.config.forces_contour_step)
            if shape.obstacles:
                self._obstacle_samples = np.vstack([
                    sample_boundary(o, self.config.forces_contour_step)
                    for o in shape.obstacles])
        self.localizer.home = np.asarray(shape.centroid, dtype=float)

    def set_goals(self, goals: Sequence[Goal], version: int) -> None:
        """Adopt a new versioned goal list (all types); keep the goal of the same id."""
        if version == self.goal_version:
            return
        self.goals = list(goals)
        self.goal_version = version
        self._mine = TypeGoals.of(goals, self.config.agent_type)
        self._my_goals = self._mine.goals
        self._rows.clear()
        classes = any(g.beacon for g in self._my_goals)
        if not any(g.id == self.goal_id
                   and (not classes or g.beacon == self.config.is_beacon)
                   for g in self._my_goals):
            self.goal_id = -1

    def on_imu(self, t: float, accel: np.ndarray) -> None:
        """Accelerometer sample in the map frame (m/s^2): Kalman prediction (eq. 3.30)."""
        AgentBrain.take_imu(t, (self,), np.asarray(accel, dtype=float).reshape(1, -1))

    @staticmethod
    def take_imu(t: float, brains: Sequence[AgentBrain], accels: np.ndarray) -> None:
        """``on_imu`` for each of ``brains`` with its row of ``accels`` (n, 2): one
        prediction for all (``Localizer.predict_all``); rows not finite are dropped."""
        if accels.shape != (len(brains), 2):
            return
        finite = np.isfinite(accels).all(axis=1)
        if not finite.all():
            brains, accels = [b for b, ok in zip(brains, finite) if ok], accels[finite]
        Localizer.predict_all(t, [b.localizer for b in brains], accels)
        for brain, accel in zip(brains, accels):
            if brain._stall.imu(t, accel, brain.localizer.kf.bias):
                taken = brain.localizer.stood_still()
                brain._stall.stands(t, taken)
                if taken:
                    brain.loop.reset()
                    brain._avoid_due = True     # the sidestep turns the setpoint now

    def on_gps(self, t: float, position: np.ndarray, std: float) -> None:
        """Absolute position fix; only beacons have one."""
        if self.config.is_beacon:
            position = np.asarray(position, dtype=float)
            if position.shape == (2,) and np.all(np.isfinite(position)) and std > 0:
                self.localizer.gps_update(t, position, std)

    def on_ranges(self, t: float, ranges: Sequence[tuple[int, float, float]]) -> None:
        """TOA ranges (beacon id, metres, std) to beacons that are direct neighbours."""
        self._ranges = [(int(b), float(r), float(s)) for b, r, s in ranges
                        if math.isfinite(r) and r >= 0.0 and math.isfinite(s) and s > 0.0]
        self._ranges_at = t
        self._position_at_ranges = self.localizer.position.copy()

    def on_proximity(self, t: float, offsets, radii) -> None:
        """Proximity scan: neighbours' centres minus this robot's (k, 2, map frame, m)
        and their coverage radii (k,). Rows that are not finite are dropped."""
        offsets = np.array(offsets, dtype=float).reshape(-1, 2)    # the brain's own copy
        radii = np.array(radii, dtype=float).reshape(-1)
        if len(offsets) != len(radii):
            return
        AgentBrain.take_proximity(t, (self,), offsets, radii, _FIRST, np.array([len(radii)]))

    @staticmethod
    def take_proximity(t: float, brains: Sequence[AgentBrain], offsets: np.ndarray,
                       radii: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> None:
        """The scans of ``brains`` at ``t`` in one call: brain k saw the rows
        ``starts[k]:ends[k]`` of ``offsets`` (M, 2) and ``radii`` (M,) (a whole world's
        scan: the headless evaluator; one robot's: ``on_proximity``). Rows that are not
        finite are dropped, each brain keeps its rows as views of the kept ones.

        A parked robot at rest (zero setpoint and command) that no neighbour comes too
        close to would get the zero command again (``setpoint.stays_parked``, one call
        for all such brains): its scan changes nothing now and is kept for the next
        recomputation; every other scan makes its brain recompute its command."""
        ok = np.isfinite(offsets).all(axis=1) & np.isfinite(radii) & (radii >= 0.0)
        if not ok.all():
            kept = np.concatenate(([0], np.cumsum(ok)))
            offsets, radii = offsets[ok], radii[ok]
            starts, ends = kept[starts], kept[ends]
        starts, ends = starts.tolist(), ends.tolist()
        at_rest = [k for k, b in enumerate(brains)
                   if b._parked and not b._commanded and not b._stall.sidestepping(t)]
        unchanged: set[int] = set()
        if at_rest:
            clear = stays_parked_each(offsets, radii, [starts[k] for k in at_rest],
                                      [ends[k] for k in at_rest],
                                      [brains[k].robot.coverage_radius for k in at_rest],
                                      [brains[k].config.setpoint for k in at_rest])
            unchanged = {k for k, c in zip(at_rest, clear) if c}
        for k, brain in enumerate(brains):
            lo, hi = starts[k], ends[k]
            brain._proximity = (offsets[lo:hi], radii[lo:hi])
            brain._proximity_at = t
            if k not in unchanged:
                brain._avoid_due = True

    def on_packet(self, t: float, packet: Packet) -> None:
        """A packet heard on the radio: authenticate it, route it, and consume what is
        for this agent (``reception.receive``, as for many brains at once)."""
        receive(t, packet, self._alone)

    def take_routed(self, t: float, packets: Sequence[Packet],
                    delivered: Sequence[Delivered]) -> None:
        """What the router made of a frame heard at ``t``: frames to send, and payloads
        for this agent (neighbours' heartbeat information, cost rows)."""
        self._outbox.extend(packets)
        if delivered:
            AgentBrain.take_delivered(t, (self,), delivered)

    @staticmethod
    def take_delivered(t: float, brains: Sequence[AgentBrain],
                       delivered: Sequence[Delivered]) -> None:
        """Payloads delivered alike to each of ``brains`` at ``t`` (a heartbeat heard by
        many: ``reception.receive``), each decoded once for all of them."""
        for item in delivered:
            try:
                if item.kind == _HEARTBEAT:
                    neighbour = Neighbour(NeighbourInfo.decode(item.payload), t)
                    for brain in brains:
                        brain.neighbours[item.origin] = neighbour
                elif message_kind(item.payload) == MSG_COST_ROW:
                    row = CostRow.decode(item.payload)
                    for brain in brains:
                        brain._store_row(row)
            except MeshMessageError as exc:
                for brain in brains:
                    brain.stats['bad_mesh_messages'] += 1
                    LOG.debug('agent %d dropped a mesh message from %d: %s',
                              brain.config.agent_id, item.origin, exc)

    # ------------------------------------------------------------------ stepping
    def step(self, t: float) -> BrainOutput:
        """Advance to time ``t``: inner velocity loop always, outer loop when due."""
        dt = 0.0 if self._last_t is None else max(0.0, t - self._last_t)
        self._last_t = t
        if not self.config.is_beacon and t >= self._next_localization:
            self._next_localization = _next_tick(self._next_localization, t,
                                                 self.config.localization.period_s)
            self._localize(t)
        if t >= self._next_outer:
            self._next_outer = _next_tick(self._next_outer, t, self.config.outer_period_s)
            self._outer(t)
        self._outbox.extend(self.router.tick(t))
        if self._avoid_due or self._give_way.ended(t):
            self._avoid_due = False
            offsets, radii = self._neighbour_offsets(t)
            # A parked robot applies no force and stands (static friction): its own
            # closing speed is zero, not its velocity estimate's noise. One giving way
            # keeps the parked robot's margin.
            self._command = avoid_collisions(
                self._stall.steer(t, self._setpoint), offsets, radii, self.robot.coverage_radius,
                self.config.setpoint, parked=self._parked or self._give_way.active(t),
                own_velocity=None if self._parked else self.localizer.velocity,
                lag_s=tracking_lag_s(self.robot.fluid_friction, self.loop.gains))
            for held in (self._give_way, self._detour):
                held.observe(t, self._setpoint, self._command, self._goal_distance)
            self._commanded = bool(self._command[0] or self._command[1])
        commanded = self._commanded
        if self._yielding and not commanded:
            # The neighbour has gone: back to the goal, and park there again (the
            # resume hysteresis is for localization noise, not for a real push).
            self._yielding = self._parked = False
        if self._parked and not commanded:
            if self._parked_since is None:
                self._parked_since = t
                self._force = np.zeros(2)
        else:
            # Moving, or parked and yielding to a neighbour that came too close.
            self._yielding = self._parked
            self._parked_since = None
            if dt > 0.0:
                self._force = self.loop.step(dt, self._command, self.localizer.velocity)
        self._stall.force(t, self._force)
        packets, self._outbox = self._outbox, []
        if self.auth is not None and packets:
            seal = self.auth.seal
            packets = [seal(p) for p in packets]
        # No copies (they were 2 % of the headless evaluator): both arrays are replaced,
        # never written in place, so the caller may keep them.
        return BrainOutput(packets, self._force, self._command)

    def rest(self, t: float) -> bool:
        """Take the step at ``t`` if it would do nothing, and say whether it did.

        Nothing is due when the agent is parked with zero force (not yielding, no
        collision check pending), no timer of its own is due (localization, outer loop,
        the router's) and no frame waits to be sent: ``step(t)`` would then only advance
        its clock, which this does. True: the force stays the last one returned (zero)
        and no packets go out; False: call ``step(t)``. Lets a process holding many
        brains skip the 50 Hz steps of parked agents (issue 23, event-driven).
        """
        if (self._parked_since is None or not self._parked or self._commanded
                or self._yielding
                or self._avoid_due or self._outbox or t >= self._next_outer
                or (not self.config.is_beacon and t >= self._next_localization)
                or not self.router.idle(t)):
            return False
        self._last_t = t
        return True

    def snapshot(self) -> Snapshot:
        """The agent's current belief (for AgentState and metrics)."""
        return Snapshot(
            agent_id=self.config.agent_id, agent_type=self.config.agent_type,
            is_beacon=self.config.is_beacon, mode=int(self.localizer.mode),
            position=self.localizer.position.copy(), velocity=self.localizer.velocity.copy(),
            covariance=np.array(self.localizer.covariance, dtype=float).copy(),
            goal_id=self.goal_id, goal_version=self.goal_version,
            assignment_round=self.assignment_round,
            assignment_digest=self.assignment_digest, rows_used=self.rows_used,
            settled=self.settled, localized=self.localizer.stats['localizations'] > 0)

    def status_line(self) -> str:
        """One line for logs: mode, estimate, fixes, neighbourhood and assignment."""
        loc = self.localizer
        beacons = sorted(k for k, n in self.neighbours.items() if n.info.is_beacon)
        return (f'mode {loc.mode.name} at ({loc.position[0]:.2f}, {loc.position[1]:.2f}); '
                f'fixes {loc.stats}; neighbours {len(self.neighbours)}, beacons heard '
                f'{beacons}, ranges {len(self._ranges)}; goal {self.goal_id} '
                f'(v{self.goal_version}, {self.rows_used} rows), gave way '
                f'{self._give_way.count} times, went round {self._detour.count} times, '
                f'stalled {self._stall.count} times; '
                f'mesh {self.stats}; router {self.router.stats}; '
                f'rejected frames {self.auth_stats}')

    @property
    def auth_stats(self) -> dict[str, int]:
        """Frames dropped by the authentication, by kind (``frame_auth.REJECTIONS``)."""
        return dict(self.auth.stats) if self.auth is not None else {}

    @property
    def settled(self) -> bool:
        """Inside the shape (own estimate) and slower than the settling speed (eq. 4.1)."""
        speed = float(np.hypot(*self.localizer.velocity))
        return self.shape is not None and speed < self.config.settle_speed and _inside(
            self.shape, self.localizer.position)

    # ------------------------------------------------------------------ internals
    def _info(self) -> NeighbourInfo:
        pos, vel = self.localizer.position, self.localizer.velocity
        return NeighbourInfo(self.config.agent_type, self.config.is_beacon,
                             int(self.localizer.mode), (float(pos[0]), float(pos[1])),
                             (float(vel[0]), float(vel[1])), self.settled,
                             self.localizer.position_std,
                             self._is_anchor(self._last_t or 0.0))

    def _is_anchor(self, t: float) -> bool:
        """A secondary anchor (localization.py); beacons are primary ones."""
        parked = None if self._parked_since is None else t - self._parked_since
        return not self.config.is_beacon and self.localizer.is_anchor(
            parked, self.config.stand_still_after_s)

    def _drop_stale(self, t: float) -> None:
        """Forget the neighbours not heard for ``neighbour_stale_s``."""
        stale = [k for k, n in self.neighbours.items()
                 if t - n.heard_at > self.config.neighbour_stale_s]
        for k in stale:
            del self.neighbours[k]

    def _localize(self, t: float) -> None:
        """Localization tick (3.1.1, 3.1.3): trilaterate against beacon neighbours, and
        against secondary anchors when this agent is not one (localization.py)."""
        beacons, anchors = [], []
        if t - self._ranges_at <= self.config.range_stale_s:
            self._drop_stale(t)
            beacons, anchors = anchor_ranges(
                self._ranges, self.neighbours, self._ranges_at,
                self.config.localization.beacon_variance_inflation,
                self.config.localization.secondary_anchors and not self._is_anchor(t))
        self.localizer.localize(t, beacons,
                                self.localizer.position - self._position_at_ranges,
                                secondary=anchors)

    def _outer(self, t: float) -> None:
        """The 2 Hz loop: cost report, assignment, setpoint (3.2.2.2, 3.2.4)."""
        self._avoid_due = True
        self._goal_distance = math.inf
        self._drop_stale(t)
        if (self._parked_since is not None
                and t - self._parked_since >= self.config.stand_still_after_s):
            self.localizer.stand_still()
        mode = self.localizer.mode
        position = self.localizer.position
        if self.shape is None:
            self._setpoint = np.zeros(2)
            return
        if mode == Mode.RETURN_HOME:
            # 3.1.3: head for the centre of the formation to meet beacons again, and
            # wait there parked. Holding a zero setpoint instead would servo on a
            # velocity estimate that carries the unobserved accelerometer bias: the body
            # drifts off at bias x time (0.1 m/s after a minute) while the estimate stands.
            target = np.asarray(self.localizer.home, dtype=float)
            distance = float(np.hypot(*(target - position)))
            if distance < self.config.hold_radius or (
                    self._parked and distance < self.config.resume_radius):
                self._parked_goal = (-1, -1)
                self._park()
                return
            self._parked = False
            self._setpoint = self._setpoint_towards(target)
            return
        if self.config.method == 'forces':
            self._parked = False
            self._setpoint = self._forces_setpoint(t)
            return
        rnd = int(math.floor(t / self.config.consensus_period_s + 1e-9))   # the round
        if rnd != self._last_round:
            self._last_round = rnd
            if self._my_goals:
                # LOST agents still report: their dead-reckoned estimate is good for a
                # few periods, and dropping their rows would hand their goals to others
                # while they keep driving to them. RETURN_HOME agents do not report.
                self._report_costs(rnd)
            self._assign(rnd - 1)
        goal = next((g for g in self._my_goals if g.id == self.goal_id), None)
        if goal is None:
            self._park()
            return
        target = np.array([goal.x, goal.y])
        distance = self._goal_distance = float(np.hypot(*(target - position)))
        # Hysteresis around the goal: do not chase localization noise (the estimate
        # jumps by a few decimetres at every trilateration); park and brake instead. A
        # parked agent moves again when the goal is farther than the resume radius by
        # two standard deviations of its own position estimate, when its goal changed,
        # or when it finds itself outside the shape (goals lie closer to the contour
        # than the resume radius; parked outside, eq. 4.1 never holds).
        resume = self.config.resume_radius + 2.0 * self.localizer.position_std
        if (self.goal_version, goal.id) != self._parked_goal:
            self._parked = False
        if distance < self.config.hold_radius or (
                self._parked and distance < resume and _inside(self.shape, position)):
            self._parked_goal = (self.goal_version, goal.id)
            self._park()
            return
        self._parked = False
        self._setpoint = self._setpoint_towards(target)

    def _park(self) -> None:
        """Stop at the goal: zero setpoint, zero force, integral state cleared."""
        if not self._parked:
            self.loop.reset()
        self._parked = True
        self._setpoint = np.zeros(2)

    def _report_costs(self, rnd: int) -> None:
        costs = class_costs(self._graph.cost_row(self.localizer.position, self._mine.positions),
                            self._mine.beacon, self.config.is_beacon)
        row = CostRow.from_costs(self.config.agent_id, self.config.agent_type,
                                 self.goal_version, rnd, costs)
        self._store_row(row)
        self._outbox.extend(self.router.broadcast(self._last_t or 0.0, row.encode()))
        self.stats['rows_sent'] += 1

    def _store_row(self, row: CostRow) -> None:
        if row.agent_type != self.config.agent_type or row.goal_version != self.goal_version:
            return
        if len(row.quantised) != len(self._my_goals):
            self.stats['bad_mesh_messages'] += 1
            return
        if row.agent_id != self.config.agent_id:
            self.stats['rows_received'] += 1
        self._rows.setdefault(row.round, {})[row.agent_id] = row
        for old in [r for r in self._rows if r < row.round - 4]:
            del self._rows[old]

    def _assign(self, rnd: int) -> None:
        """Hungarian assignment over the rows of round ``rnd`` (the same on every agent)."""
        rows = self._rows.get(rnd)
        if not rows or self.config.agent_id not in rows:
            return
        ordered = sorted(rows.items())
        used = b''.join([row.keyed for _, row in ordered])
        goal_ids = self._mine.ids
        # The rows' bytes and the goal ids fix the problem: one solve per process for all
        # the agents holding the same rows (assignment.AssignmentCache).
        result = SHARED_ASSIGNMENTS.get((used, goal_ids), lambda: assign(
            {aid: (row.agent_type, row.costs) for aid, row in ordered},
            self._mine.types, np.array(goal_ids)))
        self.goal_id = int(result.get(self.config.agent_id, -1))
        self.assignment_round = rnd
        self.assignment_digest = zlib.crc32(used)
        self.rows_used = len(rows)
        self.stats['assignments'] += 1

    def _neighbour_offsets(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Neighbours' centres minus this robot's (k, 2) and their radii (k,): measured
        by the proximity sensor while its last scan is fresh, else from the neighbours'
        broadcast estimates (off by both robots' localization errors)."""
        if self._proximity is not None and \
                t - self._proximity_at <= self.config.proximity_stale_s:
            return self._proximity
        self._drop_stale(t)
        return broadcast_offsets(self.neighbours.values(), self.localizer.position,
                                 self.config.type_radii, self.robot.coverage_radius)

    def _setpoint_towards(self, target: np.ndarray) -> np.ndarray:
        position = self.localizer.position
        waypoints = None
        if self._graph is not None and np.hypot(*(target - position)) > 1e-6:
            if self._detour.active:     # round the robots that hold it (detour.Detour)
                waypoints = self._detour.waypoints(position, target, *self._neighbour_offsets(
                    self._last_t), self._graph.obstacles)
            if waypoints is None:
                waypoints = self._graph.path(position, target)
        return velocity_setpoint(position, target, self.config.setpoint, waypoints=waypoints)

    def _forces_setpoint(self, t: float) -> np.ndarray:
        """Artificial forces (3.2.1.1) turned into a velocity setpoint: the steady velocity
        of a mass with viscous and dry friction under the force (``ForceParams.setpoint``).
        An agent the force cannot move parks, as at a goal; it counts as at rest (static
        friction) once it has stood parked through a step."""
        offsets, radii = self._neighbour_offsets(t)
        position = self.localizer.position
        force = formation_force(position, self.localizer.velocity,
                                _inside(self.shape, position), self._boundary,
                                position + offsets, radii,
                                self.robot.coverage_radius, self._obstacle_samples,
                                self.config.forces)
        at_rest = self._parked_since is not None
        v = self.config.forces.setpoint(force, self.config.setpoint.v_max, at_rest)
        if not v.any():
            self._park()
        return v
