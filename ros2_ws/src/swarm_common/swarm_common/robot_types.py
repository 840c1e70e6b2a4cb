"""Heterogeneous robot types (thesis Table 4.1) and the LQR design weights (eq. 3.111).

One source of truth for every component: the agents' controllers, the simulator's
bodies and the headless dynamics all read the same ``RobotType`` records, by default
from ``config/robot_types.yaml`` of this package.
"""

from __future__ import annotations

from dataclasses import dataclass
import pathlib

import yaml

from swarm_common.paths import package_file

GRAVITY = 9.81  # m/s^2
# One colour per type (RGB in 0..1) for every view: figures, pybullet bodies, RViz markers
# (matplotlib's tab:red, tab:orange, tab:purple).
TYPE_COLOURS = {1: (0.839, 0.153, 0.157), 2: (1.0, 0.498, 0.055), 3: (0.580, 0.404, 0.741)}
OTHER_COLOUR = (0.5, 0.5, 0.5)


DEFAULT_CONFIG = package_file('swarm_common', 'config/robot_types.yaml')


class RobotTypeError(ValueError):
    """A robot type table or type id that cannot be used."""


@dataclass(frozen=True)
class RobotType:
    """Physical parameters of one robot type (Table 4.1).

    ``dry_friction`` is the Coulomb coefficient mu_1 (force mu_1 * m * g opposing the
    motion); ``fluid_friction`` is mu_2 in N s/m (force -mu_2 * v), the ``b`` of the
    LQR design model of eq. 3.108.
    """

    type_id: int
    mass: float
    dry_friction: float
    fluid_friction: float
    coverage_radius: float

    def __post_init__(self) -> None:
        for name in ('mass', 'coverage_radius'):
            if not getattr(self, name) > 0.0:
                raise RobotTypeError(
                    f'robot type {self.type_id}: {name} must be positive, '
                    f'got {getattr(self, name)!r}')
        for name in ('dry_friction', 'fluid_friction'):
            if not getattr(self, name) >= 0.0:
                raise RobotTypeError(
                    f'robot type {self.type_id}: {name} must be non-negative, '
                    f'got {getattr(self, name)!r}')


@dataclass(frozen=True)
class LqrDesign:
    """Bryson-rule weights of eq. 3.111: settling times, state and input maxima."""

    t1: float = 1.5
    t2: float = 0.01
    x1_max: float = 1.0
    x2_max: float = 4.0
    u_max: float = 3.0


def _load_yaml(path: pathlib.Path) -> dict:
    """The table's contents (read only), parsed once per version of the file: every
    brain of a trial reads it twice, and parsing it was 1 % of a 50-agent trial."""
    try:
        stat = path.stat()
        version = (str(path), stat.st_mtime_ns, stat.st_size)
        data = _PARSED.get(version)
        if data is None:
            with open(path, encoding='utf-8') as stream:
                data = yaml.safe_load(stream)
    except OSError as exc:
        raise RobotTypeError(f'cannot read robot type table {path}: {exc.strerror}') from exc
    if not isinstance(data, dict) or 'robot_types' not in data:
        raise RobotTypeError(f'{path} has no "robot_types" mapping; see {DEFAULT_CONFIG}')
    _PARSED.setdefault(version, data)
    return data


_PARSED: dict[tuple[str, int, int], dict] = {}   # (path, mtime, size) -> its contents


def load_robot_types(path: str | pathlib.Path | None = None) -> dict[int, RobotType]:
    """Read the robot type table; keys are type ids (1, 2, 3 in the thesis)."""
    data = _load_yaml(pathlib.Path(path) if path else DEFAULT_CONFIG)
    types = {}
    for key, fields in data['robot_types'].items():
        try:
            types[int(key)] = RobotType(type_id=int(key), **fields)
        except TypeError as exc:
            raise RobotTypeError(f'robot type {key}: {exc}; expected keys mass, '
                                 'dry_friction, fluid_friction, coverage_radius') from exc
    return types


def load_lqr_design(path: str | pathlib.Path | None = None) -> LqrDesign:
    """Read the eq. 3.111 design parameters (defaults when the file has none)."""
    data = _load_yaml(pathlib.Path(path) if path else DEFAULT_CONFIG)
    return LqrDesign(**data.get('lqr_design', {}))


def robot_type(types: dict[int, RobotType], type_id: int) -> RobotType:
    """Look up a type id with an error naming the known ids."""
    try:
        return types[int(type_id)]
    except (KeyError, ValueError, TypeError):
        raise RobotTypeError(
            f'unknown robot type {type_id!r}; known types are {sorted(types)}') from None


def parse_type_counts(spec: str) -> dict[int, int]:
    """Parse a swarm composition like ``'1:20,2:20,3:10'`` into ``{1: 20, 2: 20, 3: 10}``."""
    counts: dict[int, int] = {}
    try:
        for part in spec.split(','):
            type_id, count = part.split(':')
            counts[int(type_id)] = int(count)
    except ValueError:
        raise RobotTypeError(
            f'bad type counts {spec!r}; write TYPE:COUNT pairs like 1:20,2:20,3:10') from None
    if any(c < 0 for c in counts.values()) or sum(counts.values()) <= 0:
        raise RobotTypeError(f'type counts {spec!r} must be non-negative with a positive total')
    return counts


def agent_types_of(counts: dict[int, int]) -> dict[int, int]:
    """Agent id -> robot type of a swarm given by its composition: ids 0.. in type order
    (the fleet the launcher generates from counts, and the nodes that read only counts)."""
    return dict(enumerate(t for t in sorted(counts) for _ in range(counts[t])))


def default_type_counts(n_agents: int) -> dict[int, int]:
    """Split ``n_agents`` over types 1..3 in the thesis proportions 20:20:10."""
    if n_agents <= 0:
        raise RobotTypeError(f'agent count must be positive, got {n_agents}')
    n1 = round(n_agents * 0.4)
    n2 = round(n_agents * 0.4)
    n3 = n_agents - n1 - n2
    if n3 < 0:
        n2 += n3
        n3 = 0
    return {t: c for t, c in ((1, n1), (2, n2), (3, n3)) if c > 0}
