"""The whole pipeline on one recording, per stage: with the camera (10 Hz), without it, and the
same chain with the thesis's stack (Stone Soup's MultiTargetMixtureTracker, scikit-learn's
MeanShift, the numpy line-of-sight filter), in the same run; real-time factor = recording
span / wall time. "camera inline" runs the camera network on the main thread
(`camera.worker_thread = false`); by default it runs on a worker thread, overlapping the
reader, the LiDAR chain and the tracker (camera.wait: the main thread's wait for it). One
untimed read of the navigation streams first warms the process (imports), so that every run
is timed alike.

    PYTHONPATH=python python benches/bench_pipeline.py [--duration 30] [--config CFG]

Default recording: tests/pipeline_recording.py (VLP-16 PointCloud2 at 10 Hz, NMEA at 10 Hz,
IMU at 50 Hz, 640x360 jpeg camera frames at 10 Hz, five floats, two moored boats), with its
colour-threshold detector; `--config` runs any recording config instead (its own detector).
Every detection carries its own covariance in every run (Stone Soup: its own LinearGaussian).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from usvfast.pipeline import Pipeline, load_config
from usvfast.pipeline.pose import NavTrack


def run_once(cfg, detector) -> dict:
    pipe = Pipeline(cfg, detector=detector)
    cpu0 = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in pipe.run():
            pass
    return {**pipe.summary, "cpu_s": time.process_time() - cpu0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--config", type=Path, default=None)
    args = ap.parse_args()
    detector = None
    with tempfile.TemporaryDirectory() as tmp:
        if args.config is None:
            import pipeline_recording as pr

            built = pr.build(Path(tmp) / "rec", duration=args.duration)
            config, detector = built.config, pr.disc_detector
        else:
            config = args.config
        base: dict = {}
        runs = {
            "usvfast, camera": load_config(config, base),
            "usvfast, camera inline": load_config(config, {**base, "camera.worker_thread": False}),
            "usvfast, no camera": load_config(config, {**base, "camera.enabled": False}),
            "thesis stack, camera": load_config(
                config,
                {
                    **base,
                    "tracker.backend": "stonesoup",
                    "lidar.backend": "sklearn",
                    "lidar.los_backend": "numpy",
                },
            ),
        }
        results = {}
        # Warm-up (untimed): the first read of the navigation streams imports the bag and NMEA
        # readers; every timed run below then starts from the same warm process.
        NavTrack.from_config(runs["usvfast, camera"])
        for name, cfg in runs.items():
            results[name] = run_once(cfg, detector)
            results[name]["load"] = os.getloadavg()[0]
    stages = []
    for r in results.values():
        stages += [s for s in r["stages"] if s not in stages]
    names = list(results)
    width = max(len(s) for s in stages) + 2
    print(f"recording span {results[names[0]]['duration_s']:.1f} s; ms per call (calls)")
    print("stage".ljust(width) + "".join(n.rjust(24) for n in names))
    for s in stages:
        cells = []
        for n in names:
            v = results[n]["stages"].get(s)
            cells.append("-" if v is None else f"{v['ms_per_call']:.2f} ({v['calls']})")
        print(s.ljust(width) + "".join(c.rjust(24) for c in cells))
    print("wall s".ljust(width) + "".join(f"{results[n]['wall_s']:.2f}".rjust(24) for n in names))
    print(
        "CPU s (all threads)".ljust(width)
        + "".join(f"{results[n]['cpu_s']:.2f}".rjust(24) for n in names)
    )
    print(
        "real-time factor".ljust(width)
        + "".join(f"{results[n]['real_time_factor']:.1f}x".rjust(24) for n in names)
    )
    print(
        "load (1 min)".ljust(width) + "".join(f"{results[n]['load']:.1f}".rjust(24) for n in names)
    )
    print(
        "camera network on".ljust(width)
        + "".join(str(results[n].get("detector_runtime") or "-").rjust(24) for n in names)
    )
    print("tracks".ljust(width) + "".join(str(results[n]["tracks"]).rjust(24) for n in names))
    ours, thesis = results[names[0]], results[names[3]]
    print(
        f"ratio (thesis stack wall / usvfast wall, with camera): "
        f"{thesis['wall_s'] / ours['wall_s']:.1f}x"
    )
    tr_o = ours["stages"]["tracker"]["seconds"]
    tr_t = thesis["stages"]["tracker"]["seconds"]
    print(f"tracker alone: Stone Soup {tr_t:.3f} s vs usvfast {tr_o:.3f} s ({tr_t / tr_o:.0f}x)")


if __name__ == "__main__":
    main()
