"""What every node of every package shares on the ROS side (not a node module itself).

``run_node`` is the ``main()`` of a node: start it, refuse bad input in one line, spin,
stop cleanly. ``lean_publisher`` and ``lean_subscription`` create endpoints without
rclpy's default QoS event handlers.

A node that cannot start (a parameter out of its type or range, an unknown method or
robot type, a missing file) prints one line naming the input and exits with status 2;
no traceback reaches the user. Ctrl-C or a shutdown of the context ends the spin
quietly, and ``stop`` (e.g. command zero velocity) runs before the node is destroyed.
"""

from __future__ import annotations

from collections.abc import Callable
import signal
import sys
from typing import TypeVar

from rcl_interfaces.msg import ParameterDescriptor
import rclpy
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter

N = TypeVar('N', bound=Node)

# What a node's constructor raises for bad input: its parameters (rclpy's checks of
# type and range, ParameterError and the configs' ValueErrors) and files (OSError).
BAD_INPUT = (ParameterException, ValueError, OSError, KeyError)


def _one_line(exc: BaseException) -> str:
    text = ' '.join(str(exc).split())
    return text or type(exc).__name__


def _stop_interrupts() -> None:
    """Ignore further SIGINTs while the node cleans up: ``ros2 launch`` forwards one of
    its own after the terminal's, and a second Ctrl-C must not cut the clean-up short
    with a traceback."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _shutdown() -> None:
    """``rclpy.try_shutdown()``, which races rclpy's SIGINT handler: that one shuts the
    context down from a thread of its own, so after an interrupt the context can go
    between try_shutdown's check and its shutdown (RCLError: rcl_shutdown already
    called). Shut down either way is what was asked."""
    try:
        rclpy.try_shutdown()
    except Exception:
        if rclpy.ok():
            raise


def run_node(make_node: Callable[[], N], name: str, args=None,
             executor: Callable[[], Executor] | None = None,
             stop: Callable[[N], None] | None = None) -> None:
    """Run ``make_node()`` until Ctrl-C or shutdown (the body of a node's ``main``).

    ``executor`` makes the executor to spin (rclpy's default when None), after
    ``make_node`` ran; ``stop`` runs before the node is destroyed. An interrupt while
    the node starts ends the process quietly (status 0), as one while it runs does.
    """
    rclpy.init(args=args)
    try:
        node = make_node()
    except Exception as exc:
        if not rclpy.ok():
            # rclpy's SIGINT handler shut the context down while the node started (with
            # SIGINT ignored by the parent, no KeyboardInterrupt follows): an interrupt.
            _stop_interrupts()
            sys.exit(0)
        if isinstance(exc, BAD_INPUT):
            print(f'{name}: {_one_line(exc)}', file=sys.stderr)
            _shutdown()
            sys.exit(2)
        raise
    except KeyboardInterrupt:
        _stop_interrupts()
        _shutdown()
        sys.exit(0)
    try:
        rclpy.spin(node, executor=executor() if executor else None)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as exc:
        # A stop, not an error: rclpy's SIGINT handler shut the context down while the
        # executor built its wait set (RCLError: the context is not valid; with SIGINT
        # ignored by the parent no KeyboardInterrupt follows), or a message taken while
        # SIGINT tears the subscriptions down failed to convert (ros2/rclpy#848, the
        # context still reported ok). Anything else is real.
        if rclpy.ok():
            if 'Unable to convert call argument' not in str(exc):
                raise
            node.get_logger().warning(f'stopped while taking a message: {exc}')
    finally:
        _stop_interrupts()
        if stop is not None:
            try:
                stop(node)
            except Exception:  # noqa: BLE001 - the context may already be gone
                pass
        node.destroy_node()
        _shutdown()


def lean_publisher(node, msg_type, topic: str, qos_profile, **kwargs):
    """``node.create_publisher`` without rclpy's default QoS event handlers.

    rclpy gives every publisher and subscription default event handlers (incompatible
    QoS, incompatible type) that only log a warning; each is a Python waitable the
    executor adds to its wait set and polls after every wait. The per-robot topics of a
    swarm make hundreds of them (about 550 in a composed process of 50 agents, 250 in
    the simulator): profiled with py-spy on the 50-agent composed scenario, both
    executors spent 60-77 % of their time on wait sets and under 10 % in callbacks.
    What is given up: the warning when a peer's QoS or type does not match; every swarm
    topic takes its profile from ``swarm_common.qos``, so peers agree by construction.
    """
    return node.create_publisher(
        msg_type, topic, qos_profile,
        event_callbacks=PublisherEventCallbacks(use_default_callbacks=False), **kwargs)


def lean_subscription(node, msg_type, topic: str, callback, qos_profile, **kwargs):
    """``node.create_subscription`` without the default QoS event handlers (see
    ``lean_publisher``)."""
    return node.create_subscription(
        msg_type, topic, callback, qos_profile,
        event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False), **kwargs)


def declare_list_parameter(node: Node, name: str, type_: Parameter.Type, description: str) -> list:
    """Declare the read-only list parameter ``name``, the empty list unless given, and
    return its value. rclpy infers no type from ``[]``, and a parameter declared with a
    type only has no value: a get_parameters request that names it gets no values at all,
    which empties ``ros2 param dump`` of the node."""
    node.declare_parameter(name, type_, ParameterDescriptor(description=description))
    if node.get_parameter_or(name).value is None:
        node.set_parameters([Parameter(name, type_, [])])
    node.set_descriptor(name, ParameterDescriptor(description=description, type=type_.value,
                                                  read_only=True))
    return list(node.get_parameter(name).value)
