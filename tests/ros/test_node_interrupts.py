"""Every node's main (swarm_common.ros_support.run_node) stops quietly on Ctrl-C: also
on a second one while it cleans up (``ros2 launch`` forwards its own SIGINT after the
terminal's) and on one while the node is still starting."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import pytest

NODE = textwrap.dedent("""
    import os, signal, sys, time
    from rclpy.node import Node
    from swarm_common.ros_support import run_node

    def interrupt():
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.5)                      # the signal lands in here

    def make():
        if sys.argv[1] == 'start':
            interrupt()                      # Ctrl-C while the node starts
        node = Node('interrupted')
        node.create_timer(0.05, lambda: os.kill(os.getpid(), signal.SIGINT))
        return node

    def stop(node):
        interrupt()                          # a second Ctrl-C while it cleans up
        print('cleaned up', flush=True)

    run_node(make, 'interrupted', stop=stop)
""")


def _run(when: str, sigint) -> subprocess.CompletedProcess:
    """Run the node with SIGINT as its parent leaves it: the default, or ignored (a job
    started in the background of a non-interactive shell, e.g. under nohup)."""
    return subprocess.run([sys.executable, '-c', NODE, when], capture_output=True,
                          text=True, timeout=60, env=dict(os.environ),
                          preexec_fn=lambda: signal.signal(signal.SIGINT, sigint))


INHERITED = pytest.mark.parametrize('sigint', [signal.SIG_DFL, signal.SIG_IGN],
                                    ids=['sigint_default', 'sigint_ignored'])


@INHERITED
def test_a_second_interrupt_during_clean_up_is_ignored(sigint):
    result = _run('spin', sigint)
    assert result.returncode == 0, result.stderr
    assert 'cleaned up' in result.stdout
    assert 'Traceback' not in result.stderr, result.stderr


@INHERITED
def test_an_interrupt_while_the_node_starts_ends_it_quietly(sigint):
    result = _run('start', sigint)
    assert result.returncode == 0, result.stderr
    assert 'Traceback' not in result.stderr, result.stderr
    assert 'cleaned up' not in result.stdout


RACED = textwrap.dedent("""
    import rclpy
    from swarm_common.ros_support import run_node

    def racing_try_shutdown(context=None):
        rclpy.shutdown()     # rclpy's SIGINT thread shuts the context down first...
        rclpy.shutdown()     # ...then try_shutdown's own call: already shut down

    rclpy.try_shutdown = racing_try_shutdown

    def make():
        raise KeyboardInterrupt

    run_node(make, 'raced')
""")


def test_an_interrupt_racing_rclpys_own_shutdown_ends_quietly():
    """rclpy's SIGINT handler shuts the context down from a thread of its own; when it
    does so between try_shutdown's check and its call, rcl reports the context already
    shut down (RCLError). Seen once in CI; forced here."""
    result = subprocess.run([sys.executable, '-c', RACED], capture_output=True, text=True,
                            timeout=60, env=dict(os.environ))
    assert result.returncode == 0, result.stderr
    assert 'Traceback' not in result.stderr, result.stderr
