"""package.xml says exactly what each Python package of ros2_ws/src imports: every
third-party and ROS package its modules and launch files import is an <exec_depend>
(or <depend>), and every one declared is imported somewhere (rosdep installs what is
declared; a stale declaration installs what nothing uses)."""

from __future__ import annotations

import ast
import pathlib
import sys
import xml.etree.ElementTree as ET

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SRC = ROOT / 'ros2_ws' / 'src'
PACKAGES = sorted(p for p in SRC.glob('swarm_*') if (p / 'setup.py').is_file())

# rosdep keys of the Python modules whose import name is not their key; ROS packages
# (rclpy, *_msgs, launch, ...) are imported under their own names.
ROSDEP = {
    'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'shapely': 'python3-shapely',
    'yaml': 'python3-yaml', 'PIL': 'python3-pil', 'contourpy': 'python3-contourpy',
    'matplotlib': 'python3-matplotlib', 'tqdm': 'python3-tqdm',
    'serial': 'python3-serial', 'cv2': 'python3-opencv', 'pybullet': 'python3-pybullet',
    'dask': 'python3-dask', 'mcap': 'python3-mcap', 'mcap_ros2': 'python3-mcap-ros2',
    'rosbags': 'python3-rosbags', 'foxglove': 'python3-foxglove-sdk',
    'numba': 'python3-numba',
}


def imports_of(path: pathlib.Path) -> set[str]:
    """Top-level names of the modules ``path`` imports, outside the standard library."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'), filename=str(path))):
        if isinstance(node, ast.Import):
            names.update(a.name.split('.')[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.add(node.module.split('.')[0])
    return {n for n in names if n not in sys.stdlib_module_names and n != '__future__'}


def used_keys(package: pathlib.Path) -> dict[str, str]:
    """rosdep key -> a file that needs it, over the package's modules and launch files."""
    files = [*(package / package.name).rglob('*.py'), *(package / 'launch').glob('*.py')]
    return {ROSDEP.get(name, name): str(path.relative_to(ROOT))
            for path in files for name in imports_of(path) if name != package.name}


def declared_keys(package: pathlib.Path) -> set[str]:
    return {e.text.strip() for e in ET.parse(package / 'package.xml').getroot()
            if e.tag in ('exec_depend', 'depend') and e.text}


@pytest.mark.parametrize('package', PACKAGES, ids=lambda p: p.name)
def test_package_xml_declares_what_the_package_imports(package: pathlib.Path):
    used, declared = used_keys(package), declared_keys(package)
    missing = {key: where for key, where in used.items() if key not in declared}
    assert not missing, f'{package.name}/package.xml lacks <exec_depend> of {missing}'


@pytest.mark.parametrize('package', PACKAGES, ids=lambda p: p.name)
def test_package_xml_declares_nothing_unused(package: pathlib.Path):
    unused = declared_keys(package) - set(used_keys(package))
    assert not unused, f'{package.name}/package.xml declares {sorted(unused)}, imported nowhere'


def test_the_check_sees_imports_and_maps_them_to_rosdep_keys(tmp_path):
    module = tmp_path / 'mod.py'
    module.write_text('import os\nimport yaml\nfrom PIL import Image\n'
                      'from rclpy.node import Node\nfrom . import sibling\n')
    assert imports_of(module) == {'yaml', 'PIL', 'rclpy'}
    assert {ROSDEP.get(n, n) for n in imports_of(module)} == {
        'python3-yaml', 'python3-pil', 'rclpy'}
