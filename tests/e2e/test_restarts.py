"""Restarts through ROS (issue 24): a launcher run whose agent process is SIGKILLed gets
it back, respawned, with DSDV sequence numbers from its new boot time, in every other
agent's route table; a SIGKILLed mission node is respawned, publishes the shape and
goals again and the assignment converges; a SIGKILLed simulator ends the run in one line
with its record written."""

from __future__ import annotations

import contextlib
import json
import os
import pathlib
import signal
import subprocess
import threading
import time

import pytest

from swarm_agent.dsdv import BOOT_RATE, SEQUENCE_MASK
from swarm_eval.bench.soak import writer_of

ROOT = pathlib.Path(__file__).resolve().parents[2]
LAUNCH = ROOT / 'scripts' / 'launch_swarm.py'
SHAPE = ROOT / 'tests' / 'data' / 'square_8m.json'
AGENTS = 4

pytestmark = [pytest.mark.e2e]


class Watch:
    """Every agent's latest route table, agent state and the goal lists published."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile

        from swarm_common import qos
        from swarm_msgs.msg import AgentState, GoalArray, RouteTable

        self.lock = threading.Lock()
        self.routes: dict[int, dict[int, tuple[int, int]]] = {}   # owner -> dest -> (h, seq)
        self.states: dict[int, object] = {}
        self.goals: list[tuple[float, object]] = []               # (wall time, message)
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('restart_watch', context=self.context)
        for a in range(AGENTS):
            self.node.create_subscription(RouteTable, f'agent_{a}/routes', self._on_routes,
                                          QoSProfile(**qos.STATE))
            self.node.create_subscription(AgentState, f'agent_{a}/state', self._on_state,
                                          QoSProfile(**qos.STATE))
        self.node.create_subscription(GoalArray, 'swarm/goals', self._on_goals,
                                      QoSProfile(**qos.LATCHED))
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _on_routes(self, msg) -> None:
        with self.lock:
            self.routes[int(msg.owner)] = {int(r.destination): (int(r.hop_count),
                                                                int(r.sequence_number))
                                           for r in msg.routes}

    def _on_state(self, msg) -> None:
        with self.lock:
            self.states[int(msg.id)] = msg

    def _on_goals(self, msg) -> None:
        with self.lock:
            self.goals.append((time.monotonic(), msg))

    def route_to(self, agent: int) -> dict[int, tuple[int, int]]:
        """owner -> (hops, sequence number) of the other agents' routes to ``agent``."""
        with self.lock:
            return {o: t[agent] for o, t in self.routes.items() if o != agent and agent in t}

    def close(self) -> None:
        import rclpy
        self.executor.shutdown()
        self.thread.join(timeout=5.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


@contextlib.contextmanager
def watching():
    watch = Watch()
    try:
        yield watch
    finally:
        watch.close()


def _launch(processes, out: pathlib.Path, *extra: str) -> subprocess.Popen:
    out.mkdir(parents=True)
    return processes.python(
        str(LAUNCH), '--agents', str(AGENTS), '--beacons', '3', '--shape', str(SHAPE),
        '--half-size', '15', '--duration', '600', '--min-duration', '600', '--rtf', '1',
        '--domain', os.environ['ROS_DOMAIN_ID'], '--out', str(out), *extra,
        stdout=subprocess.DEVNULL, stderr=open(out / 'stderr.txt', 'w'))  # noqa: SIM115


def _until(condition, timeout: float, proc: subprocess.Popen | None = None) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        assert proc is None or proc.poll() is None, 'the launcher stopped early'
        time.sleep(0.1)
    return condition()


def _holder(log: pathlib.Path) -> int:
    """The process writing ``log``: the node (exec'd or forked) of that process name."""
    pid = writer_of(log)
    assert pid is not None, f'no process writes {log}'
    return pid


def _stderr(out: pathlib.Path) -> str:
    return (out / 'stderr.txt').read_text(encoding='utf-8', errors='replace')


def _stop(proc: subprocess.Popen, out: pathlib.Path) -> dict:
    os.kill(proc.pid, signal.SIGINT)
    proc.wait(timeout=60)
    return json.loads((out / 'metrics.json').read_text())['trials'][0]


def test_a_killed_agent_process_is_back_in_every_route_table(processes, tmp_path):
    out = tmp_path / 'agent'
    proc = _launch(processes, out)
    with watching() as watch:
        others = set(range(AGENTS)) - {3}
        assert _until(lambda: {o for o, (h, _) in watch.route_to(3).items() if h < 255}
                      == others, 60.0, proc), 'agent 3 never in every route table'
        old = max(seq for _, seq in watch.route_to(3).values())
        os.kill(_holder(out / 'logs' / 'agent_3.log'), signal.SIGKILL)
        killed = time.monotonic()
        assert _until(lambda: 'agent_3 exited with code -9; started again (1/3)'
                      in _stderr(out), 20.0, proc), _stderr(out)

        def fresh() -> bool:
            # Newer than the old run's numbers by the boot clock (at least a second of it
            # between the boots), not by a neighbour's odd break number plus one.
            routes = watch.route_to(3)
            return set(routes) == others and all(
                h < 255 and 2 * BOOT_RATE <= (seq - old) & SEQUENCE_MASK < 1 << 31
                for h, seq in routes.values())
        assert _until(fresh, 30.0, proc), watch.route_to(3)
        print(f'agent 3 back in every route table {time.monotonic() - killed:.1f} s '
              f'after SIGKILL (sequence {old} -> {min(s for _, s in watch.route_to(3).values())})')

        def assigned() -> bool:   # the new agent 3 has the goals (transient local) again
            with watch.lock:
                goals = [s.assigned_goal for s in watch.states.values()]
                fresh_state = watch.states[3].header.stamp.sec > stamp
            return fresh_state and -1 not in goals and len(set(goals)) == AGENTS
        stamp = watch.states[3].header.stamp.sec + 5
        assert _until(assigned, 30.0, proc), watch.states
    metrics = _stop(proc, out)
    assert metrics['outcome'] == 'interrupted'
    assert (out / 'logs' / 'agent_3.run1.log').is_file()


def test_a_killed_mission_node_is_respawned_and_the_assignment_converges(processes,
                                                                         tmp_path):
    out = tmp_path / 'mission'
    proc = _launch(processes, out, '--composed')
    with watching() as watch:
        def agreed(after: float) -> bool:
            with watch.lock:
                goals = [m for t, m in watch.goals if t > after]
                states = dict(watch.states)
            if not goals or len(states) < AGENTS:
                return False
            version = goals[-1].version
            assigned = [s.assigned_goal for s in states.values()]
            return (len(set(assigned)) == AGENTS and -1 not in assigned
                    and {s.goal_version for s in states.values()} == {version})
        assert _until(lambda: agreed(0.0), 60.0, proc), watch.states
        rounds = {a: s.assignment_round for a, s in watch.states.items()}
        with watch.lock:
            version = watch.goals[-1][1].version
        os.kill(_holder(out / 'logs' / 'mission.log'), signal.SIGKILL)
        assert _until(lambda: 'mission exited with code -9; started again (1/3)'
                      in _stderr(out), 20.0, proc), _stderr(out)
        # Goals taken after this were published by the new node: the old one died at
        # least RESPAWN_DELAY_S before the launcher said it started the new one, and a
        # goals message of the old node whose callback ran late (the watch's thread
        # starved under load) must not count as the new node's.
        respawned = time.monotonic()
        # The new mission node resumes its state file: it publishes the same goals under
        # the same version (transient local), and the agents agree on an assignment of
        # later consensus rounds.
        assert _until(lambda: 'resumed shape' in (out / 'logs' / 'mission.log').read_text()
                      and agreed(respawned) and all(
                          watch.states[a].assignment_round > rounds[a] for a in rounds),
                      40.0, proc), (out / 'logs' / 'mission.log').read_text()
        with watch.lock:
            assert [m.version for t, m in watch.goals if t > respawned][-1] == version
    assert _stop(proc, out)['outcome'] == 'interrupted'


def test_a_killed_simulator_ends_the_run_in_one_line_with_its_record(processes, tmp_path):
    out = tmp_path / 'sim'
    proc = _launch(processes, out, '--composed')
    with watching() as watch:
        assert _until(lambda: len(watch.states) == AGENTS, 60.0, proc)
    time.sleep(2.0)
    os.kill(_holder(out / 'logs' / 'sim.log'), signal.SIGKILL)
    assert proc.wait(timeout=60) == 1
    lines = [line for line in _stderr(out).splitlines() if line.strip()]
    assert len(lines) == 1 and 'the simulator exited with code -9' in lines[0], lines
    metrics = json.loads((out / 'metrics.json').read_text())['trials'][0]
    assert metrics['outcome'] == 'crash of sim'
    assert (out / 'record.npz').is_file()
