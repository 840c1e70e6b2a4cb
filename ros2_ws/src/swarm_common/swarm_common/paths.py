"""Where a package's shipped files are: its source tree, else its install share folder."""

from __future__ import annotations

import pathlib

SRC = pathlib.Path(__file__).resolve().parents[2]   # ros2_ws/src of the source tree


def package_file(package: str, relative: str) -> pathlib.Path:
    """Path of ``relative`` (e.g. ``config/fleet.yaml``) in ``package``.

    The source tree's copy when there is one (a symlink install resolves to it), else the
    ament share folder of an installed package; the source path when neither is found,
    so that the error that follows names a real place to look.
    """
    local = SRC / package / relative
    if local.exists():
        return local
    try:
        from ament_index_python.packages import get_package_share_directory
        return pathlib.Path(get_package_share_directory(package)) / relative
    except (ImportError, LookupError):
        return local
