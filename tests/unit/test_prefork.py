"""swarm_agent.prefork: children forked from a server that imported their module once
behave like exec'd processes (argv, environment, session, log, exit code)."""

from __future__ import annotations

import os
import pathlib
import signal
import subprocess

import pytest

from swarm_agent.prefork import ForkServer

DATA = pathlib.Path(__file__).resolve().parents[1] / 'data'


@pytest.fixture
def server(monkeypatch):
    monkeypatch.syspath_prepend(str(DATA))   # the fork server imports the target from here
    return ForkServer(['prefork_target'])


def test_a_forked_child_runs_main_with_its_argv_env_and_log(server, tmp_path):
    log = tmp_path / 'child.log'
    child = server.start('child', 'prefork_target', ['--ros-args', '-p', 'x:=1'], str(log),
                         {'PREFORK_PROBE': 'yes', 'PATH': '/usr/bin'}, str(tmp_path))
    assert child.wait(timeout=30) == 0 and child.poll() == 0 and child.returncode == 0
    text = log.read_text()
    assert "argv=['--ros-args', '-p', 'x:=1'] env=yes own_session=True" in text
    assert f'cwd={tmp_path}' in text and 'to stderr' in text


def test_exit_codes_timeouts_and_signals_look_like_popen(server, tmp_path):
    child = server.start('failing', 'prefork_target', ['--fail'], str(tmp_path / 'f.log'),
                         {}, str(tmp_path))
    assert child.wait(timeout=30) == 3
    sleeper = server.start('sleeper', 'prefork_target', ['--sleep'],
                           str(tmp_path / 's.log'), {}, str(tmp_path))
    with pytest.raises(subprocess.TimeoutExpired):
        sleeper.wait(timeout=0.5)
    assert sleeper.poll() is None
    os.killpg(sleeper.pid, signal.SIGKILL)     # its own process group, as the launcher's
    assert sleeper.wait(timeout=30) == -signal.SIGKILL


def test_die_with_a_process_already_gone_dies_at_once():
    """A child told to die with a launcher that has already exited must not live on
    (a fork request queued when the launcher was SIGKILLed)."""
    gone = subprocess.Popen(['true'])
    gone.wait()
    pid = os.fork()
    if pid == 0:                       # the child: die_with must kill it right here
        try:
            from swarm_agent.prefork import die_with
            die_with(gone.pid)
        finally:
            os._exit(0)
    _, status = os.waitpid(pid, 0)
    assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL


def test_a_child_whose_parent_died_before_it_set_its_death_signal_dies_at_once():
    """The launcher's children set their death signal after the fork; one forked just
    before the launcher was SIGKILLed does so after the launcher is gone, when the
    signal can never come. ``die_with_parent`` told the pid it was forked from kills
    such a child at once (here: a child told a parent it does not have, as a reparented
    child finds), and lets a child of that parent run."""
    import functools
    import sys

    from swarm_agent.prefork import die_with_parent
    run = [sys.executable, '-c', 'print("ran")']
    orphan = subprocess.run(run, capture_output=True, text=True, timeout=30,
                            preexec_fn=functools.partial(die_with_parent, 1))
    assert orphan.returncode == -signal.SIGKILL and orphan.stdout == ''
    child = subprocess.run(run, capture_output=True, text=True, timeout=30,
                           preexec_fn=functools.partial(die_with_parent, os.getpid()))
    assert child.returncode == 0 and child.stdout == 'ran\n'
