"""Whether each track carries a slowly changing offset for the LiDAR as well as the camera:
the pipeline's float figures on the held-out simulated recordings for a small grid, and a
choice rule fixed in advance.

    python benches/sensor_offsets_heldout.py --work DIR

Protocol (declared and committed before any of its runs). Premise, from the shipped
setting's runs on the ten held-out seeds and on the scored ones:

- the floats' NIS of one recording are correlated: pooled over the 17 seeds the NIS of one
  track has an autocorrelation of 0.20 / 0.17 / 0.13 / 0.11 at lags 1-4 that sums to about
  1.4 over 30 lags, and the variance of the seeds' float ANIS is about 3x that of independent
  samples (std 0.139 against 0.080), so a seed's ANIS leaves a band made for independent
  samples far more often than 5 % of the time;
- its cause is the sensors' slow offsets about each object (the camera: the box's fit; the
  LiDAR: the seen side): a track following one sensor carries that sensor's offset, the
  other's next detection lands off by the difference (mean NIS after a sensor switch 2.3-4.2,
  within one sensor 1.35-2.4), and the track's covariance knows nothing of them (float ANEES
  5.8-15.5 where a consistent filter gives 2);
- one run with both offsets in the state (`tracker.lidar_offset_std = 0.1`,
  `camera_offset_std = 0.25`, both q 0.001, R as shipped) took the ANEES to 0.6-1.3 and the
  mean float RMSE from 0.162 to 0.157 m, and left the ANIS under its band on 8 seeds (mean
  1.62): the offsets take the slow part, so R must shrink to the fast part.

The setting: `[tracker] lidar_offset_std` / `camera_offset_std` (m) and `*_offset_q`
(m²/s): state [n, v_n, e, v_e, b_lidar, b_camera], each sensor measuring position + its own
b. The grid, everything else as shipped:

- lidar_offset_std in {0.05, 0.07} m; camera_offset_std 0.25 m; both q 0.001 m²/s;
- the LiDAR's model stds (`lidar.range_std`, `cross_range_std`, `low_profile_std`) x f for f in
  {0.8, 0.65};
- the camera's `pixel_sigma_uv` x k for k in {0.95, 0.85};
- beside the shipped setting (no offsets, f = k = 1).

The seeds: held out 4, 5, 6, 8, 9, 10, 11, 12, 13, 14; the scored and fresh seeds (1, 2, 3,
7, 15, 16, 17) are refused before the decision (`--scored` after it). A setting passes when
clauses (a)-(d) of benches/demo_detector_heldout.py hold against the shipped setting and all
floats tracked >= the shipped setting's. Choice among passing settings: the most seeds with
the float ANIS inside its gated 95 % band, then the smaller root mean square of (ANIS -
expected) / half the band's width over the seeds, then the lower mean float RMSE. It
replaces the shipped setting only with strictly more seeds with the float ANIS in band; then
the simulator's template and the bundled recording take it and the scored and fresh seeds
are run once with `--scored`.

Result (run once after the protocol's commit), summed over the ten seeds:

| b_lidar m | f | k | floats | f+w+m | mean float RMSE m | seeds ANIS in band | rms z | ANEES |
| --- | --- | --- | --- | --- | --- | --- | --- | --- |
| 0 (shipped) | 1 | 1 | 103 / 103 | 0 | 0.1623 | 6 | 1.09 | 5.8-15.9 |
| 0.05 | 0.8 | 0.95 | 103 / 103 | 0 | 0.1605 | 5 | 1.46 | 0.5-1.2 |
| 0.05 | 0.8 | 0.85 | 103 / 103 | 0 | 0.1631 | 6 | 1.08 | 0.5-1.2 |
| 0.05 | 0.65 | 0.95 | 103 / 103 | 0 | 0.1613 | 5 | 1.13 | 0.6-1.2 |
| 0.05 | 0.65 | 0.85 | 103 / 103 | 0 | 0.1635 | 5 | 1.27 | 0.5-1.2 |
| 0.07 | 0.8 | 0.95 | 103 / 103 | 0 | 0.1603 | 5 | 1.45 | 0.5-1.1 |
| 0.07 | 0.8 | 0.85 | 103 / 103 | 0 | 0.1627 | 6 | 1.08 | 0.5-1.1 |
| 0.07 | 0.65 | 0.95 | 103 / 103 | 0 | 0.1614 | 5 | 1.13 | 0.5-1.1 |
| 0.07 | 0.65 | 0.85 | 103 / 103 | 0 | 0.1637 | 5 | 1.26 | 0.5-1.1 |

(rms z: the root mean square over the seeds of (ANIS - expected) / half the band.) No
setting puts more than the shipped 6 seeds in band: KEEP the shipped setting. The seeds
that leave the band are the same ones under every setting (4 and 6 low, 5, 10 and 11 high):
the offsets move every seed's ANIS together and take the track covariance from
over-confident (ANEES 5.8-15.9) to cautious (0.5-1.2), but leave the seeds' spread.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path
from typing import Any

import tomllib

sys.path.insert(0, str(Path(__file__).resolve().parent))

from demo_detector_heldout import (
    HELDOUT_SEEDS,
    SCORED_SEEDS,
    decide,
    figures,
    grid_runs,
    totals,
)

WEIGHTS = Path(__file__).resolve().parents[1] / "python/usvfast/data/models/harbour-demo.onnx"
#: Settings are (lidar_offset_std m, LiDAR std scale f, camera pixel scale k).
SHIPPED = (0.0, 1.0, 1.0)
GRID = [(b, f, k) for b in (0.05, 0.07) for f in (0.8, 0.65) for k in (0.95, 0.85)]
CAMERA_OFFSET_STD = 0.25
OFFSET_Q = 0.001
LIDAR_STDS = ("range_std", "cross_range_std", "low_profile_std")


def sets(rec: Path, lidar_offset: float, f: float, k: float) -> list[str]:
    """The `--set` overrides of a setting on the recording `rec`."""
    cfg = tomllib.loads((rec / "recording.toml").read_text())
    out = [f"lidar.{key}={f * float(cfg['lidar'][key]):.6g}" for key in LIDAR_STDS]
    u, v = (k * float(x) for x in cfg["camera"]["pixel_sigma_uv"])
    out.append(f"camera.pixel_sigma_uv=[{u:.6g}, {v:.6g}]")
    if lidar_offset > 0:
        out += [
            f"tracker.lidar_offset_std={lidar_offset}",
            f"tracker.lidar_offset_q={OFFSET_Q}",
            f"tracker.camera_offset_std={CAMERA_OFFSET_STD}",
            f"tracker.camera_offset_q={OFFSET_Q}",
        ]
    return out


def consistency(run_dir: Path) -> dict[str, float]:
    """The floats' ANIS z (ANIS - expected over half the band) and ANEES of a run."""
    m = json.loads((run_dir / "metrics.json").read_text())["groups"]["floats"]
    a = m["anis"]
    return {
        "z": (a["mean"] - a["expected"]) / ((a["upper"] - a["lower"]) / 2),
        "anees": m["anees"]["mean"],
    }


def main(argv: list[str] | None = None) -> None:
    """Simulate, run and tabulate (module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", type=Path, required=True, help="recordings and runs go here")
    ap.add_argument("--seeds", type=int, nargs="+", default=list(HELDOUT_SEEDS))
    ap.add_argument("--scored", action="store_true", help="allow scored / fresh seeds")
    ap.add_argument("--setting", type=float, nargs=3, metavar=("B", "F", "K"), help="one setting")
    args = ap.parse_args(argv)
    banned = sorted(set(args.seeds) & SCORED_SEEDS)
    if banned and not args.scored:
        raise ValueError(f"--seeds: {banned} are scored / fresh seeds (--scored after the choice)")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    grid = [tuple(args.setting)] if args.setting else [SHIPPED, *GRID]
    rows: dict[tuple, list[dict[str, Any]]] = {s: [] for s in grid}
    cons: dict[tuple, list[dict[str, float]]] = {s: [] for s in grid}
    print("| seed | b_lidar m, f, k | floats | RMSE m | ANIS | in band | z | ANEES |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    runs = grid_runs(
        args.work,
        args.seeds,
        grid,
        WEIGHTS,
        lambda s: f"offsets-{s[0]:g}-f{s[1]:g}-k{s[2]:g}",
        lambda rec, s: sets(rec, *s),
    )
    for seed, (b, f, k), out in runs:
        fig, c = figures(out), consistency(out)
        rows[(b, f, k)].append(fig)
        cons[(b, f, k)].append(c)
        print(
            f"| {seed} | {b:g}, {f:g}, {k:g} | {fig['tracked']} / {fig['targets']} | "
            f"{fig['rmse']:.3f} | {fig['anis']:.3f} | {fig['anis_inside']} | "
            f"{c['z']:+.2f} | {c['anees']:.1f} |",
            flush=True,
        )
    print(
        "\n| b_lidar m | f | k | detectable floats | floats | f+w+m | mean float RMSE m | "
        "seeds ANIS in band | rms z | ANEES range |\n"
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    )
    sums = {}
    for s, r in rows.items():
        t = totals(r)
        t["rms_z"] = math.sqrt(sum(c["z"] ** 2 for c in cons[s]) / len(cons[s]))
        sums[s] = t
        anees = [c["anees"] for c in cons[s]]
        print(
            f"| {s[0]:g} | {s[1]:g} | {s[2]:g} | {t['det_tracked']} / {t['det_targets']} | "
            f"{t['tracked']} / {t['targets']} | {t['fwm']} | {t['rmse_mean']:.4f} | "
            f"{t['anis_inside']} | {t['rms_z']:.2f} | {min(anees):.1f}-{max(anees):.1f} |"
        )
    if SHIPPED in sums and len(sums) > 1 and set(args.seeds) == set(HELDOUT_SEEDS):
        base = sums[SHIPPED]
        ok = [
            (-t["anis_inside"], t["rms_z"], t["rmse_mean"], s)
            for s, t in sums.items()
            if s != SHIPPED and decide(base, t)[0] and t["tracked"] >= base["tracked"]
        ]
        pick = min(ok)[3] if ok else SHIPPED
        if sums[pick]["anis_inside"] <= base["anis_inside"]:
            pick = SHIPPED
        print(f"decision: {'KEEP the shipped setting' if pick == SHIPPED else f'ADOPT {pick}'}")


if __name__ == "__main__":
    main()
