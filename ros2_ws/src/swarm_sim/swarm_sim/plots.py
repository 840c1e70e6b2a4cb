"""Figures of a run (thesis Figs. 4.4-4.6, 4.17-4.34), shared by the evaluator and launcher.

Every function takes plain arrays, writes one PNG with the Agg backend and returns its
path. Colours: robot types 1/2/3 red/orange/purple; shape blue; obstacles green.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import pathlib
import warnings

import matplotlib

matplotlib.use('Agg')
from matplotlib.patches import Circle  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.spatial import Delaunay  # noqa: E402

from swarm_common.robot_types import TYPE_COLOURS  # noqa: E402

MODE_NAMES = {0: 'NORMAL', 1: 'LOST', 2: 'RETURN_HOME'}


def _draw_shape(ax, shape, colour: str = 'tab:blue', lw: float = 1.2) -> None:
    x, y = shape.region.exterior.xy
    ax.plot(x, y, color=colour, lw=lw)
    for hole in shape.region.interiors:
        hx, hy = hole.xy
        ax.plot(hx, hy, color=colour, lw=lw)
    for o in shape.obstacles:
        ox, oy = o.exterior.xy
        ax.fill(ox, oy, color='tab:green', alpha=0.5)


def trajectories(path: pathlib.Path, times: np.ndarray, positions: np.ndarray,
                 types: Sequence[int], shapes: Sequence, goals: Sequence = (),
                 title: str = '') -> pathlib.Path:
    """True trajectories (Figs. 4.23-4.25) with every shape of the run and final goals."""
    fig, ax = plt.subplots(figsize=(7, 7))
    for k, shape in enumerate(shapes):
        _draw_shape(ax, shape, colour='tab:blue' if k == len(shapes) - 1 else 'lightsteelblue')
    for i in range(positions.shape[1]):
        c = TYPE_COLOURS.get(int(types[i]), 'k')
        ax.plot(positions[:, i, 0], positions[:, i, 1], color=c, lw=0.6, alpha=0.7)
        last = positions[~np.isnan(positions[:, i, 0]), i]
        if len(last):
            ax.plot(*last[-1], 'o', color=c, ms=3)
    for g in goals:
        ax.add_patch(Circle((g.x, g.y), g.radius, fill=False, color='k', lw=0.4))
    ax.set_aspect('equal')
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    ax.set_title(title or f'trajectories over {times[-1]:.0f} s')
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def mesh(path: pathlib.Path, points: np.ndarray, types: Sequence[int],
         radii: Mapping[int, float], shape, eps_t: float, eps_g: float,
         title: str = '') -> pathlib.Path:
    """Final positions as coverage circles with their Delaunay edges (Figs. 4.11-4.16)."""
    fig, ax = plt.subplots(figsize=(7, 7))
    _draw_shape(ax, shape)
    if len(points) >= 3:
        tri = Delaunay(points)
        ax.triplot(points[:, 0], points[:, 1], tri.simplices, color='0.7', lw=0.5)
    for p, t in zip(points, types):
        ax.add_patch(Circle(p, radii[int(t)], color=TYPE_COLOURS.get(int(t), 'k'), alpha=0.6))
    ax.set_aspect('equal')
    ax.autoscale_view()
    ax.set_title(title or f'final mesh: eps_t = {eps_t:.2f}, eps_g = {eps_g:.2f}')
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def localization_error(path: pathlib.Path, times: np.ndarray, errors: np.ndarray,
                       title: str = 'localization error') -> pathlib.Path:
    """Error norm of every non-beacon agent over time, with the swarm maximum (Figs. 4.4-4.6).
    ``errors`` (samples, agents) may have no agents (every robot a beacon): empty axes."""
    fig, ax = plt.subplots(figsize=(8, 3.5))
    if np.shape(errors)[1]:
        ax.plot(times, errors, color='0.6', lw=0.4)
        with warnings.catch_warnings():
            # Before any agent reports, a row is all NaN: nanmax warns and gives NaN (no line).
            warnings.simplefilter('ignore', RuntimeWarning)
            ax.plot(times, np.nanmax(errors, axis=1), color='tab:red', lw=1.2, label='max')
        ax.legend()
    else:
        title = f'{title}: no agent localizes (every robot is a beacon)'
    ax.set_xlabel('t [s]')
    ax.set_ylabel('|estimate - truth| [m]')
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def modes(path: pathlib.Path, times: np.ndarray, mode_matrix: np.ndarray) -> pathlib.Path:
    """Number of agents in each localization mode over time (3.1.3)."""
    fig, ax = plt.subplots(figsize=(8, 3))
    for value, name in MODE_NAMES.items():
        ax.plot(times, (mode_matrix == value).sum(axis=1), label=name)
    ax.set_xlabel('t [s]')
    ax.set_ylabel('agents')
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def boxplots(path: pathlib.Path, groups: Mapping[str, Sequence[Mapping]],
             keys: Sequence[tuple[str, str]]) -> pathlib.Path:
    """Box plots of trial metrics per method (Figs. 4.17-4.20, 4.26, 4.33-4.34)."""
    fig, axes = plt.subplots(1, len(keys), figsize=(3.6 * len(keys), 3.6))
    for ax, (key, label) in zip(np.atleast_1d(axes), keys):
        data = [[t[key] for t in trials if t.get(key) is not None] or [np.nan]
                for trials in groups.values()]
        ax.boxplot(data, tick_labels=list(groups))
        ax.set_title(label)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
