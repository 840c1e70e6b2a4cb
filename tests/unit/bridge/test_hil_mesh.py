"""The hardware-in-the-loop mesh carries the agents' frames through the simulator's radio
medium: loss, range, line of sight and airtime plus latency, configured by MediumConfig."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
from shapely.geometry import box
import yaml

from swarm_agent.packet import BROADCAST, Kind, Packet
from swarm_bridge.hil_mesh import HilMesh
from swarm_sim.medium import FRAME_OVERHEAD_BYTES, MediumConfig

CONFIG = (pathlib.Path(__file__).resolve().parents[3] / 'ros2_ws' / 'src' / 'swarm_bridge'
          / 'config' / 'hil.yaml')
# The five robots of Table 5.1 in the 2 x 2 m arena (config/hil.yaml's initial poses).
ARENA = {1: (-0.55, -0.55), 2: (0.55, -0.55), 3: (0.55, 0.55), 4: (-0.55, 0.55),
         5: (0.0, -0.62)}


def _frame(source: int, destination: int = BROADCAST, size: int = 40) -> Packet:
    return Packet(source, destination, Kind.DATA, 0, 1, bytes(size))


def _mesh(**config) -> HilMesh:
    mesh = HilMesh(ARENA, MediumConfig(**config), seed=3)
    mesh.move(ARENA)
    return mesh


def _heard(mesh: HilMesh, t: float) -> dict[int, int]:
    counts = {k: 0 for k in ARENA}
    for _, receivers in mesh.due(t):
        for k in receivers:
            counts[k] += 1
    return counts


def test_each_receiver_loses_its_share_of_the_frames():
    """2000 broadcasts at 30 % loss: every other robot hears 70 % of them, within 4
    binomial standard deviations (1 %); the sender never hears itself."""
    mesh = _mesh(loss=0.3)
    for k in range(2000):
        assert mesh.send(0.01 * k, _frame(1))
    heard = _heard(mesh, 100.0)
    assert heard[1] == 0
    sd = np.sqrt(0.3 * 0.7 / 2000)
    for k in (2, 3, 4, 5):
        assert abs(heard[k] / 2000 - 0.7) < 4 * sd, heard


def test_a_unicast_frame_reaches_its_destination_only():
    mesh = _mesh()
    mesh.send(0.0, _frame(2, destination=4))
    assert _heard(mesh, 1.0) == {1: 0, 2: 0, 3: 0, 4: 1, 5: 0}


def test_range_and_line_of_sight_cut_links():
    """1 m range: robot 1 reaches 2 and 4 (1.1 m) no more, only 5 (0.56 m); a wall
    between 1 and 5 cuts that link too."""
    mesh = _mesh(range_m=1.0)
    mesh.send(0.0, _frame(1))
    assert _heard(mesh, 1.0) == {1: 0, 2: 0, 3: 0, 4: 0, 5: 1}
    walled = HilMesh(ARENA, MediumConfig(range_m=1.0), seed=3,
                     obstacles=[box(-0.35, -0.9, -0.3, -0.3)])
    walled.move(ARENA)
    walled.send(0.0, _frame(1))
    assert sum(_heard(walled, 1.0).values()) == 0


def test_a_frame_arrives_after_its_airtime_and_the_latency():
    mesh = _mesh(latency_s=0.02)
    mesh.send(5.0, _frame(3, size=100))
    arrival = 5.0 + 8.0 * (100 + FRAME_OVERHEAD_BYTES) / MediumConfig().bandwidth_bps + 0.02
    assert mesh.due(arrival - 1e-6) == []
    assert sum(_heard(mesh, arrival).values()) == 4


def test_frames_of_a_robot_outside_the_fleet_are_not_carried():
    mesh = _mesh()
    assert not mesh.send(0.0, _frame(9))
    assert mesh.due(1.0) == []


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match='packet loss must be in'):
        HilMesh(ARENA, MediumConfig(loss=1.5), seed=0)
    with pytest.raises(ValueError, match='radio latency must be'):
        HilMesh(ARENA, MediumConfig(latency_s=-1.0), seed=0)


def test_the_hil_world_defaults_are_the_simulators_medium():
    """hil_world_node's radio parameters and config/hil.yaml default to MediumConfig."""
    pytest.importorskip('rclpy')
    from swarm_bridge.hil_world_node import PARAMETERS

    medium = MediumConfig()
    yaml_values = yaml.safe_load(CONFIG.read_text())['hil_world']['ros__parameters']
    for name, field in (('radio_loss', 'loss'), ('radio_range_m', 'range_m'),
                        ('radio_latency_s', 'latency_s')):
        assert PARAMETERS[name][0] == getattr(medium, field)
        assert yaml_values[name] == getattr(medium, field)
