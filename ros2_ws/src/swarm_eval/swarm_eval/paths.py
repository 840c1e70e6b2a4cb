"""Where the repository is: the launcher, benchmark scripts and docs/ live in it."""

from __future__ import annotations

import json
import pathlib
from typing import Any


def repo_root() -> pathlib.Path:
    """The checkout holding this package (the first parent with ``scripts/env.sh``; a
    symlinked or installed build resolves to its source), else the working directory."""
    here = pathlib.Path(__file__).resolve()
    for parent in here.parents:
        if (parent / 'scripts' / 'env.sh').is_file():
            return parent
    return pathlib.Path.cwd()


def write_json(directory: str | pathlib.Path, name: str, data: Any) -> pathlib.Path:
    """Write ``data`` as indented JSON to ``directory/name`` (the directory is made)."""
    out = pathlib.Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    path = out / name
    path.write_text(json.dumps(data, indent=1) + '\n', encoding='utf-8')
    return path
