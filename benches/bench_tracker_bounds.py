"""Bounded cost and memory of the native tracker (no peer: Stone Soup has neither bound).

(a) Clutter burst: one scan of 10,000 uniform clutter plots among 5 tracked targets, then a
normal scan; time of both scans and tentative tracks left, without and with
`max_new_tentative=100`. (b) Soak: 100,000 scans in one `run` where a short-lived target is born
every 6 scans (≈ 16,000 deleted tracks); resident memory growth without a bound and with
`max_deleted=100`.

    PYTHONPATH=python python benches/bench_tracker_bounds.py
"""

from __future__ import annotations

import time

import numpy as np

from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d


def rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4096 / 1e6


def make(cap=None, max_deleted=None):
    return T.Tracker(
        motion_model=constant_velocity_2d(0.1),
        sensors=[T.Sensor.position(0.5)],
        association=T.JPDA(0.9, 0.99, 1e-3),
        deleter=T.StepsSinceUpdate(2),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4), np.diag([0, 1.0, 0, 1.0]), missed_distance=2.0, max_new_tentative=cap
        ),
        max_deleted=max_deleted,
    )


def burst(cap):
    rng = np.random.default_rng(0)
    tr = make(cap)
    targets = np.array([[i * 50.0, 0.0] for i in range(5)])
    for k in range(5):
        tr.step(float(k), targets + rng.normal(0, 0.3, targets.shape))
    t0 = time.perf_counter()
    tr.step(5.0, np.vstack([targets, rng.uniform(-100, 1100, (10_000, 2))]))
    t1 = time.perf_counter()
    tr.step(6.0, targets)
    t2 = time.perf_counter()
    return (t1 - t0) * 1e3, (t2 - t1) * 1e3, len(tr.tentative_tracks), len(tr.tracks)


def soak(max_deleted, n=100_000):
    k = np.arange(n)
    keep = k % 6 < 4
    z = np.column_stack([(k // 6) * 100.0, np.zeros(n)])[keep]
    tr = make(max_deleted=max_deleted)
    before = rss_mb()
    t0 = time.perf_counter()
    tr.run(k.astype(float), z, np.zeros(len(z), np.int64), k[keep])
    dt = time.perf_counter() - t0
    return rss_mb() - before, dt / n * 1e6, len(tr.deleted_track_ids)


def main() -> None:
    print("(a) clutter burst of 10,000 plots        burst ms  next ms  tentative  confirmed")
    for cap in (None, 100):
        b, nx, tent, conf = burst(cap)
        print(
            f"    max_new_tentative={cap!s:5s}            {b:8.1f} {nx:8.1f} {tent:10d} {conf:10d}"
        )
    print("(b) soak, 100,000 scans                   RSS growth MB  us/scan  deleted kept")
    for md in (None, 100):
        mb, us, kept = soak(md)
        print(f"    max_deleted={md!s:5s}                     {mb:13.1f} {us:8.2f} {kept:13d}")


if __name__ == "__main__":
    main()
