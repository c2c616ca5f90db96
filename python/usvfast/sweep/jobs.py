"""What one sweep job does on a worker: build the run from the job's paths and parameters,
run it, return one flat result row. Nothing but the `Job` (plain data) crosses the wire; the
worker builds its own tracker or pipeline.

Job kinds:
- "plots": a file of radar plots (the Joyride `.mat`, or CSV `time,north,east[,sensor]`)
  tracked by the tracker configured by `base` + params; metrics against the recording's truth.
- "pipeline": a recording config run through `usvfast.pipeline.Pipeline`; metrics from
  `usvfast.report` against the job's truth.
- "module:function": a user function `f(job) -> (metrics dict, timings dict)`.
"""

from __future__ import annotations

import importlib
import os
import socket
import time
import traceback
from typing import Any

from usvfast.sweep.spec import Job


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}"


def _flat(prefix: str, values: dict[str, Any]) -> dict[str, Any]:
    out = {}
    for k, v in values.items():
        if isinstance(v, bool | int | float | str) or v is None:
            out[f"{prefix}{k}"] = v
    return out


def _kind_function(kind: str):
    if kind == "plots":
        from usvfast.sweep.plots_job import plots_job

        return plots_job
    if kind == "pipeline":
        from usvfast.sweep.pipeline_job import pipeline_job

        return pipeline_job
    module, _, name = kind.partition(":")
    return getattr(importlib.import_module(module), name)


def run_job(job: Job) -> dict[str, Any]:
    """Run one job and return its result row; never raises. Columns: job_id, recording,
    truth, status ("ok" or "error"), error (message + traceback tail, "" when ok), worker,
    started / finished (UNIX s), wall_s, then `param.<name>`, `metric.<name>` and
    `time.<stage>` (seconds) columns."""
    started = time.time()
    t0 = time.perf_counter()
    row: dict[str, Any] = {
        "job_id": job.job_id,
        "recording": job.recording,
        "truth": job.truth or "",
        "status": "ok",
        "error": "",
        "worker": _worker_name(),
        "started": started,
    }
    row.update(_flat("param.", job.params))
    try:
        metrics, timings = _kind_function(job.kind)(job)
        row.update(_flat("metric.", metrics))
        row.update(_flat("time.", timings))
    except Exception as e:  # a failed job is a row with its error; the sweep goes on
        tail = "".join(traceback.format_exception(e)[-3:])
        row.update(status="error", error=f"{type(e).__name__}: {e}\n{tail}"[:4000])
    row["wall_s"] = time.perf_counter() - t0
    row["finished"] = time.time()
    return row
