"""The simulated radio medium (thesis 4.1): range, line of sight, loss, latency, TOA."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import box, LineString

from swarm_agent.packet import BROADCAST, Kind, Packet
from swarm_sim.medium import FRAME_OVERHEAD_BYTES, MediumConfig, RadioMedium


def _medium(positions, obstacles=(), seed: int = 0, **config) -> RadioMedium:
    medium = RadioMedium(MediumConfig(**config), np.random.default_rng(seed), obstacles)
    medium.update_positions(list(range(len(positions))), positions)
    return medium


def _frame(source: int, destination: int = BROADCAST, size: int = 20) -> Packet:
    return Packet(source, destination, Kind.DATA, 0, 1, bytes(size))


def test_links_only_within_range():
    """Thesis 4.1: 25 m radio range."""
    assert MediumConfig().range_m == 25.0
    medium = _medium([[0.0, 0.0], [24.9, 0.0], [49.8, 0.0], [0.0, 25.1]])
    assert medium.neighbours(0) == [1]
    assert medium.neighbours(1) == [0, 2]
    assert medium.neighbours(2) == [1]
    assert medium.neighbours(3) == []
    ids, links = medium.adjacency()
    assert ids == [0, 1, 2, 3] and (links == links.T).all() and not links.diagonal().any()


def test_obstacle_between_two_robots_removes_their_link():
    wall = box(9.0, -1.0, 11.0, 1.0)
    medium = _medium([[0.0, 0.0], [20.0, 0.0], [10.0, 10.0]], obstacles=[wall])
    assert medium.neighbours(0) == [2] and medium.neighbours(1) == [2]
    clear = _medium([[0.0, 0.0], [20.0, 0.0], [10.0, 10.0]], obstacles=[wall],
                    line_of_sight=False)
    assert clear.neighbours(0) == [1, 2]
    # a frame from 0 never reaches 1 through the wall
    medium.transmit(0.0, _frame(0, 1))
    assert medium.deliver(1.0) == [] and medium.stats.dropped_range == 1


def test_links_are_range_and_line_of_sight_on_random_crowds_as_robots_move(kernels):
    # The definition pair by pair (distance <= range, the segment crossing no obstacle,
    # neither radio dead) on random crowds, moved between updates so that the links
    # change and then stay (the neighbour lists are rebuilt only when they change).
    rng = np.random.default_rng(3)
    walls = [box(-2.0, -8.0, 0.0, 8.0), box(10.0, 10.0, 14.0, 12.0)]
    for _ in range(40):
        n = int(rng.integers(2, 40))
        pos = rng.uniform(-30.0, 30.0, (n, 2))
        medium = RadioMedium(MediumConfig(), np.random.default_rng(0), walls)
        ids = list(range(100, 100 + n))
        dead = {int(d) for d in rng.choice(ids, size=int(rng.integers(0, 3)))}
        for d in dead:
            medium.disable_radio(d)
        for _ in range(3):
            if rng.random() < 0.5:
                pos = pos + rng.normal(0.0, 3.0, pos.shape)
            medium.update_positions(ids, pos)
            for a in range(n):
                want = [ids[b] for b in range(n) if b != a
                        and ids[a] not in dead and ids[b] not in dead
                        and np.hypot(*(pos[a] - pos[b])) <= 25.0
                        and not any(w.intersects(LineString([pos[a], pos[b]]))
                                    for w in walls)]
                assert medium.neighbours(ids[a]) == want


def test_dead_radio_has_no_links_and_hears_nothing():
    medium = _medium([[0.0, 0.0], [5.0, 0.0]])
    medium.transmit(0.0, _frame(0))
    medium.disable_radio(1)
    assert medium.deliver(1.0) == [] and medium.stats.dropped_dead == 1
    medium.update_positions([0, 1], [[0.0, 0.0], [5.0, 0.0]])
    assert medium.neighbours(0) == [] and medium.toa_ranges(0, [1]) == []
    medium.enable_radio(1)
    medium.update_positions([0, 1], [[0.0, 0.0], [5.0, 0.0]])
    assert medium.neighbours(0) == [1]


@pytest.mark.parametrize('loss', [0.0, 0.2, 0.5])
def test_loss_rate_close_to_configured(loss):
    """Each receiver draws its own loss: the delivered share is binomial, 4 sigma wide."""
    medium = _medium([[0.0, 0.0], [5.0, 0.0], [0.0, 5.0]], loss=loss, seed=1)
    n = 5000
    for k in range(n):
        medium.transmit(k * 0.01, _frame(0))
    delivered = medium.deliver(1e6)
    share = len(delivered) / (2 * n)
    assert abs(share - (1 - loss)) <= 4 * np.sqrt(loss * (1 - loss) / (2 * n)) + 1e-12
    assert medium.stats.dropped_loss == 2 * n - len(delivered)
    # the two receivers lose independently: both hear a frame with probability (1-p)^2
    per_receiver = {r: sum(1 for rr, _ in delivered if rr == r) for r in (1, 2)}
    assert all(abs(c / n - (1 - loss)) < 0.03 for c in per_receiver.values())


def test_bad_loss_rejected():
    with pytest.raises(ValueError, match='packet loss'):
        RadioMedium(MediumConfig(loss=1.5), np.random.default_rng(0))
    with pytest.raises(ValueError, match='packet loss'):
        _medium([[0.0, 0.0]]).set_loss(-0.1)


def test_latency_and_airtime_respected():
    """Arrival = start + airtime (payload + 18 bytes at 250 kbit/s) + latency."""
    cfg = MediumConfig()
    medium = _medium([[0.0, 0.0], [5.0, 0.0]])
    airtime = 8.0 * (20 + FRAME_OVERHEAD_BYTES) / cfg.bandwidth_bps
    arrival = 1.0 + airtime + cfg.latency_s
    medium.transmit(1.0, _frame(0, 1))
    assert medium.deliver(arrival - 1e-9) == []
    got = medium.deliver(arrival)
    assert [(r, p.source) for r, p in got] == [(1, 0)]
    # a second frame sent at the same instant waits for the first to leave the radio
    medium.transmit(2.0, _frame(0, 1))
    medium.transmit(2.0, _frame(0, 1))
    second = 2.0 + 2 * airtime + cfg.latency_s
    assert len(medium.deliver(second - 1e-9)) == 1
    assert len(medium.deliver(second)) == 1


def test_deliver_in_arrival_order():
    medium = _medium([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]])
    medium.transmit(0.0, _frame(0, size=90))
    medium.transmit(0.0, _frame(2, size=5))
    got = medium.deliver(1.0)
    assert [(r, p.source) for r, p in got] == [(0, 2), (1, 2), (1, 0), (2, 0)]


def test_toa_ranges_only_to_beacon_neighbours_with_configured_noise():
    """True distance plus N(0, range_noise_std), only to beacons in direct radio contact."""
    positions = [[0.0, 0.0], [10.0, 0.0], [0.0, 20.0], [40.0, 0.0], [-6.0, -8.0]]
    medium = _medium(positions, obstacles=[box(-4.0, -6.0, -2.0, -3.0)], seed=3,
                     range_noise_std=0.5)
    beacons = [1, 2, 3, 4]   # 3 is out of range, 4 behind an obstacle
    samples = [medium.toa_ranges(0, beacons) for _ in range(4000)]
    assert {tuple(b for b, _, _ in s) for s in samples} == {(1, 2)}
    r = np.array([[rng for _, rng, _ in s] for s in samples])
    assert all(std == 0.5 for s in samples for _, _, std in s)
    se = 0.5 / np.sqrt(len(r))
    np.testing.assert_allclose(r.mean(axis=0), [10.0, 20.0], atol=4 * se)
    # sample std of 4000 normals: relative standard error 1 / sqrt(2 n) ~ 1.1 %
    np.testing.assert_allclose(r.std(axis=0, ddof=1), [0.5, 0.5], rtol=0.05)
    assert medium.toa_ranges(0, [0]) == []   # not its own beacon


def test_peer_ranges_reach_every_neighbour_without_touching_the_beacon_stream():
    """With ``peers`` the ranges cover every direct neighbour (secondary anchors), with
    the same noise; the beacon ranges of a seed are those without peers, draw for draw
    (peer ranges have a stream of their own)."""
    positions = [[0.0, 0.0], [10.0, 0.0], [0.0, 20.0], [40.0, 0.0], [-6.0, -8.0], [3.0, 4.0]]
    plain, peers = _medium(positions, seed=3), _medium(positions, seed=3)
    for _ in range(50):
        a = plain.toa_ranges(0, [1, 2])
        b = peers.toa_ranges(0, [1, 2], peers=True)
        assert b[:2] == a
        assert [k for k, _, _ in b[2:]] == [4, 5]     # 3 is out of range
    r = np.array([[rng for _, rng, _ in peers.toa_ranges(0, [1, 2], peers=True)[2:]]
                  for _ in range(4000)])
    se = 0.3 / np.sqrt(len(r))
    np.testing.assert_allclose(r.mean(axis=0), [10.0, 5.0], atol=4 * se)
    np.testing.assert_allclose(r.std(axis=0, ddof=1), [0.3, 0.3], rtol=0.05)
