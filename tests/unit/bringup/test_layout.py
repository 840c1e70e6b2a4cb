"""Library code lives in swarm_bringup; the scripts that start a swarm are thin wrappers
(issue 22: no file in scripts/ over 150 lines, no module of ros2_ws/src over 600)."""

from __future__ import annotations

import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]
WRAPPERS = ('launch_swarm.py', 'hil_demo.py', 'demo.py')


@pytest.mark.parametrize('name', WRAPPERS)
def test_scripts_are_thin_wrappers_of_the_package(name):
    path = ROOT / 'scripts' / name
    text = path.read_text(encoding='utf-8')
    assert len(text.splitlines()) <= 150
    tree = ast.parse(text)
    modules = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    modules |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    # No script imports another script: everything comes from the package.
    assert not modules & {w.removesuffix('.py') for w in WRAPPERS}
    assert any(m and m.startswith('swarm_bringup.') for m in modules)


def test_package_modules_stay_short():
    package = ROOT / 'ros2_ws' / 'src' / 'swarm_bringup'
    long = {p.name: n for p in package.rglob('*.py')
            if (n := len(p.read_text(encoding='utf-8').splitlines())) > 600}
    assert not long
