"""swarm_common.domains: a run's ROS domain is one no other run on the machine uses.

Two runs in one domain on localhost discover each other: a hardware-in-the-loop demo
beside a soak run in the same domain took the soak's goals (ids 16 and 19 of 50) and
drove four of its five robots 3.6 m off the arena.
"""

from __future__ import annotations

import socket

import pytest

from swarm_common.domains import (
    bound_udp_ports,
    claim_domain,
    domain_in_use,
    domain_ports,
    DomainError,
)


def test_domain_ports_follow_the_rtps_port_mapping():
    assert domain_ports(0)[0] == 7400 and domain_ports(217)[0] == 7400 + 250 * 217
    assert len(domain_ports(5)) == 250


def test_a_held_domain_is_not_claimed_twice():
    first, lock = claim_domain(start=150)
    try:
        second, other = claim_domain(start=first)
        other.close()
        assert second != first
    finally:
        lock.close()
    again, lock = claim_domain(start=first)     # released: free again
    lock.close()
    assert again == first


def test_a_domain_with_a_participant_socket_is_skipped():
    """A socket bound in a domain's port block (a participant this project did not
    start, e.g. a user's ros2 command) makes the domain busy."""
    domain, lock = claim_domain(start=170)
    lock.close()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind(('127.0.0.1', domain_ports(domain)[10]))
        assert domain_ports(domain)[10] in bound_udp_ports()
        assert domain_in_use(domain)
        other, lock = claim_domain(start=domain)
        lock.close()
        assert other != domain
    finally:
        sock.close()
    assert not domain_in_use(domain)


def test_no_free_domain_is_one_clear_error():
    domain, lock = claim_domain(start=190)
    try:
        with pytest.raises(DomainError, match='pass --domain'):
            claim_domain(low=domain, high=domain)
    finally:
        lock.close()
    with pytest.raises(DomainError, match='not within'):
        claim_domain(low=200, high=300)
