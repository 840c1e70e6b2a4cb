"""sim_node's run record on disk: what the launcher's report computes its metrics from.

In ``record_dir``: ``truth.csv`` (``t,id,x,y,vx,vy,alive`` at every truth sample of the
world model), and when the run closes ``medium.json`` (the radio medium's counters) and
``separation.json`` (``SeparationTracker.result`` over every physics step, the body
contacts of the backend, None for point masses, and the minimum of each sample
interval as ``series``).
"""

from __future__ import annotations

import json
import pathlib

from swarm_sim.world_model import TruthSample, World


class RunRecord:
    """Writes one run's record into ``folder``; see the module docstring."""

    def __init__(self, folder: str, ids: list[int]) -> None:
        self.folder = pathlib.Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.ids = ids
        self._csv = open(self.folder / 'truth.csv', 'w', encoding='utf-8')  # noqa: SIM115
        self._csv.write('t,id,x,y,vx,vy,alive\n')
        self._times: list[float] = []
        self._mins: list[float] = []

    def add(self, truth: TruthSample) -> None:
        """One truth sample."""
        pos, vel = truth.positions, truth.velocities
        self._csv.write(''.join(
            f'{truth.t:.3f},{agent},{pos[i, 0]:.4f},{pos[i, 1]:.4f},{vel[i, 0]:.4f},'
            f'{vel[i, 1]:.4f},{int(truth.alive[i])}\n' for i, agent in enumerate(self.ids)))
        self._times.append(truth.t)
        self._mins.append(truth.min_separation)

    def close(self, world: World) -> None:
        """Flush the CSV and write the medium's counters and the separation summary."""
        if self._csv.closed:
            return
        self._csv.close()
        (self.folder / 'medium.json').write_text(
            json.dumps(vars(world.medium.stats), indent=2), encoding='utf-8')
        (self.folder / 'separation.json').write_text(json.dumps(
            {**world.separation.result(), 'body_contacts': world.backend.body_contacts,
             'series': {'times': self._times, 'min': self._mins}}), encoding='utf-8')
