"""Hardware in the loop without hardware (thesis ch. 5, Figs. 5.13-5.14): five emulated
robots of Table 5.1 form the square through agent processes, bridge_node, XBee frames
on a pty and the firmware twins. Asserts eq. 5.4 settling inside the shape, every robot
at its goal, and a total displacement bounded by the geometry: at least the optimal
assignment's straight-line distance to the goals (less the parking radius per robot)
and at most 1.5 times it plus one avoidance detour per robot."""

from __future__ import annotations

import json
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
HIL = ROOT / 'scripts' / 'hil_demo.py'
HOLD_RADIUS = 0.02          # config/hw_agent.yaml: robots park this close to the goal

pytestmark = [pytest.mark.e2e, pytest.mark.slow]


def test_five_emulated_robots_form_the_square_through_the_bridge(processes, tmp_path,
                                                                 ros_isolation):
    proc = processes.python(str(HIL), '--shape', 'hw_square', '--duration', '100',
                            '--settle-hold', '2', '--no-plot', '--domain',
                            str(ros_isolation), '--out', str(tmp_path),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    output, _ = proc.communicate(timeout=240)
    assert proc.returncode == 0, output[-3000:]
    m = json.loads((tmp_path / 'hil.json').read_text())['results'][0]
    assert m['outcome'] == 'arrived', m
    assert m['settling_time'] is not None and m['all_inside']
    assert m['arrival_time'] is not None and m['final_arrival_error'] <= m['arrival_tolerance']
    assert max(m['final_goal_error']) < HOLD_RADIUS + 0.02, m['final_goal_error']
    bound = m['displacement_lower_bound']
    assert bound - 5 * HOLD_RADIUS <= m['total_displacement'] <= 1.5 * bound + 5 * 0.1, m
    # every robot took part: the bridge drove each one (none left at its start)
    assert min(m['per_robot_displacement']) > 0.2


if __name__ == '__main__':
    sys.exit(pytest.main([__file__, '-v']))
