"""User job functions for the sweep tests (imported by the Dask workers by name)."""

import time


def slow_job(job):
    """Sleeps `params["sleep"]` seconds and echoes the params as metrics."""
    time.sleep(float(job.params.get("sleep", 0.0)))
    if job.params.get("fail"):
        raise RuntimeError(f"job asked to fail (x={job.params.get('x')})")
    return {"x2": float(job.params["x"]) ** 2}, {"sleep": float(job.params.get("sleep", 0.0))}
