"""Sweep throughput on this machine: jobs per minute of the Joyride q x sigma grid (36 jobs)
on a Dask local cluster of 1 and 2 workers, against a plain loop in one process, and the
engine's overhead per job (cluster start-up reported apart).

python benches/bench_sweep.py [--repeat N]    # N copies of the grid (default 4: 144 jobs)
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

from usvfast.sweep import load_spec, run_job, run_sweep
from usvfast.sweep.engine import open_client

SPEC = Path(__file__).resolve().parents[1] / "configs" / "sweep-joyride.toml"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=4)
    args = ap.parse_args()
    base = load_spec(SPEC)
    # Copies of the grid with distinct job ids, so nothing is skipped as finished.
    jobs = [
        dataclasses.replace(j, job_id=f"{j.job_id}-{k}")
        for k in range(args.repeat)
        for j in base.jobs
    ]
    spec = dataclasses.replace(base, jobs=jobs)
    n = len(jobs)
    t0 = time.perf_counter()
    for j in jobs:
        run_job(j)
    loop = time.perf_counter() - t0
    print(f"{n} Joyride jobs (238 scans each)")
    print(f"plain loop, one process : {loop:7.2f} s  {60 * n / loop:7.0f} jobs/min")
    for workers in (1, 2):
        t0 = time.perf_counter()
        with open_client("local", workers=workers) as client:
            client.wait_for_workers(workers)
            start = time.perf_counter() - t0
            with tempfile.TemporaryDirectory() as tmp:
                t1 = time.perf_counter()
                run_sweep(spec, tmp, client=client)
                wall = time.perf_counter() - t1
        overhead = (wall * workers - loop) / n
        print(
            f"dask local, {workers} worker(s): {wall:7.2f} s  {60 * n / wall:7.0f} jobs/min  "
            f"(x{loop / wall:.2f} the loop; start-up {start:.1f} s; "
            f"overhead {1e3 * overhead:+.1f} ms per job-worker)"
        )


if __name__ == "__main__":
    main()
