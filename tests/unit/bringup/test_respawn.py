"""Respawn (issue 24, restarts): the plan marks the agents and the mission node for
restart, never the simulator; launch_ros gets respawn, its delay and a bound; the
launcher restarts such a process when it exits on its own, as often as the bound
allows, one line each, and then reports the crash."""

from __future__ import annotations

import os
import sys
import time

import pytest

from swarm_bringup import launcher
from swarm_bringup.launch_plan import (
    node_kwargs,
    NodeSpec,
    RESPAWN_DELAY_S,
    RESPAWN_RETRIES,
    swarm_plan,
    SwarmRun,
)
from swarm_bringup.launcher import Children
from swarm_common.fleet import RobotSpec

FLEET = [RobotSpec(0, 1, True, -3.0, 4.0), RobotSpec(1, 1, False, 2.5, -1.0)]
COUNTS = {1: 2}


@pytest.mark.parametrize('composed', [False, True])
def test_agents_and_mission_respawn_the_world_does_not(composed):
    run = SwarmRun(fleet_file='/tmp/f.yaml', shape='circle_314', composed=composed,
                   bag='/tmp/run.mcap')
    respawned = {spec.process for spec in swarm_plan(run, FLEET, COUNTS) if spec.respawn}
    agents = {'agents'} if composed else {'agent_0', 'agent_1'}
    assert respawned == {'mission', 'mission_radio', *agents}   # not 'sim', 'recorder'


def test_launch_ros_gets_respawn_with_delay_and_bound():
    plan = swarm_plan(SwarmRun(fleet_file='/f.yaml', shape='circle_314'), FLEET, COUNTS)
    by_process = {spec.process: node_kwargs(spec) for spec in plan}
    assert by_process['agent_1']['respawn'] is True
    assert by_process['agent_1']['respawn_delay'] == RESPAWN_DELAY_S > 0.0
    assert by_process['agent_1']['respawn_max_retries'] == RESPAWN_RETRIES > 0
    assert 'respawn' not in by_process['sim']


def _children(tmp_path, monkeypatch) -> Children:
    (tmp_path / 'src' / 'fakepkg').mkdir(parents=True)
    (tmp_path / 'src' / 'fakepkg' / '__init__.py').write_text('')
    # Exits at once with code 3 (a crash on every start), 2 (refused its parameters)
    # when asked to, or sleeps when asked to.
    (tmp_path / 'src' / 'fakepkg' / 'target.py').write_text(
        'import sys, time\n'
        "if 'sleep:=true' in sys.argv:\n"
        '    time.sleep(60.0)\n'
        "raise SystemExit(2 if 'refuse:=true' in sys.argv else 3)\n")
    (tmp_path / 'logs').mkdir()
    monkeypatch.setattr(launcher, 'RESPAWN_DELAY_S', 0.0)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path / 'src'), *sys.path]))
    return Children(tmp_path / 'logs', env, cwd=str(tmp_path))


def _wait_crash(children: Children, timeout: float = 60.0) -> str | None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        crashed = children.crashed()
        if crashed is not None:
            return crashed
        time.sleep(0.02)
    return None


def test_a_crashing_process_is_restarted_up_to_the_bound(tmp_path, monkeypatch, capsys):
    children = _children(tmp_path, monkeypatch)
    children.run(NodeSpec('fakepkg', 'target', 'agent_4', respawn=True))
    assert _wait_crash(children) == 'agent_4'
    assert children.respawns['agent_4'] == RESPAWN_RETRIES
    lines = capsys.readouterr().err.splitlines()
    assert lines == [f'launch_swarm: agent_4 exited with code 3; started again '
                     f'({k}/{RESPAWN_RETRIES})' for k in range(1, RESPAWN_RETRIES + 1)]
    logs = sorted(p.name for p in (tmp_path / 'logs').iterdir())
    assert logs == ['agent_4.log', *(f'agent_4.run{k}.log'
                                     for k in range(1, RESPAWN_RETRIES + 1))]


def test_no_restart_without_respawn_or_after_a_kill(tmp_path, monkeypatch, capsys):
    children = _children(tmp_path, monkeypatch)
    children.run(NodeSpec('fakepkg', 'target', 'sim'))
    assert _wait_crash(children) == 'sim' and 'sim' not in children.respawns
    children.procs.pop('sim')
    children.run(NodeSpec('fakepkg', 'target', 'agent_2', respawn=True,
                          parameters={'sleep': True}))
    children.kill('agent_2')   # a removed robot: it stays down
    assert children.procs['agent_2'].wait(timeout=30) < 0
    assert children.crashed() is None and 'agent_2' not in children.respawns
    assert capsys.readouterr().err == ''


def test_a_node_that_refused_its_configuration_is_not_restarted(tmp_path, monkeypatch,
                                                                 capsys):
    """Status 2 is run_node's one-line refusal of bad parameters: it would refuse again."""
    children = _children(tmp_path, monkeypatch)
    children.run(NodeSpec('fakepkg', 'target', 'agent_5', respawn=True,
                          parameters={'refuse': True}))
    assert _wait_crash(children) == 'agent_5'
    assert 'agent_5' not in children.respawns and capsys.readouterr().err == ''



def test_the_new_log_exists_when_the_restart_is_announced(tmp_path, monkeypatch):
    """Whoever reads the process's log on the 'started again' line finds the new run's
    file (a restart test read it between the old log's rename and the new one's open)."""
    children = _children(tmp_path, monkeypatch)
    log = tmp_path / 'logs' / 'agent_5.log'
    seen: list[bool] = []

    def announce(*args, **kwargs) -> None:
        seen.append(log.is_file())
    monkeypatch.setattr(launcher, 'print', announce, raising=False)
    children.run(NodeSpec('fakepkg', 'target', 'agent_5', respawn=True))
    assert _wait_crash(children) == 'agent_5'
    assert seen == [True] * RESPAWN_RETRIES
