#!/usr/bin/env python3
"""Repair the CMake files of the ROS 2 Jazzy PyPI wheels inside a venv.

The wheels were built in a manylinux container; their exported CMake targets name the
include directories of that container (``/opt/python/cp311-cp311/include/python3.11``
and its numpy include directory). Those paths do not exist here, so CMake refuses to
configure any package that links the generated Python type support. This rewrites
them, in the venv's own ``share/**/cmake`` files only, to this interpreter's Python
and numpy include directories. Idempotent; touches nothing outside the venv.
"""

from __future__ import annotations

import pathlib
import sys
import sysconfig

BUILD_PREFIX = '/opt/python/cp311-cp311'
BUILD_NUMPY = BUILD_PREFIX + '/lib/python3.11/site-packages/numpy/_core/include'
BUILD_PYTHON = BUILD_PREFIX + '/include/python3.11'


def main(venv: str) -> int:
    """Rewrite the container include paths below ``venv/share``; print how many files."""
    import numpy

    root = pathlib.Path(venv).resolve()
    replacements = [
        (BUILD_NUMPY, numpy.get_include()),
        (BUILD_PYTHON, sysconfig.get_paths()['include']),
    ]
    changed = 0
    for path in (root / 'share').glob('**/cmake/*.cmake'):
        text = path.read_text(encoding='utf-8', errors='surrogateescape')
        new = text
        for old, repl in replacements:
            new = new.replace(old, repl)
        if new != text:
            path.write_text(new, encoding='utf-8', errors='surrogateescape')
            changed += 1
    print(f'fix_wheel_cmake: rewrote {changed} CMake files under {root / "share"}')
    return 0


if __name__ == '__main__':
    if len(sys.argv) != 2:
        sys.exit('usage: fix_wheel_cmake.py VENV_DIR')
    sys.exit(main(sys.argv[1]))
