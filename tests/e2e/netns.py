"""Two Linux network namespaces joined by a veth pair: two "hosts" on one machine.

``NetnsPair`` creates namespaces ``<prefix>a`` (10.77.0.1/24) and ``<prefix>b``
(10.77.0.2/24), each with its loopback up, joined by one veth link; ``command``
prefixes an argv with ``ip netns exec`` so a process runs on one side. ``destroy``
kills every process still inside either namespace and deletes both (the veth goes
with them), so a failed test leaves nothing behind; ``reap_stale`` removes pairs whose
test process was killed before it could do that.

``unavailable_reason()`` says in one line why this machine cannot do that (not Linux,
not root, no ``ip``, namespace creation refused, e.g. in an unprivileged container),
or returns None. It creates and deletes a probe namespace to find out.
"""

from __future__ import annotations

import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

SUBNET_PREFIX = '10.77.0'
STALE_PREFIX = 'swarmtest'


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    """Run ``ip ARGS``; raise RuntimeError naming the command and its stderr."""
    proc = subprocess.run(['ip', *args], capture_output=True, text=True, timeout=30)
    if check and proc.returncode != 0:
        raise RuntimeError(f'ip {" ".join(args)}: {proc.stderr.strip() or proc.returncode}')
    return proc


def _first_line(text: str) -> str:
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[0] if lines else 'no message'


def unavailable_reason() -> str | None:
    """One line saying why namespaces cannot be used here, or None when they can."""
    if not sys.platform.startswith('linux'):
        return f'network namespaces need Linux (this is {sys.platform})'
    if os.geteuid() != 0:
        return 'network namespaces need root (ip netns add); run the tests as root'
    if shutil.which('ip') is None:
        return 'no `ip` command (iproute2); install it: apt-get install iproute2'
    probe = f'swprobe{os.getpid()}'
    try:
        made = _ip('netns', 'add', probe, check=False)
        if made.returncode != 0:
            return f'cannot create a network namespace: {_first_line(made.stderr)}'
        veth = _ip('-n', probe, 'link', 'add', 'swp0', 'type', 'veth', 'peer', 'name',
                   'swp1', check=False)
        if veth.returncode != 0:
            return f'cannot create a veth pair: {_first_line(veth.stderr)}'
        run = subprocess.run(['ip', 'netns', 'exec', probe, 'true'], capture_output=True,
                             text=True, timeout=30)
        if run.returncode != 0:
            return f'cannot run a process in a network namespace: {_first_line(run.stderr)}'
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f'cannot run ip netns: {exc}'
    finally:
        try:
            _ip('netns', 'del', probe, check=False)
        except (OSError, subprocess.TimeoutExpired):
            pass
    return None


class NetnsPair:
    """Namespaces A (10.77.0.1) and B (10.77.0.2) on one veth link; see the module doc."""

    def __init__(self, prefix: str | None = None) -> None:
        prefix = prefix or f'{STALE_PREFIX}{os.getpid()}'
        self.names = {'a': f'{prefix}a', 'b': f'{prefix}b'}
        self.addresses = {'a': f'{SUBNET_PREFIX}.1', 'b': f'{SUBNET_PREFIX}.2'}
        # Interface names are at most 15 characters; they only live inside the namespaces.
        self.links = {'a': 'veth_swa', 'b': 'veth_swb'}

    def peer_of(self, side: str) -> str:
        """The other side's address (its ROS_STATIC_PEERS entry)."""
        return self.addresses['b' if side == 'a' else 'a']

    def create(self) -> NetnsPair:
        """Create both namespaces and the link; on any failure undo it and raise."""
        try:
            for name in self.names.values():
                if name in self.list():
                    self.destroy_one(name)
                _ip('netns', 'add', name)
                _ip('-n', name, 'link', 'set', 'lo', 'up')
            a, b = self.names['a'], self.names['b']
            _ip('-n', a, 'link', 'add', self.links['a'], 'type', 'veth',
                'peer', 'name', self.links['b'], 'netns', b)
            for side, name in self.names.items():
                link = self.links[side]
                _ip('-n', name, 'addr', 'add', f'{self.addresses[side]}/24', 'dev', link)
                _ip('-n', name, 'link', 'set', link, 'up')
        except Exception:
            self.destroy()
            raise
        return self

    @staticmethod
    def list() -> list[str]:
        """Names of the namespaces that exist now."""
        out = _ip('netns', 'list', check=False).stdout
        return [line.split()[0] for line in out.splitlines() if line.strip()]

    def command(self, side: str, argv: list[str]) -> list[str]:
        """``argv`` run inside namespace ``side`` ('a' or 'b')."""
        return ['ip', 'netns', 'exec', self.names[side], *argv]

    def link_bytes(self, side: str) -> tuple[int, int]:
        """(received, sent) bytes so far on side ``side``'s end of the veth link."""
        out = _ip('-n', self.names[side], '-s', '-j', 'link', 'show', 'dev',
                  self.links[side]).stdout
        stats = json.loads(out)[0]['stats64']
        return int(stats['rx']['bytes']), int(stats['tx']['bytes'])

    def pids(self, side: str) -> list[int]:
        """Processes running inside namespace ``side``."""
        out = _ip('netns', 'pids', self.names[side], check=False).stdout
        return [int(p) for p in out.split() if p.isdigit()]

    @staticmethod
    def destroy_one(name: str, grace: float = 5.0) -> None:
        """SIGINT, then SIGKILL, every process inside ``name``; delete the namespace."""
        def alive() -> list[int]:
            out = _ip('netns', 'pids', name, check=False).stdout
            return [int(p) for p in out.split() if p.isdigit()]

        for sig, wait in ((signal.SIGINT, grace), (signal.SIGKILL, 5.0)):
            pids = alive()
            for pid in pids:
                try:
                    os.kill(pid, sig)
                except ProcessLookupError:
                    pass
            deadline = time.monotonic() + wait
            while pids and time.monotonic() < deadline:
                time.sleep(0.1)
                pids = alive()
            if not pids:
                break
        _ip('netns', 'del', name, check=False)

    @classmethod
    def reap_stale(cls) -> list[str]:
        """Destroy pairs left by a test process that no longer exists (e.g. SIGKILLed)."""
        reaped = []
        for name in cls.list():
            pid = name[len(STALE_PREFIX):-1]
            if name.startswith(STALE_PREFIX) and pid.isdigit() and \
                    not pathlib.Path('/proc', pid).exists():
                cls.destroy_one(name)
                reaped.append(name)
        return reaped

    def destroy(self) -> None:
        """Kill everything inside both namespaces and delete them (idempotent)."""
        existing = set(self.list())
        for name in self.names.values():
            if name in existing or pathlib.Path('/run/netns', name).exists():
                self.destroy_one(name)
