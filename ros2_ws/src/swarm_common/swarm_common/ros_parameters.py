"""ROS side of the parameters generated from configuration dataclasses.

The specs come from ``swarm_common.parameters`` (``tunable`` dataclass fields: the brain's
configs, sim_node's ``SimParameters`` and the radio medium's ``MediumConfig``); this
module turns one into the ``ParameterDescriptor`` a node declares (description, an
``IntegerRange`` or ``FloatingPointRange`` when both bounds are given, read-only unless
the parameter may change at run time) and declares a whole table on a node. Not a node
module; no rclpy import (the node is passed in).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor


def descriptor(spec) -> ParameterDescriptor:
    """The ROS descriptor of a generated parameter (a ``ParamSpec``)."""
    result = ParameterDescriptor(description=spec.description, read_only=not spec.live)
    if isinstance(spec.default, bool) or spec.low is None or spec.high is None:
        return result
    if isinstance(spec.default, int):
        result.integer_range = [IntegerRange(from_value=int(spec.low),
                                             to_value=int(spec.high), step=1)]
    elif isinstance(spec.default, float):
        result.floating_point_range = [FloatingPointRange(
            from_value=float(spec.low), to_value=float(spec.high), step=0.0)]
    return result


def declare(node, table: Mapping[str, Any]) -> dict[str, Any]:
    """Declare every spec of ``table`` (name -> ``ParamSpec``) on ``node``; the values by
    name (rclpy refuses a value of the wrong type or out of range)."""
    for name, spec in table.items():
        node.declare_parameter(name, spec.default, descriptor(spec))
    return {name: node.get_parameter(name).value for name in table}
