"""Sweeps: many recordings × parameter sets on a Dask cluster, one Parquet row per job.

    from usvfast.sweep import run_sweep
    result = run_sweep("configs/sweep-joyride.toml", "out/sweep", engine="local", workers=2)
    result.table[["param.tracker.q", "param.tracker.sigma", "metric.rmse", "status"]]

`usvfast sweep SPEC --out DIR` is the same from the shell. See `usvfast.sweep.spec` for the
spec format and `usvfast.sweep.engine` for running on a real cluster.
"""

from usvfast.sweep.jobs import run_job
from usvfast.sweep.run import SweepResult, run_sweep
from usvfast.sweep.spec import Job, SweepSpec, load_spec

__all__ = ["Job", "SweepResult", "SweepSpec", "load_spec", "run_job", "run_sweep"]
