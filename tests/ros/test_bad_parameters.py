"""Every node refuses bad parameters in one line (swarm_bringup.bad_parameters): each case
of ``CASES`` is started as its own process, must exit non-zero with exactly one line that
names the node and no traceback, and docs/parameters.md's table must be what they print
(regenerate it with ``python -m swarm_bringup.bad_parameters --write docs/parameters.md``).
"""

from __future__ import annotations

import pathlib

import pytest

pytest.importorskip('rclpy')

from swarm_bringup.bad_parameters import BEGIN, CASES, END, run_cases, table  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]
DOC = ROOT / 'docs' / 'parameters.md'


def test_every_node_refuses_a_bad_parameter_in_one_line():
    outcomes = run_cases(CASES, workers=2, cwd=str(ROOT))
    problems = [f'{o.executable} {o.given}: {o.problem()}\n{o.output}' for o in outcomes
                if o.problem()]
    assert problems == []
    assert {o.returncode for o in outcomes} == {2}
    # Every node of the project is in the table.
    assert {o.executable for o in outcomes} >= {
        'agent_node', 'composed_node', 'mission_node', 'mission_radio_node', 'sim_node',
        'monitor_node',
        'live_view_node', 'recorder_node', 'bridge_node', 'camera_tracker_node',
        'hil_world_node', 'launch_swarm.py'}
    text = DOC.read_text(encoding='utf-8')
    documented = text.split(BEGIN, 1)[1].split(END, 1)[0].strip()
    assert documented == table(outcomes), ('docs/parameters.md is not what the nodes print; '
                                           'regenerate it (module docstring)')
