"""Per-scan time of the usvfast tracker vs Stone Soup (same scenario, same process).

Code 5.7 configuration (CV q = 0.001, JPDA P_D 0.85 / P_G 0.95 / λ 0.125, GNN initiator with
missed distance 0.3, covariance-trace + steps deleters), one position sensor σ = 0.25 m:
(a) 5 well-separated targets with clutter, (b) 20 separated targets, (c) 8 targets in parallel
0.3 m apart (inside each other's gates), (d) scaling 10 … 10,000 separated targets (ours; Stone
Soup's EHM up to 100). Stone Soup runs JPDA (where it finishes) and JPDAWithEHM (the pyehm
plugin), both built by tests/ssharness.py.
Run: `python benches/bench_tracker.py [--scans N] [--full]`.
"""

from __future__ import annotations

import argparse
import sys
import time
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from usvfast import tracking as T

import ssharness as H

SIGMA = 0.25


def scenario(n, spacing, n_scans, clutter=0.0, seed=0):
    """Targets on a grid (or in a row when spacing < 1 m) at (0, 0.2) m/s, scans 1 s apart."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    if spacing < 1:
        pos = np.column_stack([np.arange(n) * spacing, np.zeros(n)])
    else:
        pos = np.column_stack([np.arange(n) % side, np.arange(n) // side]) * spacing
    extent = pos.max(axis=0) + 10
    scans = []
    for k in range(1, n_scans + 1):
        truth = pos + np.array([0.0, 0.2 * k])
        seen = rng.random(n) < 0.95
        z = truth[seen] + rng.normal(0, SIGMA, (seen.sum(), 2))
        c = rng.uniform([-10.0, -10.0], extent, (rng.poisson(clutter), 2))
        z = np.concatenate([z, c]) if len(c) else z
        scans.append((float(k), z))
    return scans


def ours(scans, warm=0):
    tracker = T.code_5_7([T.Sensor.position(SIGMA)])
    per = []
    for t, z in scans:
        t0 = time.perf_counter()
        out = tracker.step(t, z, np.zeros(len(z), dtype=np.int64))
        per.append(time.perf_counter() - t0)
    return float(np.mean(per[warm:])), len(out)


def stonesoup(scans, ehm, warm=0):
    from stonesoup.types.detection import Detection

    epoch = datetime(2024, 1, 1)
    cfg = H.Code57(init_noise=SIGMA**2, associator="ehm" if ehm else "jpda")
    detector = (
        (
            epoch + timedelta(seconds=t),
            {Detection(zz.reshape(2, 1), timestamp=epoch + timedelta(seconds=t)) for zz in z},
        )
        for t, z in scans
    )
    tracker, _ = H.build_stonesoup(cfg, detector)
    per = []
    tracks = set()
    t0 = time.perf_counter()
    for _, tracks in tracker:  # noqa: B007 (the last set is the result)
        per.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
    return float(np.mean(per[warm:])), len(tracks)


def row(name, scans, peers, warm=0):
    t_ours, n_ours = ours(scans, warm)
    line = f"{name:<32} ours {t_ours * 1e3:9.3f} ms/scan ({n_ours} tracks)"
    for label, ehm in peers:
        t_ss, n_ss = stonesoup(scans, ehm, warm)
        line += f" | {label} {t_ss * 1e3:8.2f} ms ({n_ss}) x{t_ss / t_ours:,.0f}"
    print(line, flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scans", type=int, default=15)
    ap.add_argument("--full", action="store_true", help="also 10,000 targets")
    a = ap.parse_args()
    both = [("SS JPDA", False), ("SS EHM", True)]
    row("(a) 5 separated + clutter", scenario(5, 100, a.scans, 3.0), both)
    row("(b) 20 separated", scenario(20, 100, a.scans, 0.0), [("SS EHM", True)])
    row("(c) 8 parallel 0.3 m", scenario(8, 0.3, a.scans, 0.0), both)
    row("(c') 20 parallel 0.3 m", scenario(20, 0.3, a.scans, 0.0), [])
    # Scaling in steady state: the first 6 scans (initiation: up to 3x more tentative tracks
    # than targets) are run but not timed, the same number of scans for every size.
    for n in [10, 100, 1000] + ([10_000] if a.full else []):
        peers = [("SS EHM", True)] if n <= 100 else []
        row(f"(d) {n} separated (steady)", scenario(n, 100, 12), peers, warm=6)


if __name__ == "__main__":
    main()
