"""Bounded cost and memory of the native tracker (no peer: Stone Soup has neither bound).

(a) Clutter burst: one scan of 10,000 uniform clutter plots among 5 tracked targets, then a
normal scan; time of both scans and tentative tracks left, without and with
`max_new_tentative=100`. (b) Soak: 100,000 scans in one `run` where a short-lived target is born
every 6 scans (≈ 16,000 deleted tracks); resident memory growth without a bound and with
`max_deleted=100`. (c) Grids of 6x6 and 8x8 targets 2 m apart (Code 5.7 configuration,
σ 0.25 m, 15 scans): worst and mean time per scan, with the default JPDA budget
(`max_hypotheses=1e6`) and exact (`None`). (d) Dense clutter: 3,000 uniform plots a scan in
300 m x 300 m for 8 scans; clutter tracks merge into clusters of thousands of tracks. With the
budget: worst scan time, peak RSS, approximated clusters; exact EHM is run in a child process
under a 3 GB address-space limit (it exhausts it).

    PYTHONPATH=python python benches/bench_tracker_bounds.py
"""

from __future__ import annotations

import resource
import subprocess
import sys
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


def grid(side, budget, n_scans=15, spacing=2.0):
    rng = np.random.default_rng(0)
    n = side * side
    pos = np.column_stack([np.arange(n) % side, np.arange(n) // side]) * spacing
    tr = T.code_5_7([T.Sensor.position(0.25)], T.JPDA(0.85, 0.95, 0.125, max_hypotheses=budget))
    per, approx, largest = [], 0, 0
    for k in range(1, n_scans + 1):
        seen = rng.random(n) < 0.95
        z = pos[seen] + np.array([0.0, 0.2 * k]) + rng.normal(0, 0.25, (seen.sum(), 2))
        t0 = time.perf_counter()
        tr.step(float(k), z)
        per.append(time.perf_counter() - t0)
        approx += tr.last_step.approximated_clusters
        largest = max(largest, tr.last_step.largest_cluster)
    return max(per) * 1e3, float(np.mean(per)) * 1e3, approx, largest, len(tr.tracks)


def dense(budget, n_scans=8, n_plots=3000, side=300.0):
    rng = np.random.default_rng(0)
    tr = T.Tracker(
        motion_model=constant_velocity_2d(0.1),
        sensors=[T.Sensor.position(0.5)],
        association=T.JPDA(0.9, 0.99, 1e-3, max_hypotheses=budget),
        deleter=T.StepsSinceUpdate(3),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4), np.diag([0, 1.0, 0, 1.0]), missed_distance=3.0
        ),
    )
    worst, approx, largest = 0.0, 0, 0
    for k in range(n_scans):
        t0 = time.perf_counter()
        tr.step(float(k), rng.uniform(0, side, (n_plots, 2)))
        worst = max(worst, time.perf_counter() - t0)
        approx += tr.last_step.approximated_clusters
        largest = max(largest, tr.last_step.largest_cluster)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
    return worst * 1e3, peak, approx, largest


def dense_exact_child() -> str:
    code = (
        "import resource, sys; sys.path.insert(0, 'benches');"
        "resource.setrlimit(resource.RLIMIT_AS, (3_000_000_000, 3_000_000_000));"
        "import bench_tracker_bounds as b; print(b.dense(None))"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=900)
    if r.returncode == 0:
        return r.stdout.strip()
    tail = (r.stderr.strip().splitlines() or ["?"])[0]
    return f"failed (exit {r.returncode}): {tail[:70]}"


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
    print("(c) grid, 2 m apart, 15 scans          worst ms  mean ms  approx  largest  tracks")
    for side in (6, 8):
        for budget in (1_000_000, None):
            w, m, a, lg, nt = grid(side, budget)
            print(
                f"    {side}x{side} max_hypotheses={budget!s:8s} {w:9.1f} {m:8.1f} {a:7d} "
                f"{lg:8d} {nt:7d}",
                flush=True,
            )
    print("(d) dense clutter 3,000 plots x 8 scans   worst ms  peak RSS MB  approx  largest")
    w, peak, a, lg = dense(1_000_000)
    print(f"    max_hypotheses=1000000            {w:9.1f} {peak:12.0f} {a:7d} {lg:8d}")
    print(f"    max_hypotheses=None (exact, 3 GB limit): {dense_exact_child()}")


if __name__ == "__main__":
    main()
