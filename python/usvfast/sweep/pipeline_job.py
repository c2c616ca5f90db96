"""The "pipeline" job: one recording config through the full pipeline, scored like the report."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

from usvfast.sweep.spec import Job


def _scalars(tree: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Scalar leaves of a nested metrics dict under dotted names ("thesis.rmse")."""
    out: dict[str, Any] = {}
    for k, v in tree.items():
        if isinstance(v, dict):
            out.update(_scalars(v, f"{prefix}{k}."))
        elif isinstance(v, bool | int | float | str) or v is None:
            out[f"{prefix}{k}"] = v
    return out


def pipeline_job(job: Job) -> tuple[dict[str, Any], dict[str, float]]:
    """Run `usvfast.pipeline` on the job's recording config with the job's parameters as
    dotted overrides (`base` other than "recording" names the preset to start from); metrics
    of `usvfast.report.evaluate_run` against the job's truth (the thesis's, CLEAR MOT, HOTA,
    GOSPA), flattened to dotted names; timings per pipeline stage. No pictures: the job's
    files (tracks.csv, ...) are kept in `tracks_dir` when the spec asks for them, and
    `usvfast report DIR --truth ...` draws them later."""
    from usvfast.metrics.tables import (
        read_detections,
        read_innovations,
        read_nav,
        read_tracks,
        read_truth,
    )
    from usvfast.pipeline import Pipeline, load_config
    from usvfast.report.evaluate import evaluate_run

    overrides: dict[str, Any] = {"outputs.report": False, "outputs.animation": False}
    if job.base != "recording":
        overrides["preset"] = job.base
    overrides.update(job.params)
    pipeline = Pipeline(load_config(job.recording, overrides=overrides))
    with tempfile.TemporaryDirectory(prefix="usvfast-job-") as tmp:
        out = Path(job.tracks_dir) if job.tracks_dir is not None else Path(tmp)
        for _ in pipeline.run(out=out):
            pass
        metrics: dict[str, Any] = {}
        if job.truth is not None:
            metrics = evaluate_run(
                read_truth(job.truth),
                read_tracks(out / "tracks.csv"),
                detections=read_detections(out / "detections.csv"),
                nav=read_nav(out / "nav.csv"),
                innovations=read_innovations(out / "innovations.csv"),
            )
    summary = pipeline.summary
    metrics = {**_scalars(metrics), "real_time_factor": summary["real_time_factor"]}
    stages = summary.get("stages", {})
    timings = {k: float(v["seconds"] if isinstance(v, dict) else v) for k, v in stages.items()}
    return metrics, timings
