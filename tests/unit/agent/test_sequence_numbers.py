"""DSDV destination sequence numbers are 32-bit serial numbers (RFC 1982 order)."""

from swarm_agent.dsdv import seq_ahead, seq_newer


def test_order_across_the_wrap():
    assert seq_newer(2, 0) and not seq_newer(0, 2)
    assert seq_newer(0, 0xFFFFFFFE)          # the counter wrapped: 0 follows 2^32 - 2
    assert not seq_newer(0xFFFFFFFF, 100)    # a forged maximum is older, not newer
    assert not seq_newer(7, 7)
    assert seq_ahead(4, 0xFFFFFFFE) == 6
    assert seq_ahead(0xFFFFFFFF, 100) == 0
