"""ROS parameters generated from the brain's configuration dataclasses.

One source of truth: each tunable field of ``BrainConfig`` and of its nested configs
(``localization``, ``setpoint``, ``forces``, ``dsdv``) says in its dataclass metadata
(``tunable``) what it means, its unit, its range and whether a running agent may change
it. A node declares one parameter per ``ParamSpec`` of ``specs(BrainConfig)`` (dotted
names: ``hold_radius``, ``localization.gate``, ``setpoint.v_max``), builds its brain's
configuration with ``configured`` and applies run-time changes with ``set_live``. No
YAML mirrors the defaults. Pure: no rclpy (the node turns a spec into a
``ParameterDescriptor``).

Live parameters are read by the brain each time it uses them, so changing the field in
place takes effect at the agent's next step; the others are built into an object when
the brain starts (the Kalman filter's noise model, the router's timers) and are
read-only.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
import dataclasses
from dataclasses import dataclass, field
import math
from typing import Any

Value = bool | int | float | str


class ParameterError(ValueError):
    """A parameter value outside its type or range; the message is one line naming the
    parameter and the fix."""


@dataclass(frozen=True)
class ParamSpec:
    """One generated parameter."""

    name: str                    # dotted path from the root config
    default: Value
    description: str
    low: float | None = None     # inclusive bounds (None: unbounded)
    high: float | None = None
    live: bool = False           # may change while the agent runs

    def check(self, value: Any) -> Value:
        """``value`` converted to this parameter's type, or ParameterError."""
        kind = type(self.default)
        if kind is bool:
            if not isinstance(value, bool):
                raise ParameterError(f'parameter {self.name} must be true or false, got '
                                     f'{value!r}')
            return value
        if kind is int:
            if isinstance(value, bool) or not isinstance(value, int):
                raise ParameterError(f'parameter {self.name} must be an integer, got '
                                     f'{value!r}: e.g. {self.name}:={self.default}')
        elif kind is float:
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value):
                raise ParameterError(f'parameter {self.name} must be a finite number, got '
                                     f'{value!r}: e.g. {self.name}:={self.default}')
            value = float(value)
        if (self.low is not None and value < self.low) or \
                (self.high is not None and value > self.high):
            raise ParameterError(f'parameter {self.name} must be in [{self.low}, '
                                 f'{self.high}], got {value}: {self.description}')
        return value


def tunable(default: Value, description: str, *, low: float | None = None,
            high: float | None = None, live: bool = False):
    """A dataclass field that is also a ROS parameter (see the module docstring)."""
    meta = {'description': description, 'low': low, 'high': high, 'live': live}
    return field(default=default, metadata={'tunable': meta})


def _nested(f: dataclasses.Field) -> type | None:
    """The dataclass a field holds by default, if it is one (a nested config)."""
    factory = f.default_factory
    if factory is not dataclasses.MISSING and isinstance(factory, type) \
            and dataclasses.is_dataclass(factory):
        return factory
    return None


def specs(config_type: type, prefix: str = '') -> Iterator[ParamSpec]:
    """Every tunable field of ``config_type`` and of its nested configs, depth first."""
    for f in dataclasses.fields(config_type):
        meta = f.metadata.get('tunable')
        if meta is not None:
            yield ParamSpec(prefix + f.name, f.default, meta['description'],
                            meta['low'], meta['high'], meta['live'])
        elif (inner := _nested(f)) is not None:
            yield from specs(inner, f'{prefix}{f.name}.')


def spec_table(config_type: type) -> dict[str, ParamSpec]:
    """``specs`` keyed by name."""
    return {s.name: s for s in specs(config_type)}


def configured(config: Any, values: Mapping[str, Any]) -> Any:
    """A copy of ``config`` with the dotted ``values`` set (each checked against its
    spec; the dataclasses' own checks then run on the result). ParameterError names the
    first bad one."""
    table = spec_table(type(config))
    groups: dict[str, dict[str, Any]] = {}
    top: dict[str, Any] = {}
    for name, value in values.items():
        spec = table.get(name)
        if spec is None:
            raise ParameterError(f'unknown parameter {name}: one of {", ".join(table)}')
        value = spec.check(value)
        head, _, rest = name.partition('.')
        if rest:
            groups.setdefault(head, {})[rest] = value
        else:
            top[head] = value
    for head, inner in groups.items():
        top[head] = configured(getattr(config, head), {k: v for k, v in inner.items()})
    try:
        return dataclasses.replace(config, **top)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f'{", ".join(values)}: {exc}') from None


def set_live(config: Any, name: str, value: Any) -> None:
    """Set a live parameter in place on a running agent's ``config``.

    The whole configuration is checked first as ``configured`` would build it (so the
    dataclasses' cross-field checks hold); ParameterError leaves it unchanged.
    """
    spec = spec_table(type(config)).get(name)
    if spec is None:
        raise ParameterError(f'unknown parameter {name}')
    if not spec.live:
        raise ParameterError(f'parameter {name} is read-only: it takes effect at start; '
                             'set it in the params file or with --ros-args -p')
    value = spec.check(value)
    configured(config, {name: value})
    *path, leaf = name.split('.')
    target = config
    for part in path:
        target = getattr(target, part)
    setattr(target, leaf, value)
