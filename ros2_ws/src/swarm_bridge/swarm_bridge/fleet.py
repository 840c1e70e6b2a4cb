"""The hardware fleet: XBee 64-bit addresses of the robots and the agents driving them.

Pure module; reads config/fleet.yaml (thesis Table 5.1: five robots, three types).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import pathlib

import yaml

DEFAULT_FLEET = pathlib.Path(__file__).resolve().parent.parent / 'config' / 'fleet.yaml'


class FleetError(ValueError):
    """A fleet file that cannot be used; the message names the entry and the fix."""


@dataclass(frozen=True)
class Robot:
    """One robot: the agent that drives it and the 64-bit address of its radio."""

    agent_id: int
    address: int
    color: str = ''
    type: int = 1
    radius: float = 0.1

    @property
    def address_hex(self) -> str:
        """Return the address as 16 hex digits (SH then SL)."""
        return f'{self.address:016X}'


def default_fleet_path() -> pathlib.Path:
    """Return the package's fleet.yaml (source tree, or the installed share folder)."""
    if DEFAULT_FLEET.exists():
        return DEFAULT_FLEET
    try:
        from ament_index_python.packages import get_package_share_directory
        return pathlib.Path(get_package_share_directory('swarm_bridge')) / 'config' / 'fleet.yaml'
    except Exception:  # noqa: BLE001 - no ament index: report the source path
        return DEFAULT_FLEET


def parse_address(text: str | int) -> int:
    """Parse a 64-bit XBee address given as 16 hex digits (spaces and 0x allowed)."""
    if isinstance(text, int):
        value = text
    else:
        digits = str(text).replace(' ', '').lower().removeprefix('0x')
        if len(digits) != 16:
            raise FleetError(f'address {text!r} must be 16 hex digits (SH + SL), '
                             f'e.g. 0013A20041000001')
        try:
            value = int(digits, 16)
        except ValueError:
            raise FleetError(f'address {text!r} is not hexadecimal') from None
    if not 0 <= value < 1 << 64:
        raise FleetError(f'address {text!r} does not fit in 64 bits')
    return value


def load_fleet(path: str | pathlib.Path | None = None) -> list[Robot]:
    """Load and check a fleet YAML; ids and addresses must be unique."""
    path = pathlib.Path(path) if path else default_fleet_path()
    try:
        doc = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise FleetError(f'cannot read fleet file {path}: {exc.strerror}') from None
    entries = (doc or {}).get('robots') if isinstance(doc, dict) else None
    if not isinstance(entries, list) or not entries:
        raise FleetError(f'{path}: expected a non-empty list under "robots:"')
    robots = []
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict) or 'agent_id' not in entry or 'address' not in entry:
            raise FleetError(f'{path}: robot #{i} needs agent_id and address')
        robots.append(Robot(int(entry['agent_id']), parse_address(entry['address']),
                            str(entry.get('color', '')), int(entry.get('type', 1)),
                            float(entry.get('radius', 0.1))))
    for key in ('agent_id', 'address'):
        values = [getattr(r, key) for r in robots]
        dupes = sorted({v for v in values if values.count(v) > 1})
        if dupes:
            raise FleetError(f'{path}: duplicate {key} {dupes}; every robot needs its own')
    return robots


def load_cover_colors(path: str | pathlib.Path | None = None) -> dict[str, tuple[int, int, int]]:
    """The fleet file's ``cover_colors``: colour name -> RGB 0-255 (thesis 5.1, Fig. 5.2).

    Every robot's ``color`` must be listed; a fleet file without the section gets the
    package defaults for the names it uses.
    """
    path = pathlib.Path(path) if path else default_fleet_path()
    robots = load_fleet(path)
    doc = yaml.safe_load(path.read_text()) or {}
    table = doc.get('cover_colors') if isinstance(doc, dict) else None
    if table is None and path != DEFAULT_FLEET and DEFAULT_FLEET.exists():
        table = (yaml.safe_load(DEFAULT_FLEET.read_text()) or {}).get('cover_colors')
    table = table or {}
    colors = {}
    for name, rgb in table.items():
        if (not isinstance(rgb, (list, tuple)) or len(rgb) != 3
                or not all(isinstance(v, (int, float)) and 0 <= v <= 255 for v in rgb)):
            raise FleetError(f'{path}: cover_colors {name}: give [r, g, b] with 0-255 values')
        colors[str(name)] = tuple(int(v) for v in rgb)
    unknown = sorted({r.color for r in robots} - set(colors))
    if unknown:
        raise FleetError(f'{path}: robot colours {unknown} are not in cover_colors; add '
                         'their RGB values there')
    return colors


def initial_poses(flat: list[float], count: int) -> list[tuple[float, float, float]]:
    """Poses (x m, y m, yaw rad CCW) from the flat parameter list; a row when empty."""
    if len(flat) <= 1:
        return [(-0.8 + 0.4 * i, -0.8, 0.0) for i in range(count)]
    if len(flat) != 3 * count:
        raise ValueError(f'initial_poses holds {len(flat)} numbers; give x,y,yaw_deg for '
                         f'each of the {count} robots ({3 * count} numbers)')
    return [(flat[3 * i], flat[3 * i + 1], math.radians(flat[3 * i + 2]))
            for i in range(count)]
