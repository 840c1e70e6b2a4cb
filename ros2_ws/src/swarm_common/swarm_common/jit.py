"""Compiled kernels: one Python source, compiled by numba where it can be.

A kernel is a plain Python function of numbers and numpy arrays, written as loops (the
form numba compiles well and the form a reader checks against the thesis). ``kernel``
returns a function that runs it compiled by ``numba.njit`` (numba is imported at the
first call of a kernel, so a process that calls none does not load it; machine code is
cached on disk beside the source, so it is compiled once per machine) and, where numba
cannot be used, runs the same Python source:

- ``SWARM_JIT=0`` in the environment: the Python source, no numba import.
- numba not installed, or a kernel that fails to compile: the Python source, with one
  warning line naming the cause.

Kernels call each other's helpers (``helper``): plain Python when called from Python,
compiled into the calling kernel when called from a compiled one.

``use_python(True)`` switches every kernel of the process to its Python source, which is
how the tests run each kernel both ways and compare (the source stays the reference).
``warm()`` compiles (or loads from the cache) every kernel with the example arguments it
was registered with: a fork server calls it before forking, so its children share the
compiled code and numba's compiler instead of each loading its own (measured: about 6
MB more per forked agent in a 50-agent run, against 57 MB for a process that imports
numba itself; docs/throughput.md).

Why numba (issue 23): the brains apply small numeric rules to a handful of values many
times a second per robot. numpy costs microseconds per call on arrays of two to ten
elements, which is most of the work at those sizes; compiled loops cost tens of
nanoseconds. numba compiles the Python source itself, so there is no second
implementation of any rule.
"""

from __future__ import annotations

from collections.abc import Callable
import logging
import os
from typing import Any

LOG = logging.getLogger(__name__)
ENV = 'SWARM_JIT'

_kernels: list[_Kernel] = []
_helpers: list[Callable] = []
_registered = 0             # helpers registered with numba so far
_numba: Any = None          # the numba module once imported; False: not available
_python = False             # use_python(True): every kernel runs its Python source


def _load_numba() -> Any:
    global _numba
    if _numba is None:
        if os.environ.get(ENV, '1').strip().lower() in ('0', 'false', 'no', 'off'):
            _numba = False
        else:
            try:
                import numba
                _numba = numba
            except ImportError as exc:
                LOG.warning('swarm kernels run as Python (slower): numba cannot be imported '
                            '(%s); install it with `pip install numba`, or set %s=0 to '
                            'silence this', exc, ENV)
                _numba = False
    return _numba


class _Kernel:
    """One kernel: its Python source, its compiled form and what runs now (``run``: the
    first call imports numba and compiles, then the compiled code runs; a process that
    never calls a kernel never imports numba)."""

    def __init__(self, source: Callable, example: tuple) -> None:
        self.source = source
        self.example = example
        self.compiled: Any = None   # numba's dispatcher, once made
        self.failed = False         # numba unavailable or the compile failed: source runs
        self.ready = False          # compiled for the types it is called with
        self.run: Callable = self._current()

    def _current(self) -> Callable:
        if _python or self.failed:
            return self.source
        return self.compiled if self.ready else self._first

    def _first(self, *args: Any) -> Any:
        """Compile for the types of ``args``, then run; a failed compile (numba raises
        its own errors and, on some unsupported code, plain ones) runs the source."""
        numba = _load_numba()
        if not numba:
            self.failed = True
            self.run = self.source
            return self.source(*args)
        try:
            _register_helpers()
            if self.compiled is None:
                self.compiled = numba.njit(cache=True, nogil=True)(self.source)
            self.compiled.compile(tuple(numba.typeof(a) for a in args))
        except Exception as exc:  # noqa: BLE001 - any failure to compile means Python
            self._fall_back(exc)
            return self.source(*args)
        self.ready = True
        self.run = self._current()
        return self.compiled(*args)

    def _fall_back(self, exc: Exception) -> None:
        first = str(exc).strip().splitlines()
        LOG.warning('kernel %s.%s runs as Python (slower): numba could not compile it: '
                    '%s: %s', self.source.__module__, self.source.__qualname__,
                    type(exc).__name__, first[0] if first else '')
        self.failed = True
        self.run = self.source


def kernel(*example: Any) -> Callable[[Callable], Callable]:
    """Decorator: the function as a kernel (module docstring); ``example`` are arguments
    of the types it is called with, used by ``warm``."""
    def wrap(source: Callable) -> Callable:
        state = _Kernel(source, example)
        _kernels.append(state)

        def call(*args):
            return state.run(*args)

        call.__doc__, call.__name__ = source.__doc__, source.__name__
        call.__qualname__, call.__module__ = source.__qualname__, source.__module__
        call.__wrapped__ = source       # the Python source (inspect.unwrap, tests)
        call.kernel = state
        return call
    return wrap


def helper(source: Callable) -> Callable:
    """Decorator: a function kernels call. Called from Python it is the Python function
    itself; called from a compiled kernel it is compiled into it
    (``numba.extending.register_jitable``, done before the first kernel compiles)."""
    _helpers.append(source)
    return source


def _register_helpers() -> None:
    global _registered
    if _registered < len(_helpers):
        from numba.extending import register_jitable
        for source in _helpers[_registered:]:
            register_jitable(source)
        _registered = len(_helpers)


def use_python(python: bool) -> None:
    """Run every kernel as its Python source (True) or compiled where it can be."""
    global _python
    _python = bool(python)
    for state in _kernels:
        state.run = state._current()


def compiled() -> bool:
    """Whether kernels run compiled now (numba available and not switched off)."""
    return not _python and bool(_load_numba())


def registered() -> int:
    """How many kernels the imported modules registered."""
    return len(_kernels)


def warm() -> int:
    """Compile (or load from the cache) every kernel registered so far on its example
    arguments; returns how many run compiled."""
    for state in _kernels:
        if state.example and not state.ready and not state.failed:
            state._first(*state.example)
    return sum(state.ready for state in _kernels)
