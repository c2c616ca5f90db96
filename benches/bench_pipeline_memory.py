"""Memory of the pipeline against the recording's length: the same simulated recording
(tests/pipeline_recording.py) at two durations, Python allocations traced with tracemalloc
after the first 50 track updates and at the end, plus the process's peak RSS (which also
holds the Rust tracker's track histories). Bounded memory: the end figures do not grow with
the duration (nothing is kept per message; rows go to the output files as they happen).

    PYTHONPATH=python python benches/bench_pipeline_memory.py [--durations 20 120]
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import tracemalloc
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from usvfast.pipeline import Pipeline

import pipeline_recording as pr


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--durations", type=float, nargs="+", default=[20.0, 120.0])
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for d in args.durations:
            built = pr.build(Path(tmp) / f"rec{d:g}", duration=d)
            pipe = Pipeline(built.config, detector=pr.disc_detector)
            tracemalloc.start()
            n, base = 0, 0
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                for _ in pipe.run(out=Path(tmp) / f"out{d:g}"):
                    n += 1
                    if n == 50:
                        base = tracemalloc.get_traced_memory()[0]
            cur, peak = tracemalloc.get_traced_memory()
            tracemalloc.stop()
            rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
            print(
                f"{d:6.0f} s: {n} updates; traced {base / 1e6:.1f} MB after 50 updates, "
                f"{cur / 1e6:.1f} MB at the end, peak {peak / 1e6:.1f} MB; max RSS {rss:.0f} MB"
            )


if __name__ == "__main__":
    main()
