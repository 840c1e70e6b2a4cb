"""The bootstrap builds the tf2_msgs stand-in only where no ROS installation provides
tf2_msgs: its check finds an installed tf2_msgs in the sourced prefixes (system mode) or
the venv (wheels mode), never the workspace's own build."""

from __future__ import annotations

import pathlib
import re
import shutil
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _installed(mode: str, venv: pathlib.Path, ws: pathlib.Path, prefixes: list) -> bool:
    """Run bootstrap.sh's ``tf2_msgs_installed`` alone with these settings."""
    script = (ROOT / 'scripts' / 'bootstrap.sh').read_text()
    function = re.search(r'^tf2_msgs_installed\(\) \{\n.*?^\}\n', script, re.M | re.S)
    assert function, 'bootstrap.sh defines tf2_msgs_installed'
    result = subprocess.run(
        [shutil.which('bash'), '-c', function.group(0) + 'tf2_msgs_installed'],
        env={'MODE': mode, 'VENV': str(venv), 'WS': str(ws),
             'AMENT_PREFIX_PATH': ':'.join(str(p) for p in prefixes)},
        capture_output=True, text=True, timeout=10)
    assert result.returncode in (0, 1), result.stderr
    return result.returncode == 0


def _prefix(path: pathlib.Path, with_tf2_msgs: bool) -> pathlib.Path:
    index = path / 'share' / 'ament_index' / 'resource_index' / 'packages'
    index.mkdir(parents=True)
    (index / 'geometry_msgs').touch()
    if with_tf2_msgs:
        (index / 'tf2_msgs').touch()
    return path


@pytest.mark.parametrize(('mode', 'where', 'expected'), [
    ('system', 'ros', True),         # /opt/ros/jazzy has it: skip the stand-in
    ('system', 'nowhere', False),    # a ROS without tf2_msgs: build it
    ('system', 'workspace', False),  # our own earlier build does not count
    ('wheels', 'venv', True),        # a future wheel of tf2_msgs in the venv
    ('wheels', 'ros', False),        # wheels mode looks at the venv only
])
def test_tf2_msgs_is_found_only_in_a_ros_installation(tmp_path, mode, where, expected):
    ws = tmp_path / 'ws'
    venv = _prefix(tmp_path / 'venv', where == 'venv')
    ros = _prefix(tmp_path / 'ros', where == 'ros')
    own = _prefix(ws / 'install' / 'tf2_msgs', True)
    assert _installed(mode, venv, ws, [own, ros]) is expected
