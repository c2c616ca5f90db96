"""Sweeps: many recordings × parameter sets on a Dask cluster, one Parquet row per job.

    from usvfast.sweep import run_sweep
    result = run_sweep("configs/sweep-joyride.toml", "out/sweep", engine="local", workers=2)
    result.table[["param.tracker.q", "param.tracker.sigma", "metric.rmse", "status"]]

`usvfast sweep SPEC --out DIR` is the same from the shell. See `usvfast.sweep.spec` for the
spec format and `usvfast.sweep.engine` for running on a real cluster. The names below load on
first use, so `import usvfast.sweep` (and the CLI) works without the `cluster` extra.
"""

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # for type checkers and editors; at run time they load on first use
    from usvfast.sweep.jobs import run_job
    from usvfast.sweep.run import SweepResult, run_sweep
    from usvfast.sweep.spec import Job, SweepSpec, load_spec

_EXPORTS = {
    "Job": "usvfast.sweep.spec",
    "SweepSpec": "usvfast.sweep.spec",
    "load_spec": "usvfast.sweep.spec",
    "run_job": "usvfast.sweep.jobs",
    "SweepResult": "usvfast.sweep.run",
    "run_sweep": "usvfast.sweep.run",
}
__all__ = ["Job", "SweepResult", "SweepSpec", "load_spec", "run_job", "run_sweep"]


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'usvfast.sweep' has no attribute {name!r}")
    return getattr(import_module(_EXPORTS[name]), name)
