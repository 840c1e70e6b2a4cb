"""Run records on disk, written as the run goes: a killed run leaves all but its last
few seconds.

``RunRecord`` is sim_node's record. In ``record_dir``: ``truth.csv``
(``t,id,x,y,vx,vy,alive`` at every truth sample of the world model, flushed to the file
at least every ``flush_period_s`` wall seconds), and when the run closes ``medium.json``
(the radio medium's counters) and ``separation.json`` (``SeparationTracker.result`` over
every physics step, the body contacts of the backend, None for point masses, and the
minimum of each sample interval as ``series``). ``read_truth_csv`` reads it back, also
from a run that never closed (then it says so in one warning line).

``RecordLog`` is a headless trial's record (``swarm_eval.trials``): JSON lines, a
``{"header": ...}`` line (``dtypes``: the numpy type of each field), one
``{"row": ...}`` line per truth sample (the arrays of ``swarm_sim.headless.TrialRecord``
at that sample, floats rounded to 0.1 mm, and the wall time ``wall`` it was written),
flushed at least every ``flush_period_s``, and an ``{"end": ...}`` line when the trial
ends (its metrics). ``read_record_log`` reads it
back as arrays; a log without its end line (its writer was killed) gives the partial
run and one warning line saying where it was cut. NaN and infinities are written as
Python's json writes them (``NaN``, ``Infinity``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
import json
import logging
import pathlib
import time
from typing import Any, TextIO

import numpy as np

from swarm_sim.world_model import TruthSample, World

FLUSH_PERIOD_S = 2.0   # wall seconds: the most a killed run loses of its record
DECIMALS = 4           # of the floats of a RecordLog row (0.1 mm, as truth.csv)
TRUTH_COLUMNS = ('t', 'id', 'x', 'y', 'vx', 'vy', 'alive')
_log = logging.getLogger(__name__)


class RecordError(ValueError):
    """A record file that cannot be read at all: one line naming it and why."""


class _Flusher:
    """Flushes a text file to the OS when ``period_s`` wall seconds have passed since
    the last flush (the OS keeps what was flushed when the process is killed)."""

    def __init__(self, file: TextIO, period_s: float,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not period_s > 0.0:
            raise ValueError(f'flush period {period_s!r} s: give a period > 0 s, e.g. '
                             f'{FLUSH_PERIOD_S:g}')
        self.file, self.period_s, self._clock = file, float(period_s), clock
        self._last = clock()

    def __call__(self, force: bool = False) -> bool:
        if not force and self._clock() - self._last < self.period_s:
            return False
        self.file.flush()
        self._last = self._clock()
        return True


class RunRecord:
    """Writes one run's record into ``folder``; see the module docstring."""

    def __init__(self, folder: str, ids: list[int],
                 flush_period_s: float = FLUSH_PERIOD_S) -> None:
        self.folder = pathlib.Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.ids = ids
        self._csv = open(self.folder / 'truth.csv', 'w', encoding='utf-8')  # noqa: SIM115
        self._csv.write(','.join(TRUTH_COLUMNS) + '\n')
        self.flush_if_due = _Flusher(self._csv, flush_period_s)
        self.flush_if_due(force=True)
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
        self.flush_if_due()

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


def _complete_lines(path: pathlib.Path) -> tuple[list[str], bool]:
    """The lines of a text file that end with a newline, and whether a partial last line
    (a write cut by a kill) was dropped. RecordError if it cannot be read."""
    try:
        text = path.read_text(encoding='utf-8', errors='replace')
    except OSError as exc:
        raise RecordError(f'cannot read the run record {path}: {exc.strerror}') from None
    lines = text.split('\n')
    return lines[:-1], bool(lines[-1])


def read_truth_csv(folder: str | pathlib.Path) -> dict[str, Any]:
    """sim_node's ``truth.csv`` in ``folder`` as arrays: ``times`` (T,), ``ids`` (N,),
    ``positions``/``velocities`` (T, N, 2), ``alive`` (T, N), and ``cut``: the run never
    closed its record (no ``medium.json``), its partial last sample dropped, with one
    warning line. RecordError if there is no record to read."""
    folder = pathlib.Path(folder)
    path = folder / 'truth.csv'
    lines, partial = _complete_lines(path)
    if not lines or tuple(lines[0].split(',')) != TRUTH_COLUMNS:
        raise RecordError(f'{path} is not a truth record (header {",".join(TRUTH_COLUMNS)})')
    try:
        rows = np.array([[float(v) for v in line.split(',')] for line in lines[1:]],
                        dtype=float).reshape(-1, len(TRUTH_COLUMNS))
    except ValueError:
        raise RecordError(f'{path}: a line is not {len(TRUTH_COLUMNS)} numbers') from None
    ids = np.unique(rows[:, 1]).astype(int)
    whole = len(rows) // len(ids) * len(ids) if len(ids) else 0
    partial = partial or whole < len(rows)
    frames = rows[:whole].reshape(-1, len(ids), len(TRUTH_COLUMNS))
    cut = partial or not (folder / 'medium.json').exists()
    times = frames[:, 0, 0]
    if cut:
        _log.warning('%s was cut (its run never closed it): %d samples up to t=%.1f s '
                     'read%s', path, len(times), times[-1] if len(times) else 0.0,
                     ', a partial last sample dropped' if partial else '')
    return {'times': times, 'ids': ids, 'positions': frames[:, :, 2:4],
            'velocities': frames[:, :, 4:6], 'alive': frames[:, :, 6] > 0.5, 'cut': cut}


def _plain(value: Any) -> Any:
    """numpy data as JSON-able Python (floats of arrays rounded to DECIMALS)."""
    if isinstance(value, np.ndarray):
        if value.dtype.kind == 'f':
            value = np.round(value, DECIMALS)
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


class RecordLog:
    """A record written as JSON lines as the run goes; see the module docstring."""

    def __init__(self, path: str | pathlib.Path, header: Mapping[str, Any],
                 flush_period_s: float = FLUSH_PERIOD_S) -> None:
        self.path = pathlib.Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, 'w', encoding='utf-8')  # noqa: SIM115
        self.flush_if_due = _Flusher(self._file, flush_period_s)
        self._write({'header': dict(header)})
        self.flush_if_due(force=True)
        self.rows = 0

    def _write(self, line: Mapping[str, Any]) -> None:
        self._file.write(json.dumps(line, default=_plain) + '\n')

    def add(self, row: Mapping[str, Any]) -> None:
        """One sample of the record (name -> number or array); flushed when due."""
        self._write({'row': {**row, 'wall': time.time()}})
        self.rows += 1
        self.flush_if_due()

    def close(self, end: Mapping[str, Any] | None = None) -> None:
        """Write the end line (``end``: e.g. the run's metrics) and close. Idempotent."""
        if self._file.closed:
            return
        self._write({'end': dict(end or {})})
        self._file.close()

    def __enter__(self) -> RecordLog:
        return self

    def __exit__(self, *exc: object) -> None:
        if not self._file.closed:   # an exception: leave the log without its end line
            self._file.close()


@dataclass
class LoggedRun:
    """What ``read_record_log`` read: the header, the rows as arrays (name -> (T, ...)),
    the end line (None: the log was cut) and the number of rows."""

    header: dict
    record: dict[str, np.ndarray]
    end: dict | None
    rows: int

    @property
    def cut(self) -> bool:
        return self.end is None


def read_record_log(path: str | pathlib.Path) -> LoggedRun:
    """A ``RecordLog`` file read back; a cut one (no end line, a partial last line)
    gives the rows written before the cut and one warning line. RecordError if the file
    cannot be read or has no header."""
    path = pathlib.Path(path)
    lines, partial = _complete_lines(path)
    entries = []
    for number, line in enumerate(lines, start=1):
        try:
            entries.append(json.loads(line))
        except ValueError:
            raise RecordError(f'{path}: line {number} is not JSON') from None
    if not entries or not isinstance(entries[0], dict) or 'header' not in entries[0]:
        raise RecordError(f'{path} is not a record log (no header line)')
    rows = [e['row'] for e in entries[1:] if isinstance(e, dict) and 'row' in e]
    end = next((e['end'] for e in entries[1:] if isinstance(e, dict) and 'end' in e), None)
    dtypes = entries[0]['header'].get('dtypes', {})
    try:
        record = {name: np.array([r[name] for r in rows], dtype=dtypes.get(name, float))
                  for name in (rows[0] if rows else {})}
    except (KeyError, TypeError, ValueError) as exc:
        raise RecordError(f'{path}: the rows do not hold the same fields ({exc})') from None
    if end is None:
        times = record.get('times', np.zeros(0))
        _log.warning('%s was cut (its writer was killed): %d samples up to t=%.1f s read%s',
                     path, len(rows), times[-1] if len(times) else 0.0,
                     ', a partial last line dropped' if partial else '')
    return LoggedRun(entries[0]['header'], record, end, len(rows))
