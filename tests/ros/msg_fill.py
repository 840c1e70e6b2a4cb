"""Fill any ROS message with random non-default values, driven by its introspection."""

from __future__ import annotations

import importlib
import random
import re

INT_RANGES = {
    'uint8': (0, 255), 'octet': (0, 255), 'int8': (-128, 127), 'uint16': (0, 65535),
    'int16': (-32768, 32767), 'uint32': (0, 2**32 - 1), 'int32': (-(2**31), 2**31 - 1),
    'uint64': (0, 2**63), 'int64': (-(2**62), 2**62),
}


def msg_class(type_name: str):
    """'swarm_msgs/RouteEntry' -> the Python class."""
    pkg, name = type_name.split('/')
    return getattr(importlib.import_module(pkg + '.msg'), name)


def _scalar(type_name: str, rng: random.Random):
    if type_name in INT_RANGES:
        lo, hi = INT_RANGES[type_name]
        return rng.randint(max(lo, 1) if lo == 0 else lo, hi)
    if type_name in ('double', 'float'):
        # float32 round-trips exactly only for values representable in 24 bits.
        return rng.randint(-(2**20), 2**20) / 64.0
    if type_name == 'boolean':
        return True
    if type_name == 'string':
        return ''.join(rng.choice('abcxyz_019') for _ in range(rng.randint(1, 12)))
    if '/' in type_name:
        return fill(msg_class(type_name)(), rng)
    raise ValueError(f'unsupported field type {type_name}')


def fill(msg, rng: random.Random):
    """Set every field of ``msg`` to a random non-default value; return ``msg``."""
    for field, ftype in msg.get_fields_and_field_types().items():
        seq = re.fullmatch(r'sequence<([^,>]+)(?:, \d+)?>', ftype)
        arr = re.fullmatch(r'(.+)\[(\d+)\]', ftype)
        if seq:
            value = [_scalar(seq.group(1), rng) for _ in range(rng.randint(1, 5))]
        elif arr:
            value = [_scalar(arr.group(1), rng) for _ in range(int(arr.group(2)))]
        else:
            value = _scalar(ftype, rng)
        if (seq or arr) and (seq or arr).group(1) in ('uint8', 'octet'):
            value = bytes(value) if (seq or arr).group(1) == 'octet' else value
        setattr(msg, field, value)
    return msg


def as_plain(msg):
    """A nested plain-Python view of a message, for equality assertions."""
    if hasattr(msg, 'get_fields_and_field_types'):
        return {f: as_plain(getattr(msg, f)) for f in msg.get_fields_and_field_types()}
    if isinstance(msg, (list, tuple)) or type(msg).__name__ in ('array', 'ndarray'):
        return [as_plain(v) for v in msg]
    if isinstance(msg, (bytes, bytearray)):
        return list(msg)
    return msg
