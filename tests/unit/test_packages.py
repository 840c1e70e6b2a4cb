"""Every ament_python package of ros2_ws/src runs what it names: each console script of
its setup.py is a function of one of its modules (test_package_deps checks what it
imports against its package.xml)."""

from __future__ import annotations

import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SRC = ROOT / 'ros2_ws' / 'src'
PACKAGES = sorted(p for p in SRC.glob('swarm_*') if (p / 'setup.py').is_file())


def _console_scripts(setup_py: pathlib.Path) -> list[str]:
    """The ``name = module:function`` strings of setup.py's console_scripts."""
    for node in ast.walk(ast.parse(setup_py.read_text(encoding='utf-8'))):
        if isinstance(node, ast.Dict):
            for key, value in zip(node.keys, node.values):
                if isinstance(key, ast.Constant) and key.value == 'console_scripts':
                    return [ast.literal_eval(e) for e in value.elts]
    return []


def test_the_evaluation_package_is_in_the_workspace():
    assert 'swarm_eval' in {p.name for p in PACKAGES}


@pytest.mark.parametrize('package', PACKAGES, ids=lambda p: p.name)
def test_console_scripts_name_existing_functions(package: pathlib.Path):
    for spec in _console_scripts(package / 'setup.py'):
        name, _, target = (s.strip() for s in spec.partition('='))
        module, _, function = target.partition(':')
        path = package.joinpath(*module.split('.')).with_suffix('.py')
        assert path.is_file(), f'{package.name}: console script {name} names {module}'
        tree = ast.parse(path.read_text(encoding='utf-8'))
        assert function in {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}, (
            f'{package.name}: console script {name}: {module} has no {function}()')


def test_the_checks_can_fail(tmp_path):
    """A console script of a missing function is found."""
    setup_py = tmp_path / 'setup.py'
    setup_py.write_text("setup(entry_points={'console_scripts': ['x = pkg.mod:main']})\n")
    assert _console_scripts(setup_py) == ['x = pkg.mod:main']


@pytest.mark.parametrize('path', sorted([*ROOT.glob('scripts/*.py'),
                                         *ROOT.glob('benchmarks/*.py')]),
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_scripts_are_at_most_thin_wrappers(path: pathlib.Path):
    """Library code lives in the packages (issue 22): a file of scripts/ or benchmarks/
    is at most 150 lines."""
    lines = len(path.read_text(encoding='utf-8').splitlines())
    assert lines <= 150, f'{path.relative_to(ROOT)}: {lines} lines; move its code to a package'


@pytest.mark.parametrize('package', PACKAGES, ids=lambda p: p.name)
def test_modules_are_at_most_600_lines(package: pathlib.Path):
    """Short modules named for what they do (issue 22)."""
    long = {str(p.relative_to(ROOT)): n for p in package.rglob('*.py')
            if (n := len(p.read_text(encoding='utf-8').splitlines())) > 600}
    assert not long, f'modules over 600 lines: {long}; split them by what they do'
