"""Where the evaluator's trials run: local worker processes or a Dask cluster.

A trial depends only on its seed, so both give the same per-trial metrics for the same
seeds (only the wall-clock figures differ). Workers of a remote cluster need the swarm_*
packages importable (the same environment).
"""

from __future__ import annotations

from collections.abc import Iterator
import concurrent.futures as futures
import contextlib

from swarm_eval.scenario import run_trial, ScenarioSpec
from swarm_sim.headless import TrialRecord


class DaskError(RuntimeError):
    """The Dask cluster cannot be used: one line saying why and what to do."""


def local_trials(spec: ScenarioSpec, seeds: list[int], workers: int
                 ) -> Iterator[TrialRecord]:
    """Records of ``seeds`` from ``workers`` local processes, in completion order."""
    with futures.ProcessPoolExecutor(max_workers=workers) as pool:
        jobs = [pool.submit(run_trial, spec, s) for s in seeds]
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


def dask_trials(client, spec: ScenarioSpec, seeds: list[int]) -> Iterator[TrialRecord]:
    """Records of ``seeds`` computed on the cluster of ``client``, in completion order."""
    from dask.distributed import as_completed

    jobs = client.map(run_trial, [spec] * len(seeds), seeds, pure=False)
    for job in as_completed(jobs):
        yield job.result()
