"""The pure bridge against emulated robots: kinematics, watchdog, faults on the link."""

from __future__ import annotations

import math

from swarm_bridge import emulator, protocol, xbee
from swarm_bridge.bridge import Bridge
from swarm_common.fleet import load_fleet


def run(bridge, radio, t0, seconds, agent=None, setpoint=None, yaw=0.0, dt=0.01):
    t = t0
    for _ in range(round(seconds / dt)):
        t += dt
        if agent is not None:
            bridge.on_pose(agent, 0.0, 0.0, yaw, t)
            if setpoint is not None:
                bridge.on_setpoint(agent, *setpoint, t)
        radio.from_host(bridge.poll(t))
        radio.advance(round(dt * 1000))
        bridge.on_bytes(radio.to_host(), t)
    return t


def test_wheels_follow_the_kinematics_then_the_agent_watchdog_stops_them():
    robots = load_fleet()
    radio = emulator.EmulatedRadio.for_fleet([r.address for r in robots])
    bridge = Bridge(robots)
    yaw = math.radians(30.0)
    t = run(bridge, radio, 0.0, 1.0, agent=1, setpoint=(0.01, 0.02), yaw=yaw)
    board = radio.boards[robots[1].address]
    # the setpoint is body-frame cmd_vel (REP 103): sent as is, whatever the heading
    speed, alpha = protocol.body_to_polar(0.01, 0.02)
    for got, want in zip(board.wheel_speeds(), protocol.wheel_speeds(speed, alpha)):
        assert abs(got - want) < 2e-4
    assert bridge.links[1].status.rates == tuple(board.rates)
    t = run(bridge, radio, t, 2.0, agent=1, yaw=yaw)   # cmd_vel stops (1.5 s), poses go on
    assert board.rates == [0, 0, 0] and bridge.counters['watchdog_stops'] == 1
    assert any('stopped publishing cmd_vel' in e.text for e in bridge.take_events())


def test_board_watchdog_stops_a_robot_whose_bridge_died():
    board = emulator.EmulatedBoard(1)
    board.receive(xbee.encode(xbee.RxPacket(0, protocol.CmdVel(1, 300, 10).encode())))
    board.tick(protocol.CMD_TIMEOUT_MS - 1)
    assert any(board.rates)
    board.tick(1)
    assert board.rates == [0, 0, 0] and board.faults & protocol.FAULT_WATCHDOG


def test_garbage_unknown_addresses_and_silent_boards_are_counted_once():
    robots = load_fleet()
    radio = emulator.EmulatedRadio.for_fleet([r.address for r in robots])
    bridge = Bridge(robots)
    stranger = xbee.encode(xbee.RxPacket(0xDEADBEEF, protocol.Stop(1).encode()))
    bad = bytearray(stranger)
    bad[-1] ^= 0xFF
    for _ in range(3):
        bridge.on_bytes(b'\x13\x00noise' + stranger + bytes(bad) + stranger[:7], 0.0)
    assert bridge.counters['unknown_address'] == 3
    # each cut frame ends in a new start (truncated) or in the raw XOFF of the next noise
    cut = bridge.counters['truncated'] + bridge.counters['bad_escapes']
    assert bridge.counters['bad_checksums'] == 3 and cut >= 2
    radio.boards[robots[2].address].powered = False
    run(bridge, radio, 0.0, 2.0, agent=2, setpoint=(0.01, 0.0))
    assert bridge.links[2].silent and bridge.counters['silent_boards'] == 1
    assert bridge.counters['delivery_failures'] > 10
    texts = [e.text for e in bridge.take_events()]
    assert sum('not in the fleet' in t for t in texts) == 1
    assert sum('stopped answering' in t for t in texts) == 1
    assert sum('could not deliver' in t for t in texts) == 1
    radio.boards[robots[2].address].powered = True
    run(bridge, radio, 2.0, 0.5, agent=2, setpoint=(0.01, 0.0))
    assert not bridge.links[2].silent
    assert any('answering again' in e.text for e in bridge.take_events())
