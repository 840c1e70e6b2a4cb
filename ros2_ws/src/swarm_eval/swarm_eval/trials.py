"""Where the evaluator's trials run: local worker processes or a Dask cluster.

A trial depends only on its seed, so both give the same per-trial metrics for the same
seeds (only the wall-clock figures differ). Workers of a remote cluster need the swarm_*
packages importable (the same environment).

With a ``record_dir`` each trial writes its record as it runs into
``record_dir/trial_SEED.jsonl`` (``swarm_sim.run_record.RecordLog``: flushed at least
every ``flush_period_s`` wall seconds, so a killed evaluator leaves every trial's record
but its last seconds; on a Dask cluster, on the worker's host).
"""

from __future__ import annotations

from collections.abc import Iterator
import concurrent.futures as futures
import contextlib
import dataclasses
import pathlib

from swarm_eval.scenario import build_scenario, run_trial, ScenarioSpec
from swarm_sim.headless import HeadlessSwarm, TrialRecord
from swarm_sim.run_record import FLUSH_PERIOD_S, RecordLog

# The numpy type of each field of a trial's record rows (swarm_sim.headless._record).
ROW_DTYPES = {'times': 'float64', 'positions': 'float64', 'velocities': 'float64',
              'estimates': 'float64', 'modes': 'int64', 'alive': 'bool',
              'goal_ids': 'int64', 'digests': 'int64', 'localized': 'bool',
              'min_separation': 'float64', 'wall': 'float64'}


class DaskError(RuntimeError):
    """The Dask cluster cannot be used: one line saying why and what to do."""


def record_path(record_dir: str | pathlib.Path, seed: int) -> pathlib.Path:
    """Where the trial of ``seed`` writes its record."""
    return pathlib.Path(record_dir) / f'trial_{seed}.jsonl'


def recorded_trial(spec: ScenarioSpec, seed: int, record_dir: str = '',
                   flush_period_s: float = FLUSH_PERIOD_S) -> TrialRecord:
    """``run_trial``, its record written as it runs into ``record_path(record_dir,
    seed)`` when ``record_dir`` is given (the end line carries the trial's metrics)."""
    if not record_dir:
        return run_trial(spec, seed)
    swarm = HeadlessSwarm(build_scenario(spec, seed))
    header = {'seed': seed, 'agent_ids': swarm.ids, 'types': swarm.robot_types,
              'beacons': swarm.is_beacon, 'scenario': dataclasses.asdict(spec),
              'dtypes': ROW_DTYPES}
    with RecordLog(record_path(record_dir, seed), header, flush_period_s) as log:
        record = swarm.run(sink=log.add)
        record.metrics['seed'] = seed
        log.close({'metrics': record.metrics, 'events': record.events})
    return record


def local_trials(spec: ScenarioSpec, seeds: list[int], workers: int, record_dir: str = '',
                 flush_period_s: float = FLUSH_PERIOD_S) -> Iterator[TrialRecord]:
    """Records of ``seeds`` from ``workers`` local processes, in completion order."""
    with futures.ProcessPoolExecutor(max_workers=workers) as pool:
        jobs = [pool.submit(recorded_trial, spec, s, record_dir, flush_period_s)
                for s in seeds]
        for job in futures.as_completed(jobs):
            yield job.result()


@contextlib.contextmanager
def dask_client(address: str, workers: int) -> Iterator[object]:
    """A connected ``dask.distributed.Client``, closed (with its LocalCluster) on exit.

    ``local`` starts a LocalCluster of ``workers`` processes with one thread each and no
    dashboard; any other value is a scheduler address. Raises DaskError, one line.
    """
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise DaskError("--dask needs dask.distributed; install it with: scripts/env.sh pip "
                        "install 'dask[distributed]' (or make bootstrap)") from None
    cluster = None
    try:
        if address == 'local':
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None)
            client = Client(cluster)
        else:
            client = Client(address, timeout='10s')
    except (OSError, TimeoutError, ValueError) as exc:
        if cluster is not None:
            cluster.close()
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise DaskError(f'cannot use the Dask scheduler {address!r} ({first}); give '
                        "tcp://HOST:PORT of a running dask scheduler or 'local'") from None
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def dask_trials(client, spec: ScenarioSpec, seeds: list[int], record_dir: str = '',
                flush_period_s: float = FLUSH_PERIOD_S) -> Iterator[TrialRecord]:
    """Records of ``seeds`` computed on the cluster of ``client``, in completion order."""
    from dask.distributed import as_completed

    jobs = client.map(recorded_trial, [spec] * len(seeds), seeds,
                      [record_dir] * len(seeds), [flush_period_s] * len(seeds), pure=False)
    for job in as_completed(jobs):
        yield job.result()
