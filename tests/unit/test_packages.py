"""The layout of ros2_ws/src: every console script of a package's setup.cfg is a function
of one of its modules; each package imports only the packages below it in the layering
and no package imports another's node module (test_package_deps checks what it imports
against its package.xml)."""

from __future__ import annotations

import ast
import configparser
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SRC = ROOT / 'ros2_ws' / 'src'
PACKAGES = sorted(p for p in SRC.glob('swarm_*') if (p / 'setup.py').is_file())


# The Python packages from the bottom layer up: each may import only those before it.
LAYERS = ['swarm_common', 'swarm_mission', 'swarm_agent', 'swarm_sim', 'swarm_bridge',
          'swarm_bringup', 'swarm_eval']


def _console_scripts(setup_cfg: pathlib.Path) -> list[str]:
    """The ``name = module:function`` lines of setup.cfg's console_scripts."""
    config = configparser.ConfigParser()
    config.read(setup_cfg, encoding='utf-8')
    text = config.get('options.entry_points', 'console_scripts', fallback='')
    return [line.strip() for line in text.splitlines() if line.strip()]


def _imported_modules(path: pathlib.Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'), filename=str(path))):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.add(node.module)
            names.update(f'{node.module}.{a.name}' for a in node.names)
    return names


def _is_node_module(name: str) -> bool:
    """``name`` (a.b.c) is a module file ``*_node.py`` of a package of ros2_ws/src."""
    parts = name.split('.')
    path = SRC.joinpath(parts[0], *parts).with_suffix('.py')
    return path.name.endswith('_node.py') and path.is_file()


def _module_files(package: pathlib.Path) -> list[pathlib.Path]:
    return sorted((package / package.name).rglob('*.py'))


def test_the_evaluation_package_is_in_the_workspace():
    assert 'swarm_eval' in {p.name for p in PACKAGES}


@pytest.mark.parametrize('package', PACKAGES, ids=lambda p: p.name)
def test_console_scripts_name_existing_functions(package: pathlib.Path):
    for spec in _console_scripts(package / 'setup.cfg'):
        name, _, target = (s.strip() for s in spec.partition('='))
        module, _, function = target.partition(':')
        path = package.joinpath(*module.split('.')).with_suffix('.py')
        assert path.is_file(), f'{package.name}: console script {name} names {module}'
        tree = ast.parse(path.read_text(encoding='utf-8'))
        assert function in {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}, (
            f'{package.name}: console script {name}: {module} has no {function}()')


def test_the_checks_can_fail(tmp_path):
    """A console script is read from setup.cfg; an import of a node module is seen."""
    setup_cfg = tmp_path / 'setup.cfg'
    setup_cfg.write_text('[options.entry_points]\nconsole_scripts =\n    x = pkg.mod:main\n')
    assert _console_scripts(setup_cfg) == ['x = pkg.mod:main']
    user = tmp_path / 'user.py'
    user.write_text('from swarm_agent import agent_node\nfrom swarm_sim.sim_node import X\n')
    assert {'swarm_agent.agent_node', 'swarm_sim.sim_node'} <= _imported_modules(user)
    assert _is_node_module('swarm_agent.agent_node')
    assert not _is_node_module('swarm_common.ros_support.run_node')


def test_every_package_has_its_layer():
    assert sorted(LAYERS) == [p.name for p in PACKAGES]


@pytest.mark.parametrize('package', PACKAGES, ids=lambda p: p.name)
def test_packages_import_only_the_layers_below(package: pathlib.Path):
    """swarm_common is the base; swarm_mission only plans; nothing imports upwards."""
    allowed = set(LAYERS[:LAYERS.index(package.name) + 1])
    upward = {f'{path.relative_to(ROOT)}: {name}' for path in _module_files(package)
              for name in _imported_modules(path)
              if name.startswith('swarm_') and name.split('.')[0] in LAYERS
              and name.split('.')[0] not in allowed}
    assert not upward, f'{package.name} imports packages above it: {sorted(upward)}'


@pytest.mark.parametrize('package', PACKAGES, ids=lambda p: p.name)
def test_no_package_imports_another_packages_node_module(package: pathlib.Path):
    """Shared ROS code lives in swarm_common.ros_support, never in a node module."""
    foreign = {f'{path.relative_to(ROOT)}: {name}' for path in _module_files(package)
               for name in _imported_modules(path)
               if name.split('.')[0] in LAYERS and name.split('.')[0] != package.name
               and _is_node_module(name)}
    assert not foreign, f'{package.name} imports node modules of other packages: {foreign}'


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
