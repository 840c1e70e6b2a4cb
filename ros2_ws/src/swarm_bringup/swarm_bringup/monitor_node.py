"""monitor_node: records a running swarm for metrics and plots (never read by agents).

Subscribes ``swarm/truth`` (swarm_msgs/SwarmTruth), ``swarm/shape``,
``swarm/goals`` and every ``agent_K/state`` (swarm_msgs/AgentState), and keeps a
2 Hz record of truth and belief: true positions and velocities, estimated positions,
modes, assigned goals and assignment digests. At every truth message it checks the
settled condition of eq. 4.1 (``settle``, a ``swarm_sim.metrics.SettleTracker``; a new
shape or goal list is a change). ``scripts/launch_swarm.py`` runs it inside the
launcher process and turns the record into ``metrics.json`` and figures.

Given a ``RecordLog`` (``swarm_sim.run_record``), the record goes to its file as the run
goes and the node holds no sample (an hour of 50 agents would be 40 MB in memory), and a
killed launcher leaves it on disk; without one, it is kept in memory. ``record()``
returns it as arrays at the end either way.
"""

from __future__ import annotations

import sys
import threading

import numpy as np
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import QoSProfile

from swarm_agent.conversions import stamp_seconds
from swarm_common import qos
from swarm_common.conversions import goals_from_msg, shape_from_msg
from swarm_common.ros_support import lean_subscription, run_node
from swarm_common.shapes import ShapeError
from swarm_msgs.msg import AgentState, FormationShape, GoalArray, SwarmTruth
from swarm_sim.metrics import inside_mask, SETTLE_HOLD_S, SETTLE_SPEED, settled_now, SettleTracker
from swarm_sim.run_record import read_record_log, RecordLog

# The record's fields and their types (the header of a streamed record).
RECORD_DTYPES = {'times': 'float64', 'positions': 'float64', 'velocities': 'float64',
                 'estimates': 'float64', 'modes': 'int64', 'alive': 'bool',
                 'goal_ids': 'int64', 'digests': 'int64', 'rounds': 'int64',
                 'localized': 'bool'}


def logged_arrays(log: RecordLog, dtypes: dict[str, str]) -> dict[str, np.ndarray]:
    """Close ``log`` and read its rows back as arrays of ``dtypes`` (empty arrays when it
    has no row; the writer's ``wall`` stamps left out)."""
    log.close()
    record = read_record_log(log.path).record
    return {k: record[k] if k in record else np.zeros(0, dtype=t) for k, t in dtypes.items()}


class MonitorNode(Node):
    """Collects truth and agent states; see the module docstring."""

    def __init__(self, agent_ids: list[int] | None = None,
                 settle_hold_s: float = SETTLE_HOLD_S, record_log: RecordLog | None = None,
                 **kwargs) -> None:
        super().__init__('swarm_monitor', **kwargs)
        self.declare_parameter('agent_ids', list(agent_ids or [0]),
                               ParameterDescriptor(description='Agent ids to watch'))
        self.declare_parameter('record_period_s', 0.5,
                               ParameterDescriptor(description='Recording period (sim time)'))
        self.agent_ids = [int(a) for a in self.get_parameter('agent_ids').value]
        self.period = float(self.get_parameter('record_period_s').value)
        self.lock = threading.Lock()
        self.index = {a: i for i, a in enumerate(self.agent_ids)}
        n = len(self.agent_ids)
        self.states: list[AgentState | None] = [None] * n
        self.truth: SwarmTruth | None = None
        self.shapes: list[tuple[float, object]] = []
        self.shape = None
        self.goals: list = []
        self.goal_version = 0
        self.record_log = record_log
        self._rows: dict[str, list] = {k: [] for k in RECORD_DTYPES}   # without a log
        self._last_record = -1e9
        self.rounds_seen: set[int] = set()
        self.settle = SettleTracker(settle_hold_s)
        state_qos = QoSProfile(**qos.STATE)
        self.create_subscription(SwarmTruth, 'swarm/truth', self._on_truth, state_qos)
        self.create_subscription(FormationShape, 'swarm/shape', self._on_shape,
                                 QoSProfile(**qos.LATCHED))
        self.create_subscription(GoalArray, 'swarm/goals', self._on_goals,
                                 QoSProfile(**qos.LATCHED))
        for agent in self.agent_ids:
            lean_subscription(self, AgentState, f'agent_{agent}/state', self._on_state,
                              state_qos)

    def now(self) -> float:
        """Current (sim) time in seconds."""
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_shape(self, msg: FormationShape) -> None:
        try:
            shape = shape_from_msg(msg)
        except ShapeError:
            return
        with self.lock:
            self.shape = shape
            self.shapes.append((self._truth_time(), shape))
            self.settle.change(self._truth_time())

    def _on_goals(self, msg: GoalArray) -> None:
        with self.lock:
            self.goals = goals_from_msg(msg)
            self.goal_version = msg.version
            self.settle.change(self._truth_time())

    def _on_state(self, msg: AgentState) -> None:
        i = self.index.get(int(msg.id))
        if i is not None:
            with self.lock:
                self.states[i] = msg
                if msg.assignment_round:
                    self.rounds_seen.add(int(msg.assignment_round))

    def change(self, t: float) -> None:
        """A commanded change at sim time ``t`` (a fault, a setting): the settled streak
        ends without counting a re-departure (SettleTracker.change)."""
        with self.lock:
            self.settle.change(t)

    def _truth_time(self) -> float:
        if self.truth is None:
            return 0.0
        return stamp_seconds(self.truth.header.stamp)

    def _on_truth(self, msg: SwarmTruth) -> None:
        with self.lock:
            self.truth = msg
            t = self._truth_time()
            n = len(self.agent_ids)
            pos = np.full((n, 2), np.nan)
            vel = np.zeros((n, 2))
            alive = np.zeros(n, dtype=bool)
            for a in msg.agents:
                i = self.index.get(int(a.id))
                if i is not None:
                    pos[i] = a.position
                    vel[i] = a.velocity
                    alive[i] = a.alive
            self.settle.update(t, self.shape is not None and alive.any()
                               and settled_now(self.shape, pos, vel, alive))
            if t - self._last_record < self.period - 1e-6:
                return
            self._last_record = t
            states = self.states
            row = {
                'times': t, 'positions': pos, 'velocities': vel, 'alive': alive,
                'estimates': np.array([s.position if s is not None else (np.nan, np.nan)
                                       for s in states], dtype=float),
                'modes': np.array([s.mode if s is not None else -1 for s in states]),
                'goal_ids': np.array([s.assigned_goal if s is not None else -1
                                      for s in states]),
                'digests': np.array([s.assignment_digest if s is not None else 0
                                     for s in states], dtype=np.int64),
                'rounds': np.array([s.assignment_round if s is not None else 0
                                    for s in states], dtype=np.int64),
                'localized': np.array([bool(s is not None and s.localized) for s in states])}
            if self.record_log is not None:
                self.record_log.add(row)
            else:
                for key, value in row.items():
                    self._rows[key].append(value)

    def record(self) -> dict[str, np.ndarray]:
        """The record as numpy arrays (thread-safe); a streamed one is closed and read
        back (the monitor records nothing after)."""
        with self.lock:
            if self.record_log is not None:
                return logged_arrays(self.record_log, RECORD_DTYPES)
            return {k: np.asarray(v) for k, v in self._rows.items()}

    def _settled_truth(self) -> int:
        """Robots settled by eq. 4.1 in truth: slower than SETTLE_SPEED inside the shape.

        Judged by the evaluator on ground truth (like metrics.settling_time); an agent's
        own ``settled`` flag rests on its estimate, which hovers near the threshold.
        """
        if self.truth is None or self.shape is None:
            return 0
        alive = [a for a in self.truth.agents if a.alive]
        if not alive:
            return 0
        pos = np.array([a.position for a in alive], dtype=float)
        speed = np.hypot(*np.array([a.velocity for a in alive], dtype=float).T)
        return int(np.sum(inside_mask(self.shape, pos) & (speed < SETTLE_SPEED)))

    def live_status(self) -> dict:
        """Sim time, settled agents (truth) and mode counts for the progress line."""
        with self.lock:
            states = [s for s in self.states if s is not None]
            return {
                't': self._truth_time(),
                'agents_heard': len(states),
                'settled': self._settled_truth(),
                'normal': sum(1 for s in states if s.mode == AgentState.MODE_NORMAL),
                'lost': sum(1 for s in states if s.mode == AgentState.MODE_LOST),
                'return_home': sum(1 for s in states if s.mode == AgentState.MODE_RETURN_HOME),
                'goal_version': self.goal_version,
                'settle_held': self.settle.held(self._truth_time()),
            }


def main(args=None) -> None:
    """Run the monitor alone (records until Ctrl-C)."""
    run_node(MonitorNode, 'monitor_node', args)


if __name__ == '__main__':
    main(sys.argv)
