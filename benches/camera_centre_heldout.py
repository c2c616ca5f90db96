"""Whether the camera's floating-object detections get a range-independent centre error: the
pipeline's float figures on the held-out simulated recordings for a small grid, and a choice
rule fixed in advance.

    python benches/camera_centre_heldout.py --work DIR

Protocol (declared and committed before any of its runs). Premise, from the shipped setting's
runs of benches/vessel_noise_heldout.py on the ten held-out seeds (`vessel-o0-k0.5`): the
floats' camera NIS falls with the range, 3.18 / 2.99 / 2.23 / 1.74 / 1.45 / 1.41 in the bins
0-5 / 5-7.5 / 7.5-10 / 10-12.5 / 12.5-15 / 15-20 m (LiDAR 2.16 / 1.91 / 1.79 / 1.86), so a
seed's float ANIS follows the ranges of its floats. The camera detections' errors about the
truth (nearest float within 1.5 m, same 0.1 s) show why: along the line of sight 0.10 /
0.12 / 0.16 / 0.23 / 0.29 / 0.44 m rms against a modelled std of 0.03 / 0.06 / 0.12 / 0.19 /
0.29 / 0.43 m, across it 0.05-0.09 m against 0.01-0.06 m. The error has a part that does not
shrink with the range (the object's shape and yaw, the box's fit about it) which the pixel
model lacks; the pixel sigmas, set from the pooled innovations, then overstate the far part.
`camera.centre_along_std` / `centre_across_std` (m) add that part to each float detection's
covariance.

- Recordings: the held-out seeds 4, 5, 6, 8, 9, 10, 11, 12, 13, 14 (as the other protocols;
  reused when present), each run with the shipped detector and vessel settings
  (`detector.conf_threshold=0.45`, `camera.start_confidence=0.5`, `camera.vessel_along_std=0.5`,
  `camera.vessel_across_std=0.3`: the recordings were simulated before the template carried
  them) and the bundled demo network.
- Grid: (centre_along_std, centre_across_std) in {(0, 0) shipped, (0.05, 0.03), (0.1, 0.05)} x
  the recording's camera.pixel_sigma_uv scaled by k in {1.0 shipped, 0.75, 0.5}. Everything
  else unchanged. The scored seeds 1, 2, 3, 7 and fresh 15, 16, 17 are refused before the
  decision (`--scored` after it).
- A setting passes when clauses (a)-(d) of benches/demo_detector_heldout.py hold against the
  shipped setting (detectable floats tracked >=, false + wall + moored <=, seeds with float
  RMSE <= 0.3 m >= and mean float RMSE <= +0.02 m, seeds with float ANIS in band >=) and all
  floats tracked >= the shipped setting's.
- Choice among passing settings: the most seeds with the float ANIS inside its gated 95 %
  band, then the smaller spread of the floats' camera NIS over range (max - min of its pooled
  means in the bins 0-7.5, 7.5-12.5 and 12.5-20 m), then the lower mean float RMSE, then the
  setting nearer the shipped one (smaller centre std, then larger k). It replaces the shipped
  setting only with strictly more seeds with the float ANIS in band; then the simulator's
  template and the bundled recording take it and the scored and fresh seeds are run once with
  `--scored`.

Result (run once after the protocol's commit), summed over the ten seeds:

| along / across m | k | floats | f+w+m | float RMSE m | ANIS in | camera NIS by range (*) |
| --- | --- | --- | --- | --- | --- | --- |
| 0 / 0 (shipped) | 1 | 103 | 0 | 0.1623 | 6 | 3.03 / 1.97 / 1.43 |
| 0 / 0 | 0.75 | 103 | 0 | 0.1735 | 0 | 3.51 / 2.64 / 2.13 |
| 0 / 0 | 0.5 | 103 | 0 | 0.1824 | 0 | 4.02 / 3.43 / 3.20 |
| 0.05 / 0.03 | 1 | 103 | 0 | 0.1597 | 3 | 1.91 / 1.58 / 1.25 |
| 0.05 / 0.03 | 0.75 | 103 | 0 | 0.1675 | 4 | 2.17 / 2.01 / 1.77 |
| 0.05 / 0.03 | 0.5 | 103 | 0 | 0.1808 | 1 | 2.35 / 2.46 / 2.44 |
| 0.1 / 0.05 | 1 | 103 | 0 | 0.1527 | 0 | 1.21 / 1.19 / 1.09 |
| 0.1 / 0.05 | 0.75 | 103 | 0 | 0.1605 | 1 | 1.26 / 1.44 / 1.45 |
| 0.1 / 0.05 | 0.5 | 103 | 0 | 0.1681 | 4 | 1.31 / 1.74 / 1.92 |

(*) pooled means over 0-7.5 / 7.5-12.5 / 12.5-20 m. RMSE: the mean over the seeds; ANIS in:
seeds with the float ANIS in its band. No setting passes (d) (6 seeds in band): KEEP the
shipped setting. The centre error does flatten the camera NIS over range (spread 1.60 -> 0.11
at 0.05 / 0.03 m with k 0.5 and 0.12 at 0.1 / 0.05 m with k 1), but the grid's flat settings
sit at NIS ~2.4 and ~1.2, on either side of the 1.91 a consistent filter gives under the 0.99
gate.

Protocol 2 (declared and committed before any of its runs, after the result above):

    python benches/camera_centre_heldout.py --work DIR --line

- The settings on the line between protocol 1's two flat settings, (along, across, k) =
  (0.05, 0.03, 0.5) + t ((0.1, 0.05, 1.0) - (0.05, 0.03, 0.5)), for t in {0.3, 0.4, 0.5}
  (linear in t: the NIS level fell from ~2.4 at t = 0 to ~1.2 at t = 1, so ~1.9 lies near
  t = 0.4), beside the shipped (0, 0, 1).
- The same seeds, overrides, clauses, choice rule and adoption condition (strictly more than
  the shipped setting's 6 seeds with the float ANIS in band) as protocol 1.

Result of protocol 2 (run once after its commit), summed over the ten seeds:

| along / across m | k | floats | f+w+m | float RMSE m | ANIS in | camera NIS by range (*) |
| --- | --- | --- | --- | --- | --- | --- |
| 0 / 0 (shipped) | 1 | 103 | 0 | 0.1623 | 6 | 3.03 / 1.97 / 1.43 |
| 0.065 / 0.036 | 0.65 | 103 | 0 | 0.1702 | 5 | 1.86 / 2.01 / 1.89 |
| 0.07 / 0.038 | 0.7 | 103 | 0 | 0.1653 | 5 | 1.73 / 1.85 / 1.74 |
| 0.075 / 0.04 | 0.75 | 103 | 0 | 0.1634 | 3 | 1.64 / 1.71 / 1.59 |

No setting passes (d): KEEP the shipped setting. t = 0.3 makes the camera NIS flat over range
at the consistent level (1.86 / 2.01 / 1.89), yet puts one seed fewer in band (5 against 6)
and raises the mean float RMSE by 0.008 m: the seeds' spread of the float ANIS does not come
from the ranges of their floats. The keys stay, off by default, for cameras whose box errors
have a range-independent part.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import tomllib

sys.path.insert(0, str(Path(__file__).resolve().parent))

from demo_detector_heldout import (
    HEADER,
    HELDOUT_SEEDS,
    SCORED_SEEDS,
    decide,
    figures,
    grid_runs,
    row,
    totals,
)

CENTRE_STDS = ((0.0, 0.0), (0.05, 0.03), (0.1, 0.05))
PIXEL_SCALES = (1.0, 0.75, 0.5)
#: Settings are (centre_along_std m, centre_across_std m, pixel scale k).
SHIPPED = (0.0, 0.0, 1.0)
#: Protocol 2: t along the line between protocol 1's flat settings FLAT_FROM and FLAT_TO.
LINE_T = (0.3, 0.4, 0.5)
FLAT_FROM, FLAT_TO = (0.05, 0.03, 0.5), (0.1, 0.05, 1.0)


def on_line(t: float) -> tuple[float, float, float]:
    """Protocol 2's setting at `t` (rounded to 1e-4)."""
    return tuple(round(a + t * (b - a), 4) for a, b in zip(FLAT_FROM, FLAT_TO, strict=True))  # type: ignore[return-value]


SHIPPED_SETS = [
    "detector.conf_threshold=0.45",
    "camera.start_confidence=0.5",
    "camera.vessel_along_std=0.5",
    "camera.vessel_across_std=0.3",
]
#: Range bins (m) of the camera-NIS spread in the choice rule.
RANGE_BINS = (0.0, 7.5, 12.5, 20.0)
WEIGHTS = Path(__file__).resolve().parents[1] / "python/usvfast/data/models/harbour-demo.onnx"


def sets(rec: Path, along: float, across: float, k: float) -> list[str]:
    """The `--set` overrides of the setting (centre stds `along`, `across` m, pixel scale `k`)."""
    cam = tomllib.loads((rec / "recording.toml").read_text())["camera"]
    u, v = (k * float(x) for x in cam["pixel_sigma_uv"])
    return [
        *SHIPPED_SETS,
        f"camera.centre_along_std={along}",
        f"camera.centre_across_std={across}",
        f"camera.pixel_sigma_uv=[{u:.6g}, {v:.6g}]",
    ]


def camera_nis_by_range(run_dir: Path) -> pd.DataFrame:
    """The floats' camera updates of a run: range (m, USV to track) and NIS. Tracks whose
    median speed exceeds 0.6 m/s are the vessels' and left out."""
    inn = pd.read_csv(run_dir / "innovations.csv")
    tracks = pd.read_csv(run_dir / "tracks.csv")
    nav = pd.read_csv(run_dir / "nav.csv")
    speed = np.hypot(tracks.v_north, tracks.v_east).groupby(tracks.track_id).median()
    m = inn[inn.sensor == "camera"].merge(
        tracks[["time", "track_id", "north", "east"]], on=["time", "track_id"]
    )
    m = m[m.track_id.map(speed) <= 0.6]
    dn = m.north - np.interp(m.time, nav.time, nav.north)
    de = m.east - np.interp(m.time, nav.time, nav.east)
    return pd.DataFrame({"range": np.hypot(dn, de), "nis": m.nis})


def nis_spread(frames: list[pd.DataFrame]) -> tuple[float, list[float]]:
    """max - min of the pooled camera NIS means over RANGE_BINS, and the means."""
    a = pd.concat(frames)
    means = [
        float(a.nis[(a.range > lo) & (a.range <= hi)].mean()) for lo, hi in pairwise(RANGE_BINS)
    ]
    return max(means) - min(means), means


def choose(grid: dict[tuple[float, float, float], dict[str, Any]]) -> tuple[float, float, float]:
    """The choice rule of the module doc over {(along, across, k): totals + "spread"}."""
    base = grid[SHIPPED]
    ok = [
        (-t["anis_inside"], t["spread"], t["rmse_mean"], along, across, -k)
        for (along, across, k), t in grid.items()
        if decide(base, t)[0] and t["tracked"] >= base["tracked"]
    ]
    best = min(ok)
    pick = (best[3], best[4], -best[5])
    return pick if grid[pick]["anis_inside"] > base["anis_inside"] else SHIPPED


def main(argv: list[str] | None = None) -> None:
    """Simulate, run and tabulate (module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", type=Path, required=True, help="recordings and runs go here")
    ap.add_argument("--seeds", type=int, nargs="+", default=list(HELDOUT_SEEDS))
    ap.add_argument("--scored", action="store_true", help="allow scored / fresh seeds")
    ap.add_argument(
        "--setting", type=float, nargs=3, metavar=("ALONG", "ACROSS", "K"), help="one setting"
    )
    ap.add_argument("--line", action="store_true", help="protocol 2's settings")
    args = ap.parse_args(argv)
    banned = sorted(set(args.seeds) & SCORED_SEEDS)
    if banned and not args.scored:
        raise ValueError(f"--seeds: {banned} are scored / fresh seeds (--scored after the choice)")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    if args.setting:
        grid = [tuple(args.setting)]
    elif args.line:
        grid = [SHIPPED, *(on_line(t) for t in LINE_T)]
    else:
        grid = [(a, c, k) for a, c in CENTRE_STDS for k in PIXEL_SCALES]
    rows: dict[tuple, list[dict[str, Any]]] = {s: [] for s in grid}
    nis: dict[tuple, list[pd.DataFrame]] = {s: [] for s in grid}
    print(HEADER.replace("| weights |", "| centre along / across m, k |"))
    runs = grid_runs(
        args.work,
        args.seeds,
        grid,
        WEIGHTS,
        lambda s: f"centre-{s[0]:g}-{s[1]:g}-k{s[2]:g}",
        lambda rec, s: sets(rec, *s),
    )
    for seed, (along, across, k), out in runs:
        f = figures(out)
        rows[(along, across, k)].append(f)
        nis[(along, across, k)].append(camera_nis_by_range(out))
        print(row(seed, f"{along:g} / {across:g}, {k:g}", f), flush=True)
    sums: dict[tuple, dict[str, Any]] = {}
    print(
        "\n| centre along / across m | k | detectable floats | floats | f+w+m | seeds RMSE <= 0.3 "
        "| mean float RMSE m | seeds ANIS in band | camera NIS by range 0-7.5 / 7.5-12.5 / "
        "12.5-20 m | spread |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    )
    for (along, across, k), r in rows.items():
        t = totals(r)
        t["spread"], means = nis_spread(nis[(along, across, k)])
        sums[(along, across, k)] = t
        print(
            f"| {along:g} / {across:g} | {k:g} | {t['det_tracked']} / {t['det_targets']} | "
            f"{t['tracked']} / {t['targets']} | {t['fwm']} | {t['rmse_ok']} | "
            f"{t['rmse_mean']:.4f} | {t['anis_inside']} | "
            f"{' / '.join(f'{x:.2f}' for x in means)} | {t['spread']:.2f} |"
        )
    if SHIPPED in sums and len(sums) > 1 and set(args.seeds) == set(HELDOUT_SEEDS):
        pick = choose(sums)
        for s, t in sums.items():
            ok, lines = decide(sums[SHIPPED], t)
            if not ok or t["tracked"] < sums[SHIPPED]["tracked"]:
                print(f"{s} fails: {[x for x in lines if x.endswith('False')]}")
        print(f"decision: {'KEEP the shipped setting' if pick == SHIPPED else f'ADOPT {pick}'}")
    if not all(math.isfinite(t["spread"]) for t in sums.values()):
        print("note: a range bin without camera updates (spread NaN)")


if __name__ == "__main__":
    main()
