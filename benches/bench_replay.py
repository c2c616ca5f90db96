"""Recording replay: usvfast's lazy merge (clock offsets, reorder window, stable ties, pose
lookup hook) vs materialising every item and sorting it (what a scheduler without generators
does), on the same in-memory streams in one process. Prints items/s and the peak
Python memory beyond the input arrays (tracemalloc, measured in a second run).

    python benches/bench_replay.py [--streams 5] [--n 200000]
"""

from __future__ import annotations

import argparse
import time
import tracemalloc
from itertools import chain

import numpy as np

from usvfast.nav.replay import Recording, Replay
from usvfast.nav.stream_types import StreamSpec, register_stream_type

_DATA: dict[str, np.ndarray] = {}


def _open(spec: StreamSpec, decode: bool):
    times = _DATA[spec.options["key"]]

    def gen():
        i = 0
        for start in range(0, times.size, 4096):
            for t in times[start : start + 4096].tolist():
                yield t, i
                i += 1

    return gen()


register_stream_type("bench", _open, needs_path=False, options=["key"])


def make(streams: int, n: int) -> Recording:
    rng = np.random.default_rng(0)
    specs = []
    for k in range(streams):
        _DATA[f"s{k}"] = 1.7e9 + np.cumsum(rng.uniform(0.0, 0.2, n))
        specs.append(
            StreamSpec(f"s{k}", "bench", None, clock_offset=0.01 * k, options={"key": f"s{k}"})
        )
    return Recording("bench", tuple(specs))


def run_ours(rec: Recording) -> int:
    return sum(1 for _ in Replay(rec))


def run_sorted(rec: Recording) -> int:
    items = chain.from_iterable(
        ((t + s.clock_offset, k, i, d) for i, (t, d) in enumerate(_open(s, True)))
        for k, s in enumerate(rec.streams)
    )
    return len(sorted(items, key=lambda x: (x[0], x[1], x[2])))


def measure(fn, rec):
    t0 = time.perf_counter()
    count = fn(rec)
    dt = time.perf_counter() - t0
    tracemalloc.start()  # a second run for memory: tracing slows the code down
    fn(rec)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return count, dt, peak


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--streams", type=int, default=5)
    ap.add_argument("--n", type=int, default=200_000)
    args = ap.parse_args()
    rec = make(args.streams, args.n)
    results = {}
    for name, fn in [("usvfast Replay (lazy)", run_ours), ("sorted() in memory", run_sorted)]:
        count, dt, peak = measure(fn, rec)
        results[name] = dt
        print(
            f"{name:24s} {count:>9d} items  {count / dt / 1e6:6.2f} M items/s  "
            f"peak {peak / 2**20:8.1f} MiB"
        )
    ours, peer = results.values()
    print(f"time ratio sorted/ours: {peer / ours:.2f}")


if __name__ == "__main__":
    main()
