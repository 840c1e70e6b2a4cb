"""The ``main()`` of a node: start it, refuse bad input in one line, spin, stop cleanly.

A node that cannot start (a parameter out of its type or range, an unknown method or
robot type, a missing file) prints one line naming the input and exits with status 2;
no traceback reaches the user. Ctrl-C or a shutdown of the context ends the spin
quietly, and ``stop`` (e.g. command zero velocity) runs before the node is destroyed.
"""

from __future__ import annotations

from collections.abc import Callable
import sys
from typing import TypeVar

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node

N = TypeVar('N', bound=Node)

# What a node's constructor raises for bad input: its parameters (rclpy's checks of
# type and range, ParameterError and the configs' ValueErrors) and files (OSError).
BAD_INPUT = (ParameterException, ValueError, OSError, KeyError)


def _one_line(exc: BaseException) -> str:
    text = ' '.join(str(exc).split())
    return text or type(exc).__name__


def run_node(make_node: Callable[[], N], name: str, args=None,
             executor: Callable[[], Executor] | None = None,
             stop: Callable[[N], None] | None = None) -> None:
    """Run ``make_node()`` until Ctrl-C or shutdown (the body of a node's ``main``)."""
    rclpy.init(args=args)
    try:
        node = make_node()
    except BAD_INPUT as exc:
        print(f'{name}: {_one_line(exc)}', file=sys.stderr)
        rclpy.try_shutdown()
        sys.exit(2)
    try:
        rclpy.spin(node, executor=executor() if executor else None)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if stop is not None:
            try:
                stop(node)
            except Exception:  # noqa: BLE001 - the context may already be gone
                pass
        node.destroy_node()
        rclpy.try_shutdown()
