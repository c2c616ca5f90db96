"""The distributed engine behind sweeps: Dask (`distributed`). Only this module imports it.

Why Dask: its local cluster (`LocalCluster`) runs the same scheduler and worker processes as a
real cluster, so `--engine local` and a cluster differ only by the scheduler address; it is
pure Python on PyPI (`pip install usvfast[cluster]`), and its scheduler re-runs the tasks of a
worker that dies on the remaining workers. (Ray would do too, but its wheel is an order of
magnitude larger and brings its own daemons; nothing here needs its actors or object store.)

A real cluster: start `dask scheduler` on one machine and `dask worker tcp://HOST:8786` on
each worker (every worker needs `pip install usvfast[cluster]` plus the extras its jobs use,
and the recordings at the same paths, e.g. a shared file system), then
`usvfast sweep SPEC --engine dask --address tcp://HOST:8786 --out DIR`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import Any

from usvfast._extras import require

ENGINES = ("local", "dask")


def _distributed():
    return require("distributed", "cluster", "sweeps")


@contextmanager
def open_client(engine: str = "local", address: str | None = None, workers: int = 2):
    """A Dask client: `engine="local"` starts a local cluster of `workers` single-threaded
    worker processes (with nannies, which restart a worker that dies); `engine="dask"`
    connects to the scheduler at `address`. Closed (and the local cluster stopped) on exit."""
    if engine == "ray":
        raise ValueError(
            "engine: 'ray' is not supported; usvfast sweeps run on Dask ('local' or 'dask')"
        )
    if engine not in ENGINES:
        raise ValueError(f"engine: expected one of {ENGINES}, got {engine!r}")
    distributed = _distributed()
    if engine == "dask":
        if not address:
            raise ValueError("address: --engine dask needs the scheduler address (tcp://HOST:8786)")
        client = distributed.Client(address)
        try:
            yield client
        finally:
            client.close()
        return
    if address:
        raise ValueError("address: only with --engine dask")
    if not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers: expected a positive integer, got {workers!r}")
    with (
        distributed.LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
            worker_dashboard_address=None,
            silence_logs=50,
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        yield client


def map_unordered(
    client: Any, fn: Callable[[Any], dict], items: Iterable[Any], keys: Iterable[str]
) -> Iterator[dict]:
    """Submit `fn(item)` for every item under its key and yield the results as they finish.
    A task whose workers kept dying (Dask's KilledWorker after its allowed failures) yields
    {"job_id": key, "status": "worker-lost", "error": ...} instead of stopping the sweep."""
    distributed = _distributed()
    futures = {}
    for item, key in zip(items, keys, strict=True):
        futures[client.submit(fn, item, key=f"usvfast-job-{key}", pure=False)] = key
    for future in distributed.as_completed(list(futures)):
        try:
            yield future.result()
        except distributed.KilledWorker as e:
            yield {"job_id": futures[future], "status": "worker-lost", "error": str(e)}
        finally:
            future.release()
