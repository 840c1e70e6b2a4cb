"""Shared pytest fixtures: ROS isolation and child-process hygiene.

Every test runs in its own ROS domain (ROS_DOMAIN_ID unique to the test, discovery
limited to localhost, and reserved host-wide by a lock file while the test runs), so
tests never hear each other or a test of another session on the machine.
Child processes started through the ``processes`` fixture are killed, with their whole
process group, when the test ends.
"""

from __future__ import annotations

import itertools
import os
import pathlib
import subprocess
import sys

from hypothesis import settings
import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent

# Pure modules import straight from the source tree, so a module added since the last
# colcon build is found; the built workspace (scripts/env.sh) adds messages and nodes.
for _pkg in sorted((ROOT / 'ros2_ws' / 'src').glob('swarm_*')):
    if (_pkg / 'setup.py').exists() and str(_pkg) not in sys.path:
        sys.path.insert(0, str(_pkg))
sys.path.insert(0, str(ROOT / 'scripts'))
_domain_counter = itertools.count()

# Property tests assert behaviour, not speed: no per-example deadline (a loaded CI
# machine made the 200 ms default flaky). Speed is measured by benchmarks/.
settings.register_profile('swarm', deadline=None)
settings.load_profile('swarm')


def pytest_sessionstart(session) -> None:
    """Clear Fast DDS shared memory left by killed processes (swarm_common.shm): a stale
    segment hangs every later participant of its domain in rcl_node_init."""
    try:
        from swarm_common.shm import clean_stale_segments
    except ImportError:
        return  # the workspace is not built: the ROS tests are skipped anyway
    clean_stale_segments()


TEST_DOMAINS = (1, 100)   # swarm_common.domains.RUN_DOMAINS are the runs' own


def _reserve_domain_id():
    """Reserve a free domain id in 1..100 for one test: (id, the open lock file).

    Ids differ between tests of this session (a start from an offset of the pid and a
    counter); ``swarm_common.domains.claim_domain`` skips ids another session holds (its
    lock file: two CI runs at once) or some other participant uses (its UDP ports).
    """
    from swarm_common.domains import claim_domain  # a pure module: no build needed

    low, high = TEST_DOMAINS
    start = low + (os.getpid() * 7 + next(_domain_counter)) % (high - low + 1)
    return claim_domain(start, low=low, high=high)


@pytest.fixture(autouse=True)
def ros_isolation(monkeypatch: pytest.MonkeyPatch):
    """Give the test its own ROS domain on localhost; yield the domain id."""
    domain, lock = _reserve_domain_id()
    monkeypatch.setenv('ROS_DOMAIN_ID', str(domain))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    monkeypatch.delenv('ROS_STATIC_PEERS', raising=False)
    try:
        yield domain
    finally:
        lock.close()                     # releases the reservation


class ProcessGroup:
    """Start child processes in their own process groups and reap them all at the end."""

    def __init__(self) -> None:
        self.procs: list[subprocess.Popen] = []

    def start(self, args: list[str], **kwargs) -> subprocess.Popen:
        """Start ``args`` with the test's environment in a new session."""
        kwargs.setdefault('env', os.environ.copy())
        kwargs.setdefault('cwd', str(ROOT))
        proc = subprocess.Popen(args, start_new_session=True, **kwargs)
        self.procs.append(proc)
        return proc

    def python(self, *args: str, **kwargs) -> subprocess.Popen:
        """Start the current interpreter with ``args``."""
        return self.start([sys.executable, *args], **kwargs)

    def cleanup(self) -> None:
        """SIGINT, then SIGKILL after a grace period longer than a launcher's own grace
        for its children (5 s), every group still alive."""
        from swarm_bringup.launcher import stop_groups
        stop_groups(self.procs, grace=12.0)


@pytest.fixture(params=['compiled', 'python'])
def kernels(request):
    """The test runs twice: with every kernel compiled, then as its Python source
    (swarm_common.jit). The source is the reference; the compiled code must pass the same
    assertions."""
    from swarm_common import jit
    jit.use_python(request.param == 'python')
    assert jit.compiled() == (request.param == 'compiled'), 'numba is a requirement'
    yield request.param
    jit.use_python(False)


@pytest.fixture
def processes():
    """A ProcessGroup whose processes are killed when the test ends."""
    group = ProcessGroup()
    try:
        yield group
    finally:
        group.cleanup()


def pytest_collection_modifyitems(config, items):
    """Mark tests by layer from their folder, so ``-m unit`` selects the pure layer."""
    for item in items:
        path = pathlib.Path(str(item.fspath))
        for layer in ('unit', 'ros', 'e2e'):
            if layer in path.parts:
                item.add_marker(getattr(pytest.mark, layer))
