"""DSDV destination sequence numbers are 32-bit serial numbers (RFC 1982 order)."""

import pytest

from swarm_agent import wire
from swarm_agent.dsdv import DsdvConfig, DsdvRouter, seq_newer, SEQUENCE_MASK, SEQUENCE_STEP
from swarm_agent.packet import BROADCAST, Kind, Packet
from swarm_agent.wire import Advert

# The selection rules run as a kernel (swarm_agent.route_table): compiled and as source.
pytestmark = pytest.mark.usefixtures('kernels')

def test_order_across_the_wrap():
    assert seq_newer(2, 0) and not seq_newer(0, 2)
    assert seq_newer(0, 0xFFFFFFFE)          # the counter wrapped: 0 follows 2^32 - 2
    assert not seq_newer(0xFFFFFFFF, 100)    # a forged maximum is older, not newer
    assert not seq_newer(7, 7)


def _advert(router: DsdvRouter, t: float, sender: int, destination: int, hops: int,
            sequence: int) -> None:
    frame = wire.encode_adverts(0, [Advert(destination, hops, sequence)])[0]
    router.on_packet(t, Packet(sender, BROADCAST, Kind.DSDV_INCREMENTAL, 1, 1, frame))


def test_damping_counts_generations_across_the_wrap():
    """A longer path with a newer number is damped until the held route is
    ``stale_generations`` full dumps behind, also when the numbers wrap past 2^32."""
    config = DsdvConfig()
    router = DsdvRouter(0, config)
    held = 0xFFFFFFFE
    _advert(router, 0.0, 1, 9, 1, held)              # 9 is two hops away through 1
    assert router.next_hop(9) == 1
    newer = (held + SEQUENCE_STEP) & SEQUENCE_MASK    # wrapped to 0
    _advert(router, 0.1, 2, 9, 2, newer)             # three hops through 2: damped
    assert router.next_hop(9) == 1 and router.stats['damped'] == 1
    stale = (held + config.stale_generations * SEQUENCE_STEP) & SEQUENCE_MASK
    _advert(router, 0.2, 2, 9, 2, stale)             # the held route is too old now
    assert router.next_hop(9) == 2 and router.table[9].sequence_number == stale
    _advert(router, 0.3, 1, 9, 1, held)              # an older number changes nothing
    assert router.next_hop(9) == 2
    _advert(router, 0.4, 1, 9, 1, stale)             # same number, shorter path: taken
    assert router.next_hop(9) == 1 and router.table[9].hop_count == 2
