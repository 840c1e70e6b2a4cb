"""The bootstrap stops with one clear line when a tool is missing."""

from __future__ import annotations

import os
import pathlib
import shutil
import subprocess

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _fake_path(tmp_path: pathlib.Path, tools: list[str]) -> str:
    """A PATH holding only ``tools`` (symlinked from the real PATH)."""
    bindir = tmp_path / 'bin'
    bindir.mkdir()
    for tool in tools:
        real = shutil.which(tool)
        assert real, f'{tool} is needed by this test'
        (bindir / tool).symlink_to(real)
    return str(bindir)


def _run_bootstrap(path: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ('ROS_DISTRO', 'AMENT_PREFIX_PATH')}
    env['PATH'] = path
    return subprocess.run([shutil.which('bash'), str(ROOT / 'scripts' / 'bootstrap.sh')],
                          env=env, capture_output=True, text=True, timeout=60)


def test_missing_cmake_is_named_with_its_install_command(tmp_path):
    path = _fake_path(tmp_path, ['dirname', 'python3'])
    result = _run_bootstrap(path)
    assert result.returncode != 0
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, result.stderr
    assert 'cmake not found' in lines[0]
    assert 'apt-get install cmake' in lines[0]


def test_missing_compiler_is_named(tmp_path):
    path = _fake_path(tmp_path, ['dirname', 'python3', 'cmake', 'make'])
    result = _run_bootstrap(path)
    assert result.returncode != 0
    assert 'no C compiler found' in result.stderr
    assert 'build-essential' in result.stderr


def test_rerun_with_nothing_changed_is_a_no_op():
    """Once bootstrapped, a second run installs and rebuilds nothing."""
    for _ in range(2):
        result = subprocess.run(['bash', str(ROOT / 'scripts' / 'bootstrap.sh')],
                                capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    assert 'installing' not in result.stdout
    assert 'building' not in result.stdout
