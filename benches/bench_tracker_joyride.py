"""Joyride (real radar, 238 scans): the usvfast tracker with a constant-velocity model only
(preset `joyride-cv`), the IMM alone (preset `joyride` without its existence table),
IMM + existence (preset `joyride`, and `joyride-accurate` that trades coverage for RMSE)
against Stone Soup's JPDA with the anchor parameters, in
one process: time per scan and the track-quality figures of `usvfast.metrics.track_quality`
(gate 50 m) over the whole recording and over its two halves (scans 0-118 and 119-237, scored
from the same run), so that a configuration good on one half only shows. Time per scan: best
wall clock and best process CPU time of 30 runs.

    USVFAST_SHARED_DATA=/work/shared/data PYTHONPATH=python python benches/bench_tracker_joyride.py
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from usvfast.metrics import track_quality
from usvfast.trackcmd import load_config, read_plots, tracker_from_config

import ssharness as H
from timing import best_of

HALF = 119  # first scan of the second half


def parts(truth, scan, ids, pos) -> list:
    """Track quality over all scans, the first half and the second half of one run."""
    out = [track_quality(truth, scan, ids, pos)]
    for a, b in ((0, HALF), (HALF, len(truth))):
        sel = (scan >= a) & (scan < b)
        out.append(track_quality(truth[a:b], scan[sel] - a, ids[sel], pos[sel]))
    return out


def fmt(q) -> str:
    return f"{q.rmse:6.2f} {q.coverage * 100:5.1f} {q.fragments:3d} {q.tracks_elsewhere:3d}"


def best_cpu(fn, repeat: int) -> float:
    """Best process CPU time (s) of `repeat` calls: on a shared, loaded machine the wall
    clock also counts the time spent waiting for a core."""
    best = float("inf")
    for _ in range(repeat):
        c0 = time.process_time()
        fn()
        best = min(best, time.process_time() - c0)
    return best


def main() -> None:
    path = Path(os.environ.get("USVFAST_SHARED_DATA", "../shared/data")) / "joyride/joyride.mat"
    plots = read_plots(path)
    n = len(plots.times)
    cfg = load_config("joyride")
    runs = {
        "CV only (joyride-cv)": load_config("joyride-cv"),
        "IMM (joyride, no existence)": {k: v for k, v in cfg.items() if k != "existence"},
        "IMM + existence (joyride)": cfg,
        "IMM + existence (-accurate)": load_config("joyride-accurate"),
    }
    t0 = time.perf_counter()
    ss, _ = H.build_stonesoup(H.JOYRIDE_ANCHOR, detector=H.joyride_scans(plots_rec(path), 10.0))
    snaps = [H.snapshot(tracks) for _, tracks in ss]
    ss_ms = (time.perf_counter() - t0) / n * 1e3
    head = "RMSE m  cov%  fr  ft"
    print(
        f"{'':30s} {'':>9s} {'':>8s} {'':>6s}  {'all 238 scans':20s}  {'scans 0-118':20s}  "
        "scans 119-237"
    )
    print(f"{'run':30s} {'ms/scan':>9s} {'cpu ms':>8s} {'x SS':>6s}  {head}  {head}  {head}")
    scan, ids, pos = H.track_rows(snaps)
    q = parts(plots.truth, scan, ids, pos)
    print(
        f"{'Stone Soup JPDA (anchor)':30s} {ss_ms:9.3f} {'':8s} {1:6d}  " + "  ".join(map(fmt, q))
    )
    for name, c in runs.items():

        def go(c=c):
            tr = tracker_from_config(c)
            return tr.run(plots.times - plots.times[0], plots.plots, plots.sensor, plots.scan_index)

        best, res = best_of(go, 30)
        cpu = best_cpu(go, 30)
        ms = best / n * 1e3
        q = parts(plots.truth, res.scan, res.track_id, res.state[:, [0, 2]])
        print(
            f"{name:30s} {ms:9.4f} {cpu / n * 1e3:8.4f} {ss_ms / ms:6.0f}  "
            + "  ".join(map(fmt, q))
        )
    print(
        "\n(cov% coverage, fr fragments on the target, ft false tracks; aims on all scans: "
        "cov >= 96 %, RMSE <= 20.5 m, fr = 1, ft <= 2, <= 0.02 ms per scan)"
    )


def plots_rec(path: Path):
    from usvfast.datasets import load_joyride

    return load_joyride(path)


if __name__ == "__main__":
    main()
