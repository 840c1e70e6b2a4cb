"""One swarm over two hosts, joined only through DDS: two network namespaces, one veth.

Namespace A (10.77.0.1) runs what the launcher runs on the world's host: the sim, the
mission, the monitor and agents 0-3 composed. Namespace B (10.77.0.2) runs agents 4-7
composed (``--agents-only``), like a second machine would. Both keep discovery on
localhost and name the other side in ROS_STATIC_PEERS, as two real hosts would.

Asserts that the shape forms as in the single-host e2e test (every agent settles inside,
agreement, no goal claimed twice), that the traffic really crossed (the monitor in A
heard every agent's state, every robot started outside the shape and ended inside it,
so B's agents drove their robots through A's sim, and the data went over the veth both
ways), and that the isolation is real (without static peers, A does not see B's nodes).

Needs root and ``ip`` (iproute2); skips with the reason otherwise.
"""

from __future__ import annotations

import json
import os
import pathlib
import signal
import subprocess
import sys

from netns import NetnsPair, unavailable_reason
import pytest
import yaml

ROOT = pathlib.Path(__file__).resolve().parents[2]
LAUNCH = ROOT / 'scripts' / 'launch_swarm.py'
PROBE = pathlib.Path(__file__).resolve().parent / 'ros_probe.py'
SHAPE = ROOT / 'tests' / 'data' / 'square_8m.json'
AGENTS, SPLIT = 8, 4

pytestmark = [pytest.mark.e2e, pytest.mark.slow, pytest.mark.timeout(600)]


@pytest.fixture
def two_hosts():
    """A fresh namespace pair, destroyed with everything still inside it."""
    reason = unavailable_reason()
    if reason:
        pytest.skip(reason)
    NetnsPair.reap_stale()
    pair = NetnsPair()
    try:
        pair.create()
    except RuntimeError as exc:
        pytest.skip(f'cannot set up two network namespaces: {exc}')
    try:
        yield pair
    finally:
        pair.destroy()


def _env(pair: NetnsPair, side: str, peers: bool = True) -> dict[str, str]:
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONUNBUFFERED='1')
    env.pop('ROS_STATIC_PEERS', None)
    if peers:
        env['ROS_STATIC_PEERS'] = pair.peer_of(side)
    return env


def _look(processes, pair: NetnsPair, peers: bool, seconds: float) -> bool:
    """Serve a node in B, look for it from A; True if A discovered it in ``seconds``."""
    name = f'probe_b_{"peers" if peers else "alone"}'
    server = processes.start(pair.command('b', [sys.executable, str(PROBE), 'serve', name]),
                             env=_env(pair, 'b', peers), stdout=subprocess.DEVNULL)
    try:
        look = subprocess.run(
            pair.command('a', [sys.executable, str(PROBE), 'look', name, str(seconds)]),
            env=_env(pair, 'a', peers), capture_output=True, text=True, timeout=seconds + 60)
    finally:
        server.send_signal(signal.SIGINT)
        server.wait(timeout=10)
    return look.returncode == 0


def test_namespaces_isolate_unless_static_peers_are_set(processes, two_hosts):
    assert not _look(processes, two_hosts, peers=False, seconds=8.0), \
        'A discovered a node in B without ROS_STATIC_PEERS: the namespaces do not isolate'
    assert _look(processes, two_hosts, peers=True, seconds=30.0), \
        'A did not discover a node in B through ROS_STATIC_PEERS'


def test_a_swarm_split_over_two_hosts_forms_the_shape(processes, two_hosts, ros_isolation,
                                                      tmp_path):
    pair = two_hosts
    common = [str(LAUNCH), '--agents', str(AGENTS), '--beacons', '3', '--method', 'bubble',
              '--shape', str(SHAPE), '--half-size', '15', '--seed', '0', '--composed',
              '--domain', str(ros_isolation)]
    b_log = tmp_path / 'b.out'
    with open(b_log, 'w', encoding='utf-8') as stream:
        host_b = processes.start(pair.command('b', [
            sys.executable, *common, '--local-agents', f'{SPLIT}-{AGENTS - 1}',
            '--agents-only', '--out', str(tmp_path / 'b')]),
            env=_env(pair, 'b'), stdout=stream, stderr=subprocess.STDOUT)
    host_a = processes.start(pair.command('a', [
        sys.executable, *common, '--local-agents', f'0-{SPLIT - 1}', '--duration', '400',
        '--out', str(tmp_path / 'a')]),
        env=_env(pair, 'a'), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    output, _ = host_a.communicate(timeout=500)
    assert host_a.returncode == 0, output[-3000:]
    assert host_b.poll() is None, b_log.read_text()[-3000:]
    rx, tx = pair.link_bytes('a')
    host_b.send_signal(signal.SIGINT)
    try:
        code = host_b.wait(timeout=30)
    except subprocess.TimeoutExpired:
        pytest.fail('host B did not stop within 30 s of SIGINT: '
                    + b_log.read_text()[-3000:])
    assert code == 0, b_log.read_text()[-3000:]

    m = json.loads((tmp_path / 'a' / 'metrics.json').read_text())['trials'][0]
    summary = (f'{m["outcome"]}, settling {m.get("settling_time")} s, '
               f'wall {m["wall_seconds"]:.0f} s, veth bytes A<-B {rx} A->B {tx}')
    print(summary)
    assert m['outcome'] == 'settled', m
    assert m['fraction_inside'] == 1.0, summary
    assert m['duplicate_goal_claims_final'] == 0
    assert m['assignment_agreement'] >= 0.95, summary
    # ground truth is read by the monitor and the bag recorder, never by an agent
    assert m['truth_subscribers'] == ['/recorder', '/swarm_monitor'], m['truth_subscribers']
    # Crossed: A's monitor heard B's agents, and B's robots (which the sim in A moves only
    # on B's force commands) started outside the shape, so they were driven into it.
    assert m['agents_heard'] == list(range(AGENTS)), m['agents_heard']
    robots = yaml.safe_load((tmp_path / 'b' / 'fleet.yaml').read_text())['robots']
    assert robots == yaml.safe_load((tmp_path / 'a' / 'fleet.yaml').read_text())['robots']
    assert all(max(abs(r['x']), abs(r['y'])) > 4.0 for r in robots if r['id'] >= SPLIT)
    # Through the network, not a shortcut (shared memory is shared between namespaces):
    # half a megabyte each way at least. Measured since the composed agents batch their
    # inputs and commands (one SensorBatch and one ForceBatch per step): 0.9-1.5 MB each
    # way for a run settled near 50 s (before batching, several megabytes).
    assert min(rx, tx) > 500_000, summary
