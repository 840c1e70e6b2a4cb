"""swarm_bringup.launcher.Children starts the processes of a launch plan (exec'd or
forked), with their ROS arguments, logs and working folder, tells which one crashed and
stops them all."""

from __future__ import annotations

import os
import sys

import pytest

from swarm_bringup.launch_plan import NodeSpec
from swarm_bringup.launcher import Children

TARGET = """
import os, sys, time

def main(argv=None):
    argv = sys.argv if argv is None else argv
    print(f'argv={argv[1:]} cwd={os.getcwd()}', flush=True)
    if '-p' in argv and argv[argv.index('-p') + 1] == 'sleep:=true':
        time.sleep(60.0)

if __name__ == '__main__':
    main()
"""


@pytest.fixture
def package(tmp_path, monkeypatch):
    """A stand-in node package ``fakepkg`` with one executable ``target``."""
    pkg = tmp_path / 'src' / 'fakepkg'
    pkg.mkdir(parents=True)
    (pkg / '__init__.py').write_text('')
    (pkg / 'target.py').write_text(TARGET)
    monkeypatch.syspath_prepend(str(tmp_path / 'src'))   # the fork server imports it
    return tmp_path / 'src'


def _children(tmp_path, package) -> Children:
    (tmp_path / 'logs').mkdir()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(package), *sys.path]))
    return Children(tmp_path / 'logs', env, cwd=str(tmp_path))


@pytest.mark.parametrize('fork', [False, True])
def test_a_plan_entry_runs_with_its_ros_arguments_log_and_folder(tmp_path, package, fork):
    children = _children(tmp_path, package)
    children.run(NodeSpec('fakepkg', 'target', 'agent_3', name='agent', namespace='/agent_3',
                          parameters={'agent_id': 3, 'is_beacon': True}, fork=fork))
    assert children.procs['agent_3'].wait(timeout=60) == 0
    log = (tmp_path / 'logs' / 'agent_3.log').read_text()
    assert ("argv=['--ros-args', '-r', '__ns:=/agent_3', '-r', '__node:=agent', '-p', "
            "'agent_id:=3', '-p', 'is_beacon:=true']") in log
    assert f'cwd={tmp_path}' in log
    # It ended on its own: a crash of the run.
    assert children.crashed() == 'agent_3'


def test_killed_and_stopped_children_are_no_crash(tmp_path, package):
    children = _children(tmp_path, package)
    for name in ('a', 'b'):
        children.run(NodeSpec('fakepkg', 'target', name, parameters={'sleep': True}))
    children.kill('a')
    assert children.procs['a'].wait(timeout=30) < 0
    assert children.crashed() is None and children.procs['b'].poll() is None
    children.stop_all(grace=5.0)
    assert children.procs['b'].poll() is not None and children.crashed() is None
