"""swarm_common.jit: one Python source per kernel, compiled where numba can, the same
source where it cannot; and the collision filter, the first kernel, both ways."""

from __future__ import annotations

import logging
import os
import pathlib
import subprocess
import sys

from hypothesis import given
from hypothesis import strategies as st
import numpy as np

from swarm_agent import setpoint
from swarm_common import jit


@jit.kernel(np.arange(3.0), 2.0)
def scaled_sum(values: np.ndarray, factor: float) -> float:
    total = 0.0
    for v in values:
        total += factor * v
    return total


@jit.kernel()
def untypable(x: float):
    return [x, 'b']              # a list of a number and a string: numba cannot type it


def test_numba_is_installed_and_kernels_run_compiled():
    """numba is a requirement (requirements/python.txt): the tests' 'compiled' runs
    really are compiled."""
    import numba
    assert jit.compiled()
    assert scaled_sum(np.arange(4.0), 0.5) == 3.0
    assert isinstance(scaled_sum.kernel.compiled, numba.core.registry.CPUDispatcher)
    assert scaled_sum.kernel.compiled.signatures, 'the call ran the compiled code'


def test_use_python_switches_every_kernel_to_its_source():
    jit.use_python(True)
    try:
        assert not jit.compiled()
        assert scaled_sum.kernel.run is scaled_sum.__wrapped__
        assert scaled_sum(np.arange(4.0), 0.5) == 3.0
    finally:
        jit.use_python(False)
    assert scaled_sum.kernel.run is scaled_sum.kernel.compiled


def test_a_kernel_that_cannot_compile_runs_its_source_after_one_warning(caplog):
    with caplog.at_level(logging.WARNING, logger='swarm_common.jit'):
        assert untypable(2.0) == [2.0, 'b']
        assert untypable(3.0) == [3.0, 'b']
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1 and 'untypable runs as Python' in lines[0], lines
    assert '\n' not in lines[0]


def test_warm_compiles_the_registered_kernels_on_their_examples():
    assert jit.warm() >= 2          # this module's scaled_sum and the collision filter
    assert setpoint._avoid.kernel.compiled.signatures


def _run(code: str, **env: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120, env={**os.environ, 'PYTHONPATH': os.pathsep.join(
                              sys.path), **env})


FILTER = ('import numpy as np; from swarm_agent.setpoint import avoid_collisions, '
          'SetpointParams; from swarm_common import jit; '
          'v = avoid_collisions(np.array([0.5, 0.0]), [[1.0, 0.0]], [0.3], 0.3, '
          'SetpointParams()); print(jit.compiled(), "numba" in sys.modules, '
          'round(float(v[0]), 6), round(float(v[1]), 6))')


def test_swarm_jit_0_runs_the_source_without_importing_numba():
    done = _run('import sys; ' + FILTER, SWARM_JIT='0')
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[:2] == ['False', 'False']
    assert done.stderr == ''


def test_a_missing_numba_gives_one_warning_line_and_the_same_filter():
    """Without numba (import blocked) the filter runs as Python with one line that says
    how to install it; it gives what the compiled filter gives."""
    blocked = _run("import sys; sys.modules['numba'] = None; " + FILTER)
    compiled = _run('import sys; ' + FILTER)
    assert blocked.returncode == 0 and compiled.returncode == 0, blocked.stderr
    assert blocked.stdout.split()[0] == 'False' and compiled.stdout.split()[0] == 'True'
    assert blocked.stdout.split()[2:] == compiled.stdout.split()[2:]
    lines = blocked.stderr.strip().splitlines()
    assert len(lines) == 1 and 'pip install numba' in lines[0], blocked.stderr


finite = st.floats(-2.0, 2.0, allow_nan=False)


@given(v=st.tuples(finite, finite), offsets=st.lists(st.tuples(finite, finite), max_size=8),
       radius=st.floats(0.05, 0.6), lag=st.sampled_from([0.0, 0.6]),
       parked=st.booleans(), swerve=st.sampled_from([0.0, 0.5, 1.0]))
def test_the_compiled_filter_gives_what_its_source_gives(v, offsets, radius, lag, parked,
                                                         swerve):
    """Same rules, same order of floating-point operations: the compiled filter and its
    Python source agree to rounding on any neighbourhood (degenerate ones included:
    neighbours on top of the robot, opposite constraints that box it in)."""
    params = setpoint.SetpointParams(swerve=swerve, yield_margin=0.1)
    offsets = np.array(offsets, dtype=float).reshape(-1, 2)
    radii = np.full(len(offsets), radius)
    own = np.array([0.3, -0.2])
    args = (np.array(v), offsets, radii, radius)
    kwargs = dict(parked=parked, own_velocity=own, lag_s=lag)
    compiled = setpoint.avoid_collisions(*args, params, **kwargs)
    jit.use_python(True)
    try:
        python = setpoint.avoid_collisions(*args, params, **kwargs)
    finally:
        jit.use_python(False)
    np.testing.assert_allclose(compiled, python, rtol=1e-12, atol=1e-12)
    if np.hypot(*v) <= params.v_max:
        assert np.hypot(*compiled) <= params.v_max * (1 + 1e-12)


def test_warm_kernels_compiles_every_kernel_of_the_packages():
    """``make bootstrap``'s step (swarm_eval.warm_kernels), in a fresh process: it
    imports every module that defines a kernel and compiles each one, so no process of
    a fresh install compiles at its first call."""
    src = pathlib.Path(__file__).resolve().parents[2] / 'ros2_ws' / 'src'
    decorated = sum(p.read_text(encoding='utf-8').count('\n@kernel(')
                    for p in src.glob('swarm_*/swarm_*/**/*.py'))
    result = _run('import sys; from swarm_eval.warm_kernels import main; sys.exit(main())')
    assert result.returncode == 0, result.stderr
    assert f'warm_kernels: {decorated} of {decorated} kernels compiled' in result.stdout
    assert decorated >= 12
