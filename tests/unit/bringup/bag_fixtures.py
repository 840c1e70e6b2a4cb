"""Helpers of the bag tests: a settable clock and CDR bytes of a message."""

from __future__ import annotations

from mcap_ros2._dynamic import serialize_dynamic

from swarm_bringup.bag import message_definition


class FakeClock:
    """Wall seconds set by the test."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def cdr(type_name: str, message: dict) -> bytes:
    """``message`` serialized as CDR by mcap-ros2-support from the definition the bag
    stores (the bytes a publisher of the type sends)."""
    return serialize_dynamic(type_name, message_definition(type_name))[type_name](message)
