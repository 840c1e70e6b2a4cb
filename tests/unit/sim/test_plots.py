"""Run figures (swarm_sim.plots) for runs a user can start: they are written, never raise."""

from __future__ import annotations

import numpy as np

from swarm_sim import plots


def test_localization_error_of_a_swarm_of_beacons_is_an_empty_figure(tmp_path):
    """`launch_swarm.py --agents 3 --beacons 3`: no agent localizes, so no error column;
    the report ended in a traceback (nanmax of zero columns) after a successful run."""
    times = np.arange(4) * 0.5
    path = plots.localization_error(tmp_path / 'none.png', times, np.zeros((4, 0)))
    assert path.stat().st_size > 0
    # Before any agent reports every row is NaN; with agents it draws their maximum.
    errors = np.full((4, 2), np.nan)
    errors[2:] = [[0.3, 0.5], [0.2, 0.4]]
    assert plots.localization_error(tmp_path / 'some.png', times, errors).stat().st_size > 0
