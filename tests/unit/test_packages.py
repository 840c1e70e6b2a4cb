"""Every ament_python package of ros2_ws/src declares what it imports and runs what it
names: the swarm_* packages its modules import are <exec_depend>s of its package.xml, and
each console script of its setup.py is a function of one of its modules."""

from __future__ import annotations

import ast
import pathlib
import xml.etree.ElementTree as ET

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SRC = ROOT / 'ros2_ws' / 'src'
PACKAGES = sorted(p for p in SRC.glob('swarm_*') if (p / 'setup.py').is_file())


def _imported_packages(path: pathlib.Path) -> set[str]:
    """Top-level names of the swarm_* packages ``path`` imports."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'), filename=str(path))):
        if isinstance(node, ast.Import):
            names.update(a.name.split('.')[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.add(node.module.split('.')[0])
    return {n for n in names if n.startswith('swarm_')}


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
def test_imported_packages_are_declared(package: pathlib.Path):
    declared = {e.text.strip() for e in ET.parse(package / 'package.xml').getroot()
                if e.tag in ('exec_depend', 'depend') and e.text}
    used = {name: path for path in (package / package.name).rglob('*.py')
            for name in _imported_packages(path)}
    missing = {n: str(p.relative_to(ROOT)) for n, p in used.items()
               if n != package.name and n not in declared}
    assert not missing, f'{package.name}/package.xml lacks <exec_depend> of {missing}'


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
    """An undeclared import and a console script of a missing function are found."""
    module = tmp_path / 'mod.py'
    module.write_text('from swarm_sim.medium import RadioMedium\nimport numpy\n')
    assert _imported_packages(module) == {'swarm_sim'}
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
