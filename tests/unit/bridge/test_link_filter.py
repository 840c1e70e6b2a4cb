"""Who may talk on the robot link: the coordinator address the firmware is built with
(firmware/tools/coordinator_header.py, swarm_common.fleet.load_coordinator), the bridge
dropping frames from XBees not in the fleet, and boards reporting strangers' commands."""

from __future__ import annotations

import pathlib
import re
import subprocess
import sys

import pytest

from swarm_bridge import emulator, protocol, xbee
from swarm_bridge.bridge import Bridge
from swarm_common.fleet import FleetError, HARDWARE_FLEET, load_coordinator, load_fleet

TOOL = pathlib.Path(__file__).resolve().parents[3] / 'firmware/tools/coordinator_header.py'


def header_address(*args: str, out: pathlib.Path) -> tuple[int, str]:
    """Run the header tool; (exit code, stderr); the address is in out when it succeeded."""
    result = subprocess.run([sys.executable, str(TOOL), str(out), *args], capture_output=True,
                            text=True)
    return result.returncode, result.stderr


def generated(out: pathlib.Path) -> int:
    octets = re.search(r'SWP_COORDINATOR_ADDR64\s+\{([^}]*)\}', out.read_text()).group(1)
    return int.from_bytes(bytes(int(v, 16) for v in octets.split(',')), 'big')


def test_the_firmware_and_the_emulator_read_the_same_coordinator(tmp_path):
    out = tmp_path / 'swarm_coordinator.h'
    assert header_address('--fleet', str(HARDWARE_FLEET), out=out) == (0, '')
    assert generated(out) == load_coordinator() == 0x0013A20041000000
    assert load_coordinator() not in {r.address for r in load_fleet()}
    before = out.stat().st_mtime_ns        # unchanged text: not rewritten (no rebuild)
    assert header_address('--fleet', str(HARDWARE_FLEET), out=out)[0] == 0
    assert out.stat().st_mtime_ns == before
    assert header_address('--address', '0013 A200 4100 0001', out=out)[0] == 0
    assert generated(out) == 0x0013A20041000001


@pytest.mark.parametrize('coordinator, why', [
    (None, "has no 'coordinator"), ("'0013A2004100000'", '16 hex digits'),
    ('0013200041000000', 'quote'), ("'000000000000FFFF'", 'broadcast'),
    ("'0000000000000000'", 'alias'), ("'0013A20041000002'", "robot's")])
def test_a_bad_coordinator_is_refused_in_one_line_by_both(tmp_path, coordinator, why):
    text = HARDWARE_FLEET.read_text()
    text = re.sub(r'^coordinator: .*$', '' if coordinator is None else
                  f'coordinator: {coordinator}', text, flags=re.M)
    fleet = tmp_path / 'fleet.yaml'
    fleet.write_text(text)
    code, err = header_address('--fleet', str(fleet), out=tmp_path / 'h.h')
    assert code == 2 and err.count('\n') == 1 and 'Traceback' not in err, err
    assert not (tmp_path / 'h.h').exists()
    with pytest.raises(FleetError):
        load_coordinator(fleet)
    assert why in err, err


def test_frames_from_xbees_not_in_the_fleet_never_reach_an_agent():
    robots = load_fleet()
    bridge = Bridge(robots)
    robot = robots[1]
    status = protocol.Status(1, 0, 0xFFFF, (100, 100, -200), 0, 0)
    strangers = (0x0013A200DEADBEEF, 0x0013A200CAFEF00D)
    for _ in range(3):
        for stranger in strangers:
            assert bridge.on_bytes(xbee.encode(xbee.RxPacket(stranger, status.encode())),
                                   0.0) == []
    assert all(link.status is None and not link.counters for link in bridge.links.values())
    assert bridge.counters['unknown_address'] == 6 and bridge.counters['unknown_senders'] == 2
    texts = [e.text for e in bridge.take_events()]
    assert len(texts) == 2 and all(f'{s:016X}' in t for s, t in zip(strangers, texts))
    # the fleet's robot is heard, and only as itself
    assert bridge.on_bytes(xbee.encode(xbee.RxPacket(robot.address, status.encode())),
                           0.1) == [robot.id]
    assert bridge.links[robot.id].status == status
    assert [k for k, link in bridge.links.items() if link.status] == [robot.id]


def drive(bridge, radio, t, seconds, agent, setpoint, rogue=None, dt=0.01):
    """Bridge and emulated robots in lock step; ``rogue(t)`` may inject frames."""
    for _ in range(round(seconds / dt)):
        t += dt
        bridge.on_pose(agent, 0.0, 0.0, 0.0, t)
        bridge.on_setpoint(agent, *setpoint, t)
        radio.from_host(bridge.poll(t))
        if rogue is not None:
            rogue(t)
        radio.advance(round(dt * 1000))
        bridge.on_bytes(radio.to_host(), t)
    return t


def test_a_rogue_xbee_cannot_steer_an_emulated_robot_and_the_bridge_hears_of_it():
    """A rogue transmitter sends the robot a full-speed CmdVel the opposite way every
    20 ms, while the bridge commands it: the robot runs the bridge's command only, and
    its statuses make the bridge count the rogue's frames and warn once."""
    robots = load_fleet()
    coordinator = load_coordinator()
    radio = emulator.EmulatedRadio.for_fleet([r.address for r in robots], coordinator)
    bridge = Bridge(robots)
    robot = robots[2]
    board = radio.boards[robot.address]
    sent = []

    def rogue(t):
        if round(t * 100) % 2 == 0:
            radio.inject(0x0013A200BADC0DE5, robot.address, protocol.CmdVel(7, 350, 180).encode())
            sent.append(t)

    drive(bridge, radio, 0.0, 1.0, robot.id, (0.01, 0.0), rogue)
    speed, alpha = protocol.body_to_polar(0.01, 0.0)
    assert tuple(board.rates) == protocol.mix_fixed(*protocol.quantize(speed, alpha))[0]
    assert board.foreign == len(sent) == 50
    # statuses every 200 ms report what the board dropped; the last 0-20 ms are not yet in
    counted = bridge.links[robot.id].counters['foreign_frames']
    assert len(sent) - 10 <= counted <= len(sent) and bridge.counters['foreign_frames'] == counted
    warnings = [e.text for e in bridge.take_events() if 'other than the coordinator' in e.text]
    assert len(warnings) == 1 and f'agent {robot.id}' in warnings[0]
    assert bridge.links[robot.id].status.foreign == counted


def test_the_foreign_count_wraps_at_256_and_restarts_with_the_board():
    link = Bridge(load_fleet()).links[0]

    def status(foreign, faults=0):
        return protocol.Status(0, 0, 0, (0, 0, 0), faults, 0, foreign)

    assert [link.note_status(status(3, protocol.FAULT_RESET)), link.note_status(status(250)),
            link.note_status(status(4)), link.note_status(status(2, protocol.FAULT_RESET))] \
        == [3, 247, 10, 2]
