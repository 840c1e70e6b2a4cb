"""A ROS domain no other run on this machine uses.

Runs on one machine with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` discover each other
when they share a ``ROS_DOMAIN_ID``: a hardware-in-the-loop demo beside a soak run in
the same domain took the other swarm's goals and drove its robots off the arena. A
domain is free when

- no process of this project holds its lock file (``LOCK_DIR``, shared with the test
  suite's per-test domains), and
- no socket of this network namespace is bound in the domain's UDP port block: DDS
  (RTPS 2.x port mapping, the default of Fast DDS and Cyclone DDS) puts every
  participant of domain d on ports 7400 + 250 d + (0..249), so a run this project did
  not start (a user's ``ros2`` command, another ROS application) shows there.

``claim_domain`` takes the first free domain from a start and holds its lock until the
returned handle is closed (or the process exits).
"""

from __future__ import annotations

import fcntl
import pathlib
import tempfile
from typing import IO

LOCK_DIR = pathlib.Path(tempfile.gettempdir()) / 'swarm-formation-ros-domains'
PORT_BASE = 7400          # RTPS port mapping: PB
DOMAIN_GAIN = 250         # DG: ports per domain
MAX_DOMAIN = 232          # the last domain whose ports stay below 65536
RUN_DOMAINS = (101, MAX_DOMAIN)   # runs; the test suite uses 1..100


class DomainError(RuntimeError):
    """No free domain in the range asked for."""


def bound_udp_ports() -> set[int]:
    """Local ports of the UDP sockets of this network namespace (/proc/net/udp, udp6)."""
    ports: set[int] = set()
    for name in ('udp', 'udp6'):
        try:
            lines = pathlib.Path('/proc/net', name).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if len(fields) > 1 and ':' in fields[1]:
                ports.add(int(fields[1].rsplit(':', 1)[1], 16))
    return ports


def domain_ports(domain: int) -> range:
    """The UDP port block of ``domain`` (RTPS port mapping)."""
    start = PORT_BASE + DOMAIN_GAIN * domain
    return range(start, start + DOMAIN_GAIN)


def domain_in_use(domain: int, ports: set[int] | None = None) -> bool:
    """A socket is bound in the domain's port block (some participant is in it)."""
    ports = bound_udp_ports() if ports is None else ports
    block = domain_ports(domain)
    return any(p in block for p in ports)


def claim_domain(start: int | None = None, low: int = RUN_DOMAINS[0],
                 high: int = RUN_DOMAINS[1]) -> tuple[int, IO[str]]:
    """The first free domain in ``low..high`` from ``start`` (wrapping), and its lock
    file, held open: close it when the run ends. DomainError when none is free."""
    if not 0 <= low <= high <= MAX_DOMAIN:
        raise DomainError(f'domain range {low}..{high} is not within 0..{MAX_DOMAIN}')
    LOCK_DIR.mkdir(exist_ok=True)
    count = high - low + 1
    first = low if start is None else low + (start - low) % count
    ports = bound_udp_ports()
    for k in range(count):
        domain = low + (first - low + k) % count
        lock = open(LOCK_DIR / f'{domain}.lock', 'w')  # noqa: SIM115 - held by the caller
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            continue
        if domain_in_use(domain, ports):
            lock.close()
            continue
        return domain, lock
    raise DomainError(f'every ROS domain in {low}..{high} is in use on this machine; '
                      'pass --domain with a free one')
