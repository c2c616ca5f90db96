"""Running a sweep: the spec's unfinished jobs on the engine, results stored as they arrive."""

from __future__ import annotations

from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from usvfast.sweep.engine import map_unordered, open_client
from usvfast.sweep.jobs import run_job
from usvfast.sweep.results import ResultsStore
from usvfast.sweep.spec import SweepSpec, load_spec


@dataclass(frozen=True)
class SweepResult:
    """table: one row per job of the spec (a pandas DataFrame, from results.parquet);
    ran / skipped: jobs run now and jobs found finished from an earlier run; path: the
    results.parquet written."""

    table: Any
    ran: int
    skipped: int
    path: Path


def run_sweep(
    spec: SweepSpec | str | Path,
    out_dir: str | Path,
    *,
    engine: str = "local",
    address: str | None = None,
    workers: int = 2,
    retry_failed: bool = False,
    on_result: Callable[[dict], None] | None = None,
    client: Any = None,
) -> SweepResult:
    """Run every job of `spec` not already finished in `out_dir` (resume), on a Dask local
    cluster of `workers` processes (`engine="local"`) or the scheduler at `address`
    (`engine="dask"`). Each finished job is stored at once (results.parts/); failed jobs are
    rows with status "error"; `on_result(row)` is called per finished job (progress bars).
    `client`: an open `distributed.Client` to use instead (engine, address and workers are
    then ignored), e.g. a notebook's own cluster."""
    if not isinstance(spec, SweepSpec):
        spec = load_spec(spec, out_dir)
    store = ResultsStore(out_dir)
    done = store.finished_ids(retry_failed)
    todo = [j for j in spec.jobs if j.job_id not in done]
    # Rows of jobs about to run again (retried errors, lost workers) are replaced, not doubled.
    store.drop({j.job_id for j in todo})
    if todo:
        opened = (
            nullcontext(client) if client is not None else open_client(engine, address, workers)
        )
        with opened as c:
            for row in map_unordered(c, run_job, todo, [j.job_id for j in todo]):
                store.add(row)
                if on_result is not None:
                    on_result(row)
    path = store.write_table()
    table = store.table()
    table = table[table["job_id"].isin([j.job_id for j in spec.jobs])].reset_index(drop=True)
    return SweepResult(table, ran=len(todo), skipped=len(spec.jobs) - len(todo), path=path)
