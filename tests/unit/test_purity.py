"""The one architectural rule: pure modules never import rclpy (DESIGN.md)."""

from __future__ import annotations

import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[2]
SRC = ROOT / 'ros2_ws' / 'src'


# The ROS-side helpers of the base package, shared by the nodes of every package so that
# no package imports another's node module: the main() of every node (one-line errors for
# bad input) and rclpy endpoints without default QoS event handlers.
SHARED_ROS_HELPERS = {'swarm_common/ros_support.py'}


def _is_allowed(path: pathlib.Path) -> bool:
    """Nodes, the shared ROS helpers, launch files and tests may import rclpy; nothing
    else may."""
    return (
        path.name.endswith('_node.py')
        or f'{path.parent.name}/{path.name}' in SHARED_ROS_HELPERS
        or path.name.endswith('.launch.py')
        or 'launch' in path.parts
        or 'test' in path.parts
        or path.name == 'setup.py'
    )


def _imports_rclpy(path: pathlib.Path) -> list[int]:
    tree = ast.parse(path.read_text(encoding='utf-8'), filename=str(path))
    lines = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            if any(a.name == 'rclpy' or a.name.startswith('rclpy.') for a in node.names):
                lines.append(node.lineno)
        elif isinstance(node, ast.ImportFrom):
            if node.module and (node.module == 'rclpy' or node.module.startswith('rclpy.')):
                lines.append(node.lineno)
    return lines


def test_pure_modules_do_not_import_rclpy():
    offenders = []
    modules = [p for p in SRC.rglob('*.py') if not _is_allowed(p)]
    assert modules, 'no pure modules found: is ros2_ws/src populated?'
    for path in modules:
        for line in _imports_rclpy(path):
            offenders.append(f'{path.relative_to(ROOT)}:{line}')
    assert not offenders, 'pure modules import rclpy (move ROS code into a *_node.py): ' + (
        ', '.join(offenders)
    )


def test_detector_catches_an_rclpy_import(tmp_path):
    """The check itself must be able to fail."""
    bad = tmp_path / 'estimator.py'
    bad.write_text('import numpy\nfrom rclpy.node import Node\n')
    assert _imports_rclpy(bad) == [2]
    assert not _is_allowed(bad)
    assert _is_allowed(tmp_path / 'agent_node.py')
