"""Joyride (real radar, 238 scans): time per scan of the usvfast `joyride` preset (CV only,
IMM, IMM + existence) against Stone Soup's JPDA with the anchor parameters, in one process,
with the track-quality figures of each run.

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


def main() -> None:
    path = Path(os.environ.get("USVFAST_SHARED_DATA", "../shared/data")) / "joyride/joyride.mat"
    plots = read_plots(path)
    n = len(plots.times)
    cfg = load_config("joyride")
    runs = {
        "CV only": {k: v for k, v in cfg.items() if k not in ("imm", "existence")},
        "IMM (CV + 2 turns)": {k: v for k, v in cfg.items() if k != "existence"},
        "IMM + existence (preset)": cfg,
    }
    t0 = time.perf_counter()
    ss, _ = H.build_stonesoup(H.JOYRIDE_ANCHOR, detector=H.joyride_scans(plots_rec(path), 10.0))
    snaps = [H.snapshot(tracks) for _, tracks in ss]
    ss_ms = (time.perf_counter() - t0) / n * 1e3
    q = track_quality(plots.truth, *H.track_rows(snaps))
    print(f"{'run':28s} {'ms/scan':>9s} {'x SS':>8s}  RMSE m  cover  frag  false")
    print(
        f"{'Stone Soup JPDA (anchor)':28s} {ss_ms:9.3f} {1.0:8.0f}  {q.rmse:6.2f} "
        f"{q.coverage:6.3f} {q.fragments:5d} {q.tracks_elsewhere:6d}"
    )
    for name, c in runs.items():

        def go(c=c):
            tr = tracker_from_config(c)
            return tr.run(plots.times - plots.times[0], plots.plots, plots.sensor, plots.scan_index)

        best, res = best_of(go, 20)
        ms = best / n * 1e3
        q = track_quality(plots.truth, res.scan, res.track_id, res.state[:, [0, 2]])
        print(
            f"{name:28s} {ms:9.4f} {ss_ms / ms:8.0f}  {q.rmse:6.2f} {q.coverage:6.3f} "
            f"{q.fragments:5d} {q.tracks_elsewhere:6d}"
        )


def plots_rec(path: Path):
    from usvfast.datasets import load_joyride

    return load_joyride(path)


if __name__ == "__main__":
    main()
