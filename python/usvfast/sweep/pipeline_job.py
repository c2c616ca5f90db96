"""The "pipeline" job: one recording config through the full pipeline, scored by the report."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path
from typing import Any

from usvfast.sweep.spec import Job


def pipeline_job(job: Job) -> tuple[dict[str, Any], dict[str, float]]:
    """Run `usvfast.pipeline` on the job's recording config with the job's parameters as
    dotted overrides (`base` = "recording" keeps the recording's own preset, anything else
    names the preset to start from); metrics of `usvfast.report.write_report` against the
    job's truth, timings per stage from the run's summary."""
    from usvfast.pipeline import Pipeline, load_config
    from usvfast.report import write_report

    overrides = dict(job.params)
    if job.base != "recording":
        overrides["preset"] = job.base
    config = load_config(job.recording, overrides=overrides)
    with tempfile.TemporaryDirectory(prefix="usvfast-job-") as tmp:
        out = Path(job.tracks_dir) if job.tracks_dir is not None else Path(tmp)
        pipeline = Pipeline(config)
        for _ in pipeline.run(out_dir=out):
            pass
        metrics = write_report(out, truth=job.truth, plots=False)
        summary = json.loads((out / "summary.json").read_text())
    timings = {k: float(v) for k, v in summary.get("time_per_stage", {}).items()}
    return metrics, timings
