"""Whether the simulator's template declares its receiver's degraded fixes and the heading's
interpolation error (`[recording] fix_quality_std`, `heading_acceleration_std`): the pipeline's
figures on the held-out simulated recordings for a small grid, and a choice rule fixed in
advance.

    python benches/nav_errors_heldout.py --work DIR

Protocol (declared and committed before any of its runs). Premise, from the shipped setting's
runs of the held-out seeds:

- three of the ten held-out recordings (4, 10, 11) have a GNSS outage (1.4-1.7 s without any
  sentence), after which the simulated receiver reports RTK float (GGA quality 5) for 3 s
  with 0.10 m of extra white noise per fix; the pipeline took those fixes as RTK fixed and
  interpolated position and heading linearly across the outage (heading off by up to 0.8°
  and 1.5° on seeds 10 and 11 against the simulator's true heading);
- the NIS of every track's updates in those windows is 2.6-3.7 where elsewhere it is
  1.6-2.0, and seeds 10 and 11 are two of the three held-out seeds whose float ANIS lies
  above its band;
- one run with `fix_quality_std = [[5, 0.1]]` (the receiver's own figure, added in full: the
  LiDAR's four-rotation clusters and the interpolation between independent fixes average
  part of a white error away) took the window NIS to 0.7-1.2.

The setting: `[recording] fix_quality_std = [[5, s]]` (m) and `heading_acceleration_std = h`
(deg/s²), everything else as shipped. The grid: s in {0.03, 0.05, 0.07, 0.1} x h in {0, 1.5},
beside the shipped setting (neither key).

The seeds: held out 4, 5, 6, 8, 9, 10, 11, 12, 13, 14; the scored and fresh seeds (1, 2, 3, 7,
15-27) are refused before the decision (`--scored` after it). The windows: per recording, from
the last RTK-fixed fix before each gap of more than 0.3 s between fixes or before each run of
fixes of another quality, to 0.1 s after the run's last fix (read from the recording's NMEA);
the window NIS is the mean NIS of every track's updates inside the windows, pooled over the
ten seeds. A setting passes when clauses (a)-(d) of benches/demo_detector_heldout.py hold
against the shipped setting and all floats tracked >= the shipped setting's. Choice among
passing settings: the window NIS closest to 1.907 (a consistent filter's gated ANIS), then the
smaller root mean square of (float ANIS - expected) / half the band's width over the seeds.
It replaces the shipped setting only when its window NIS is closer to 1.907 than the shipped
setting's; then the simulator's template and the bundled recording take it and the scored and
fresh seeds are run once with `--scored`.

Result (run once after the protocol's commit), summed over the ten seeds (the window NIS pooled
over the outage seeds 4, 10, 11):

| std m | heading °/s² | floats | f+w+m | float RMSE m | ANIS in band | rms z | window NIS (n) |
| --- | --- | --- | --- | --- | --- | --- | --- |
| 0 (shipped) | 0 | 103 / 103 | 0 | 0.1623 | 6 | 1.09 | 2.816 (233) |
| 0.03 | 0 | 103 / 103 | 0 | 0.1619 | 7 | 0.91 | 2.232 (251) |
| 0.03 | 1.5 | 103 / 103 | 0 | 0.1637 | 6 | 0.94 | 2.092 (273) |
| 0.05 | 0 | 103 / 103 | 0 | 0.1620 | 6 | 0.91 | 1.917 (284) |
| 0.05 | 1.5 | 103 / 103 | 0 | 0.1637 | 6 | 1.01 | 1.876 (304) |
| 0.07 | 0 | 103 / 103 | 0 | 0.1617 | 7 | 0.89 | 1.608 (293) |
| 0.07 | 1.5 | 103 / 103 | 0 | 0.1633 | 7 | 0.93 | 1.600 (312) |
| 0.1 | 0 | 103 / 103 | 0 | 0.1613 | 6 | 0.95 | 1.297 (307) |
| 0.1 | 1.5 | 103 / 103 | 0 | 0.1628 | 6 | 1.00 | 1.292 (320) |

ADOPT (0.05, 0): seed 10 enters its band (2.113 -> 1.906), seed 4 leaves it (1.790 -> 1.743),
11 comes closer (2.194 -> 2.080, upper 2.066). Scored and fresh seeds, run once with
`--scored`: 1, 2, 3, 7 and 17 have no outage and are unchanged to the digit; 15 and 16: window
NIS 2.37 / 2.10 -> 1.91 / 1.97, float ANIS 1.837 / 1.779 -> 1.789 / 1.769 (both in band), RMSE
0.173 / 0.285 -> 0.169 / 0.282 m.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from demo_detector_heldout import HELDOUT_SEEDS, SCORED_SEEDS, decide, figures, grid_runs, totals
from sensor_offsets_heldout import consistency

WEIGHTS = Path(__file__).resolve().parents[1] / "python/usvfast/data/models/harbour-demo.onnx"
#: Settings are (RTK-float std m, heading acceleration std deg/s²); None: the shipped setting.
SHIPPED = (0.0, 0.0)
GRID = [(s, h) for s in (0.03, 0.05, 0.07, 0.1) for h in (0.0, 1.5)]
#: Seeds never run before the decision: the scored, the fresh and the band-check seeds.
BANNED = SCORED_SEEDS | set(range(18, 28))
EXPECTED_ANIS = 1.907
GAP_S = 0.3


def sets(setting: tuple[float, float]) -> list[str]:
    """The `--set` overrides of a setting."""
    s, h = setting
    out = [f"recording.fix_quality_std=[[5, {s:g}]]"] if s > 0 else []
    return out + ([f"recording.heading_acceleration_std={h:g}"] if h > 0 else [])


def degraded_windows(rec: Path) -> list[tuple[float, float]]:
    """The module doc's windows (UNIX s) of the recording `rec`, from its GNSS NMEA topic."""
    from usvfast.nav.bags import read_bag_nmea

    fix = read_bag_nmea(rec / "bag", "/gnss/nmea").log.positions
    t, q = np.asarray(fix.time), np.asarray(fix.fix_quality)
    out, i = [], 0
    while i < len(t) - 1:
        if q[i] == 4 and (t[i + 1] - t[i] > GAP_S or q[i + 1] != 4):
            j = i + 1
            while j < len(t) and q[j] != 4:
                j += 1
            end = t[j - 1] + 0.1 if j - 1 > i else t[i + 1]
            out.append((float(t[i]), float(end)))
            i = j
        else:
            i += 1
    return out


def window_nis(run_dir: Path, windows: list[tuple[float, float]]) -> list[float]:
    """The NIS of every track's updates inside `windows` (innovations.csv of `run_dir`)."""
    with open(run_dir / "innovations.csv", newline="") as fh:
        rows = [(float(r["time"]), float(r["nis"])) for r in csv.DictReader(fh)]
    return [n for t, n in rows if any(a < t <= b for a, b in windows)]


def main(argv: list[str] | None = None) -> None:
    """Simulate, run and tabulate (module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", type=Path, required=True, help="recordings and runs go here")
    ap.add_argument("--seeds", type=int, nargs="+", default=list(HELDOUT_SEEDS))
    ap.add_argument("--scored", action="store_true", help="allow scored / fresh seeds")
    ap.add_argument("--setting", type=float, nargs=2, metavar=("S", "H"), help="one setting")
    args = ap.parse_args(argv)
    banned = sorted(set(args.seeds) & BANNED)
    if banned and not args.scored:
        raise ValueError(f"--seeds: {banned} are scored / fresh seeds (--scored after the choice)")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    grid = [tuple(args.setting)] if args.setting else [SHIPPED, *GRID]
    rows: dict[Any, list[dict[str, Any]]] = {s: [] for s in grid}
    zs: dict[Any, list[float]] = {s: [] for s in grid}
    nis: dict[Any, list[float]] = {s: [] for s in grid}
    print(
        "| seed | float std m, heading deg/s² | floats | RMSE m | ANIS | in band | window NIS (n) |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- |")
    runs = grid_runs(
        args.work,
        args.seeds,
        grid,
        WEIGHTS,
        lambda s: f"nav-{s[0]:g}-{s[1]:g}",
        lambda _, s: sets(s),
    )
    for seed, setting, out in runs:
        fig = figures(out)
        win = window_nis(out, degraded_windows(args.work / "rec" / f"s{seed}"))
        rows[setting].append(fig)
        zs[setting].append(consistency(out)["z"])
        nis[setting] += win
        mean = f"{np.mean(win):.2f} ({len(win)})" if win else "– (0)"
        print(
            f"| {seed} | {setting[0]:g}, {setting[1]:g} | {fig['tracked']} / {fig['targets']} | "
            f"{fig['rmse']:.3f} | {fig['anis']:.3f} | {fig['anis_inside']} | {mean} |",
            flush=True,
        )
    print(
        "\n| float std m | heading deg/s² | detectable floats | floats | f+w+m | mean float RMSE m "
        "| seeds ANIS in band | rms z | window NIS (n) |\n| --- | --- | --- | --- | --- | --- | "
        "--- | --- | --- |"
    )
    sums = {}
    for s, r in rows.items():
        t = totals(r)
        t["rms_z"] = math.sqrt(sum(z * z for z in zs[s]) / len(zs[s]))
        t["window"] = float(np.mean(nis[s])) if nis[s] else math.nan
        sums[s] = t
        print(
            f"| {s[0]:g} | {s[1]:g} | {t['det_tracked']} / {t['det_targets']} | "
            f"{t['tracked']} / {t['targets']} | {t['fwm']} | {t['rmse_mean']:.4f} | "
            f"{t['anis_inside']} | {t['rms_z']:.2f} | {t['window']:.3f} ({len(nis[s])}) |"
        )
    if SHIPPED in sums and len(sums) > 1 and set(args.seeds) == set(HELDOUT_SEEDS):
        base = sums[SHIPPED]
        ok = [
            (abs(t["window"] - EXPECTED_ANIS), t["rms_z"], s)
            for s, t in sums.items()
            if s != SHIPPED and decide(base, t)[0] and t["tracked"] >= base["tracked"]
        ]
        pick = min(ok)[2] if ok else SHIPPED
        if abs(sums[pick]["window"] - EXPECTED_ANIS) >= abs(base["window"] - EXPECTED_ANIS):
            pick = SHIPPED
        print(f"decision: {'KEEP the shipped setting' if pick == SHIPPED else f'ADOPT {pick}'}")


if __name__ == "__main__":
    main()
