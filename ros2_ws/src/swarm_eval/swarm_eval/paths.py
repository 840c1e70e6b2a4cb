"""Where the repository is: the launcher, benchmark scripts and docs/ live in it."""

from __future__ import annotations

import pathlib


def repo_root() -> pathlib.Path:
    """The checkout holding this package (the first parent with ``scripts/env.sh``; a
    symlinked or installed build resolves to its source), else the working directory."""
    here = pathlib.Path(__file__).resolve()
    for parent in here.parents:
        if (parent / 'scripts' / 'env.sh').is_file():
            return parent
    return pathlib.Path.cwd()
