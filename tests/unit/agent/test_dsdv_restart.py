"""DSDV across a restart (issue 24): the first own sequence number comes from the boot
time (``dsdv.boot_sequence``), so a restarted router's numbers are newer than those of
its previous run, which its neighbours still hold, with nothing stored."""

from __future__ import annotations

import pytest

from swarm_agent.dsdv import (
    BOOT_RATE,
    boot_sequence,
    DsdvConfig,
    DsdvRouter,
    seq_newer,
    SEQUENCE_MASK,
)
from swarm_agent.packet import Kind

BOOT = 1_780_000_000.0   # a wall-clock reading (s), late 2026


def _exchange(t: float, sender: DsdvRouter, receiver: DsdvRouter,
              kinds: tuple[int, ...] = (Kind.HEARTBEAT, Kind.DSDV_FULL)) -> None:
    for packet in sender.tick(t):
        if packet.kind in kinds:
            receiver.on_packet(t, packet)


def _converse(a: DsdvRouter, b: DsdvRouter, t0: float, seconds: float) -> float:
    t = t0
    while t < t0 + seconds:
        _exchange(t, a, b)
        _exchange(t, b, a)
        t += 0.1
    return t


@pytest.mark.parametrize('boot', [0.0, 1.5, BOOT, 2.0**25 + 0.3])
def test_boot_sequence_is_even_and_grows_with_the_clock(boot):
    first = boot_sequence(boot)
    assert first % 2 == 0 and 0 <= first <= SEQUENCE_MASK
    assert first == (2 * round(boot * BOOT_RATE)) & SEQUENCE_MASK
    # One second later: 2 * BOOT_RATE newer, in serial order also across the wrap.
    assert (boot_sequence(boot + 1.0) - first) & SEQUENCE_MASK == 2 * BOOT_RATE
    assert seq_newer(boot_sequence(boot + 1.0), first)


@pytest.mark.parametrize('life_s', [1.0, 3600.0, 30 * 86400.0])
def test_a_restart_outbids_the_previous_run_at_the_fastest_dump_rate(life_s):
    """Condition (b): the config's fastest full dumps (every 0.01 s, +2 each) grow a run's
    number by 200 a second, below the 2 * BOOT_RATE = 256 a second of boot time."""
    shortest = DsdvConfig.__dataclass_fields__['full_dump_period_s'].metadata['tunable']['low']
    fastest = 1.0 / shortest   # full dumps a second
    assert fastest == pytest.approx(100.0)
    last = (boot_sequence(BOOT) + round(2 * fastest * life_s)) & SEQUENCE_MASK
    assert seq_newer(boot_sequence(BOOT + life_s), last)


def test_the_condition_ends_after_97_days_down():
    """Condition (c): past 2**30 / BOOT_RATE s between boots serial order flips."""
    limit = 2.0**30 / BOOT_RATE
    assert 97 * 86400 < limit < 98 * 86400
    assert seq_newer(boot_sequence(BOOT + limit - 1.0), boot_sequence(BOOT))
    assert not seq_newer(boot_sequence(BOOT + limit + 1.0), boot_sequence(BOOT))


@pytest.mark.parametrize('boot', [BOOT, 0.0])
def test_a_restarted_neighbour_is_taken_at_its_first_heartbeat(boot):
    """Router 1 restarts while router 2 still holds its route (within the neighbour
    timeout). Booted from the clock, router 1's first heartbeat carries a number newer
    than its old run's and router 2 takes it at once; starting from 0 again (the old
    behaviour: ``boot`` 0 for both runs), router 2 keeps the old run's number until
    router 1 has heard router 2's dump, outbid it and sent its next heartbeat."""
    a, b = DsdvRouter(1, boot_time_s=boot), DsdvRouter(2, boot_time_s=boot + 0.3)
    t = _converse(a, b, 0.0, 20.0)
    old = a.sequence
    assert b.table[1].sequence_number == old and b.table[1].hop_count == 1
    restart = t + 0.55   # off the dump grid of router 2
    a = DsdvRouter(1, boot_time_s=boot + restart if boot else 0.0)
    _exchange(restart, a, b, kinds=(Kind.HEARTBEAT,))
    taken = seq_newer(b.table[1].sequence_number, old)
    assert taken is bool(boot)
    if not boot:
        assert b.table[1].sequence_number == old
        _converse(a, b, restart + 0.1, 2.6)   # one dump period and a heartbeat
        assert seq_newer(b.table[1].sequence_number, old)


def test_a_dump_heard_before_any_heartbeat_keeps_the_senders_number():
    """A route made from a dump starts a step below the header's number (the sender's
    own): a fixed 0 would be newer than a boot-time number in the upper half of the
    serial space, and the sender, hearing it advertised back, would jump to 2."""
    boot = (2**31 + 2**20) / (2 * BOOT_RATE)       # first number just past 2**31
    a, b = DsdvRouter(1, boot_time_s=boot), DsdvRouter(2, boot_time_s=boot)
    first = a.sequence
    assert first > 2**31
    _exchange(0.0, a, b, kinds=(Kind.DSDV_FULL,))   # the heartbeat is lost
    assert b.table[1].sequence_number == first + 2
    _exchange(0.0, b, a, kinds=(Kind.DSDV_FULL,))
    assert a.sequence == first + 2                   # not outbid to 2
