"""Start many node processes without paying each one's imports: a fork server.

One process per agent is the faithful deployment (scripts/launch_swarm.py without
``--composed``), but a fresh Python process that imports rclpy, numpy, scipy and shapely
spends about 0.5 s of CPU before its node exists, and holds its own copy of every
module. Fifty agents started at once on two cores took 30 s to come up (42 s before the
world's clock moved) and 7.7 GB of resident memory.

So the launcher starts them from multiprocessing's fork server, which imports the node
module once; each agent is a fork of it. Each is still its own process with its own
rclpy context and DDS participant, its own session (a Ctrl-C reaches it once, from the
launcher), log file and exit code; it dies with the launcher however the launcher dies
(``die_with``), and the fork server ends once the launcher and its last child have.
Forking is safe here because the server only imports: rclpy starts no thread and opens
no DDS participant before ``rclpy.init``, which each child calls itself.

``ForkedProcess`` gives the launcher the ``subprocess.Popen`` calls it makes (``pid``,
``poll``, ``returncode``, ``wait``), so forked and exec'd children are handled alike.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import ctypes
import importlib
import multiprocessing
import os
import select
import signal
import subprocess
import sys
import threading

PR_SET_PDEATHSIG = 1   # linux/prctl.h
LAUNCHER_ENV = 'SWARM_PREFORK_LAUNCHER'   # pid of the process that owns the fork server


def die_with_parent(parent: int | None = None) -> None:
    """SIGKILL this process when its parent dies, however it dies (Linux; elsewhere a
    no-op). ``parent``: the pid of the process that forked this one; if it has died
    already (this process was reparented before the death signal was set), this process
    dies at once: a child forked just before its launcher is SIGKILLed runs this after
    the launcher is gone, and the death signal of a dead parent never comes, so it
    would otherwise run orphaned for the whole of the run.

    The launcher's children run in their own sessions (so that Ctrl-C reaches each node
    once, from the launcher), which also keeps a SIGKILL of the launcher from reaching
    them: a benchmark that killed an overrunning launcher left 100 agent processes
    running. SIGKILL, not SIGTERM: a parent that dies without stopping its nodes is past
    a clean stop, and under load some starting rclpy nodes ignored SIGTERM for minutes
    (6 of 100).
    """
    if sys.platform.startswith('linux'):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    if parent is not None and os.getppid() != parent:
        os.kill(os.getpid(), signal.SIGKILL)


def die_with(pid: int) -> None:
    """SIGKILL this process when process ``pid`` exits, whoever its parent is (Linux
    pidfd: a daemon thread blocks on it; elsewhere a no-op). If ``pid`` is already gone
    this process dies at once: a fork request still queued at the fork server when the
    launcher was killed otherwise starts an agent that nothing ever stops."""
    try:
        fd = os.pidfd_open(pid)
    except ProcessLookupError:
        os.kill(os.getpid(), signal.SIGKILL)
        return
    except (AttributeError, OSError):
        return

    def watch() -> None:
        select.select([fd], [], [])
        os.kill(os.getpid(), signal.SIGKILL)

    threading.Thread(target=watch, name=f'die-with-{pid}', daemon=True).start()


def guard_fork_server() -> None:
    """In the fork server (imported first by its ``preload``): die with the launcher
    that started it. The server otherwise outlives a SIGKILLed launcher for as long as
    its slowest import, or forever if a child holds its liveness pipe."""
    if os.environ.get(LAUNCHER_ENV) == str(os.getppid()):
        die_with(os.getppid())


def run_node(module: str, argv: Sequence[str], log_path: str, env: Mapping[str, str],
             cwd: str, launcher_pid: int) -> None:
    """In the forked child: a session of its own, stdout and stderr to ``log_path``, the
    launcher's environment, then ``module.main(argv)``. It dies with its parent, the fork
    server, and with the launcher (``launcher_pid``): multiprocessing keeps the fork
    server alive as long as any of its children is, so dying with the parent alone would
    leave both running after a SIGKILL of the launcher."""
    parent = os.getppid()
    os.setsid()
    die_with_parent(parent)     # the fork server may have died since the line above
    die_with(launcher_pid)
    fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    os.environ.clear()
    os.environ.update(env)
    os.chdir(cwd)
    sys.argv = [module, *argv]
    importlib.import_module(module).main(sys.argv)


class ForkedProcess:
    """The ``subprocess.Popen`` calls the launcher makes, on a forked child."""

    def __init__(self, process: multiprocessing.process.BaseProcess) -> None:
        self._process = process

    @property
    def pid(self) -> int:
        return self._process.pid

    @property
    def returncode(self) -> int | None:
        return self._process.exitcode

    def poll(self) -> int | None:
        return self._process.exitcode

    def wait(self, timeout: float | None = None) -> int:
        self._process.join(timeout)
        if self._process.exitcode is None:
            raise subprocess.TimeoutExpired(self._process.name, timeout)
        return self._process.exitcode


class ForkServer:
    """multiprocessing's fork server with ``preload`` imported once; see the module
    docstring. The server process starts with the first ``start``."""

    def __init__(self, preload: Sequence[str]) -> None:
        self._context = multiprocessing.get_context('forkserver')
        os.environ[LAUNCHER_ENV] = str(os.getpid())
        self._context.set_forkserver_preload(['swarm_agent.prefork_guard', *preload,
                                              'swarm_agent.prefork_warm'])

    def start(self, name: str, module: str, argv: Sequence[str], log_path: str,
              env: Mapping[str, str], cwd: str) -> ForkedProcess:
        """Fork a child running ``module.main`` with ``argv``; see ``run_node``."""
        process = self._context.Process(target=run_node, name=name, daemon=False,
                                        args=(module, list(argv), log_path, dict(env), cwd,
                                              os.getpid()))
        process.start()
        return ForkedProcess(process)
