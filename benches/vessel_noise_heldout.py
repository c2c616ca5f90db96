"""Whether the vessel tracker's noise settings change: the pipeline's vessel figures on the
held-out simulated recordings for a small grid, and a choice rule fixed in advance.

    python benches/vessel_noise_heldout.py --work DIR

Protocol (declared and committed before any of its runs). Premise: with the shipped settings
the moving vessels' tracks are far more cautious than their errors. On the ten held-out
seeds (benches/demo_detector_heldout.py's runs of the shipped setting) the vessel tracks'
pooled NIS is 0.50 from the camera (132 updates) and 0.62 from the LiDAR (48), against the
1.91 a consistent filter gives under the 0.99 gate; no seed's vessel ANIS lies in its band,
and the demo's vessel ANEES is 0.7. The floats' NIS, pooled by kind and sensor, lies at
1.72-2.08: the misfit is the vessels'. Two settings shape the vessel tracks' covariance:
`tracker.vessel_q` (process noise, m²/s³: P between updates) and the camera's vessel
detections' `camera.vessel_along_std` / `vessel_across_std` (m, added along / across the line
of sight: R).

- Recordings: the held-out seeds 4, 5, 6, 8, 9, 10, 11, 12, 13, 14 of
  benches/demo_detector_heldout.py (`usvfast simulate --seed S --duration 30`; reused when
  present), each run with the shipped detector settings (`--set
  detector.conf_threshold=0.45 --set camera.start_confidence=0.5`: the recordings were
  simulated before the template carried them) and the bundled demo network.
- Grid: vessel_q in {0.05 (shipped), 0.02, 0.01} x camera vessel stds scaled by k in
  {1.0 (shipped: 1.0 / 0.6 m), 0.7}. Everything else unchanged. The scored seeds 1, 2, 3, 7
  and fresh 15, 16, 17 are refused before the decision (`--scored` after it).
- A setting passes when, summed over the ten seeds, (a) vessels tracked >= the shipped
  setting's, (b) false + wall + moored-boat tracks <= its, (c) the mean vessel RMSE over the
  seeds with a vessel track <= its + 0.05 m, (d) floats tracked >= its.
- Choice among passing settings: the most seeds with the vessel ANIS inside its gated 95 %
  band, then the most seeds with the all-targets ANIS inside its band, then the lower mean
  vessel RMSE, then the shipped values' side (higher q, then higher k). It replaces the
  shipped setting only with strictly more seeds with the vessel ANIS in band; then the
  simulator's template and the bundled recording take it and the scored and fresh seeds
  are run once with `--scored`.

Result (run once after the protocol's commit): summed over the ten seeds,

| vessel_q | k | vessels | f+w+m | vessel RMSE m | floats | vessel ANIS in | all ANIS in |
| --- | --- | --- | --- | --- | --- | --- | --- |
| 0.05 (shipped) | 1.0 | 8 | 0 | 0.8170 | 103 | 0 | 7 |
| 0.05 | 0.7 | 8 | 0 | 0.9043 | 103 | 0 | 7 |
| 0.02 | 1.0 | 8 | 0 | 0.8300 | 103 | 0 | 7 |
| 0.02 | 0.7 | 8 | 0 | 0.8356 | 103 | 0 | 7 |
| 0.01 | 1.0 | 8 | 0 | 0.8961 | 103 | 0 | 7 |
| 0.01 | 0.7 | 8 | 0 | 0.8386 | 103 | 0 | 7 |

No setting puts any seed's vessel ANIS in its band (0.23-0.97 against lower ends 0.97-1.43):
KEEP the shipped setting. Why (one run each of held-out seeds 12 and 5, the prediction from
each track's previous state): the squared innovations are far below the covariance's trace
— LiDAR vessel updates 0.10 m² (seed 12) and 0.75 m² (seed 5) against tr HPHᵀ 0.37 / 0.83 +
tr R 0.28; camera vessel updates 0.31 m² against tr HPHᵀ 0.69 + tr R 1.42. The camera's
vessel detections err about the truth by 1.24 / 0.50 m rms (the R was set from that), but
that error is a slowly changing offset of each hull, not noise from frame to frame: it
cancels in the innovations and inflates P. Neither a smaller process noise nor a smaller R
(0.7x) models that; a per-track offset state, as the floats' camera offset, would.

Protocol 2 (declared and committed before any of its runs, after the result above):

    python benches/vessel_noise_heldout.py --work DIR --offset

- The vessel tracker gets the floats' per-track camera offset (`tracker.vessel_camera_offset_std`
  o m, random walk `tracker.camera_offset_q` unchanged at 0.001 m²/s; the state [n, v_n, e,
  v_e, b_n, b_e], b seen by the camera only). With the offset in the state, the camera's vessel
  detections keep less of their error as white noise: their stds are scaled by k.
- Grid: o in {0 (shipped), 1.0} x k in {1.0 (shipped), 0.5}; vessel_q 0.05 as shipped; the same
  seeds, detector settings, clauses (a)-(d), choice rule and adoption condition (strictly more
  seeds with the vessel ANIS in band than the shipped setting) as protocol 1.

Result of protocol 2 (run once after its commit): summed over the ten seeds,

| offset m | k | vessels | f+w+m | vessel RMSE m | floats | vessel ANIS in | all ANIS in |
| --- | --- | --- | --- | --- | --- | --- | --- |
| 0 (shipped) | 1.0 | 8 | 0 | 0.8170 | 103 | 0 | 7 |
| 0 | 0.5 | 8 | 0 | 0.8389 | 103 | 2 | 6 |
| 1.0 | 1.0 | 8 | 0 | 0.7845 | 103 | 0 | 7 |
| 1.0 | 0.5 | 8 | 0 | 0.8712 | 103 | 2 | 6 |

Passing: (0, 1.0), (0, 0.5), (1.0, 1.0) ((1.0, 0.5) fails (c): 0.871 > 0.867 m). Chosen and
adopted: no offset, the camera's vessel stds halved (0.5 / 0.3 m; 2 seeds with the vessel ANIS
in band against 0; seeds 10 and 13). Scored once after, seeds 7, 1, 2, 3, 15, 16, 17: vessel
ANIS 0.861 / 0.948 / 1.131 / 0.184 / 0.637 / 1.567 (in) / 0.487, all-targets ANIS inside on 6
of 7 seeds (3 before), floats unchanged, vessel RMSE 0.517 / 1.044 / 0.764 / 0.367 / 0.559 /
0.635 / 0.500 m (0.400 / 1.011 / 0.797 / 0.367 / 0.607 / 0.569 / 0.588 before).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from demo_detector_heldout import HELDOUT_SEEDS, SCORED_SEEDS, grid_runs

#: The grid: tracker.vessel_q values and scales of the camera's vessel stds (1.0 / 0.6 m).
VESSEL_Q = (0.05, 0.02, 0.01)
STD_SCALES = (1.0, 0.7)
SHIPPED = (0.05, 1.0)
#: Protocol 2: vessel camera-offset stds (m) and scales of the camera's vessel stds.
OFFSET_STDS = (0.0, 1.0)
OFFSET_SCALES = (1.0, 0.5)
SHIPPED_DETECTOR = ["detector.conf_threshold=0.45", "camera.start_confidence=0.5"]
RMSE_SLACK_M = 0.05
WEIGHTS = Path(__file__).resolve().parents[1] / "python/usvfast/data/models/harbour-demo.onnx"


def sets(q: float, k: float, offset: float | None = None) -> list[str]:
    """The `--set` overrides of the setting (q, k) (protocol 2: `offset` m)."""
    out = [
        *SHIPPED_DETECTOR,
        f"tracker.vessel_q={q}",
        f"camera.vessel_along_std={1.0 * k:.6g}",
        f"camera.vessel_across_std={0.6 * k:.6g}",
    ]
    if offset is not None:
        out.append(f"tracker.vessel_camera_offset_std={offset}")
    return out


def figures(run_dir: Path) -> dict[str, Any]:
    """The protocol's per-seed figures from `run_dir`/metrics.json."""
    m = json.loads((run_dir / "metrics.json").read_text())
    ves, floats = m["groups"]["vessels"], m["groups"]["floats"]
    anis = ves.get("anis") or {}
    walls = m["walls"]
    return {
        "vessels": ves["targets_tracked"],
        "vessel_targets": ves["n_targets"],
        "vessel_rmse": ves.get("rmse"),
        "vessel_anis": anis.get("mean"),
        "vessel_band": (anis.get("lower"), anis.get("upper")),
        "vessel_in": bool(anis.get("inside", False)),
        "all_anis": m["thesis"]["anis"]["mean"],
        "all_in": bool(m["thesis"]["anis"]["inside"]),
        "floats": floats["targets_tracked"],
        "fwm": len(m["thesis"]["false_tracks"])
        + len(walls["tracks_on_walls"])
        + len(walls["tracks_on_moored_boats"]),
    }


def totals(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The sums of the rule over one setting's seeds."""
    rmse = [r["vessel_rmse"] for r in rows if r["vessel_rmse"] is not None]
    return {
        "vessels": sum(r["vessels"] for r in rows),
        "fwm": sum(r["fwm"] for r in rows),
        "rmse_mean": sum(rmse) / len(rmse) if rmse else math.inf,
        "floats": sum(r["floats"] for r in rows),
        "vessel_in": sum(r["vessel_in"] for r in rows),
        "all_in": sum(r["all_in"] for r in rows),
    }


def passes(base: dict[str, Any], t: dict[str, Any]) -> bool:
    """Clauses (a)-(d) of the module doc."""
    return (
        t["vessels"] >= base["vessels"]
        and t["fwm"] <= base["fwm"]
        and t["rmse_mean"] <= base["rmse_mean"] + RMSE_SLACK_M
        and t["floats"] >= base["floats"]
    )


def choose(
    grid: dict[tuple[float, float], dict[str, Any]], shipped: tuple[float, float] = SHIPPED
) -> tuple[float, float]:
    """The choice rule of the module doc over {setting: totals} (protocol 1: (q, k); 2: (o, k),
    the shipped one `shipped`; ties go to the higher first, then second value)."""
    base = grid[shipped]
    ok = [
        (-t["vessel_in"], -t["all_in"], t["rmse_mean"], -q, -k)
        for (q, k), t in grid.items()
        if passes(base, t)
    ]
    best = min(ok)
    pick = (-best[3], -best[4])
    return pick if grid[pick]["vessel_in"] > base["vessel_in"] else shipped


def _fmt(x: float | None) -> str:
    return "–" if x is None or not math.isfinite(x) else f"{x:.3f}"


def main(argv: list[str] | None = None) -> None:
    """Simulate, run and tabulate (module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", type=Path, required=True, help="recordings and runs go here")
    ap.add_argument("--seeds", type=int, nargs="+", default=list(HELDOUT_SEEDS))
    ap.add_argument("--scored", action="store_true", help="allow scored / fresh seeds")
    ap.add_argument(
        "--setting", type=float, nargs=2, metavar=("Q", "K"), default=None, help="one setting only"
    )
    ap.add_argument("--offset", action="store_true", help="protocol 2's grid (offset std, k)")
    args = ap.parse_args(argv)
    banned = sorted(set(args.seeds) & SCORED_SEEDS)
    if banned and not args.scored:
        raise ValueError(f"--seeds: {banned} are scored / fresh seeds (--scored after the choice)")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    if args.offset:
        grid = [(o, k) for o in OFFSET_STDS for k in OFFSET_SCALES]
        shipped = (0.0, 1.0)
    else:
        grid = (
            [tuple(args.setting)]
            if args.setting
            else [(q, k) for q in VESSEL_Q for k in STD_SCALES]
        )
        shipped = SHIPPED
    first = "offset m" if args.offset else "q"
    rows: dict[tuple[float, float], list[dict[str, Any]]] = {s: [] for s in grid}
    print(
        f"| seed | {first} | k | vessels | vessel RMSE m | vessel ANIS [band] | all-targets ANIS | "
        "floats | f+w+m |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    )
    runs = grid_runs(
        args.work,
        args.seeds,
        grid,
        WEIGHTS,
        lambda s: f"vessel-{'o' if args.offset else 'q'}{s[0]:g}-k{s[1]:g}",
        lambda _, s: sets(SHIPPED[0], s[1], s[0]) if args.offset else sets(*s),
    )
    for seed, (q, k), out in runs:
        f = figures(out)
        rows[(q, k)].append(f)
        lo, hi = f["vessel_band"]
        va = _fmt(f["vessel_anis"])
        print(
            f"| {seed} | {q:g} | {k:g} | {f['vessels']} / {f['vessel_targets']} | "
            f"{_fmt(f['vessel_rmse'])} | {va if f['vessel_in'] else f'**{va}**'} "
            f"[{_fmt(lo)}, {_fmt(hi)}] | {f['all_anis']:.3f} {'in' if f['all_in'] else 'out'} "
            f"| {f['floats']} | {f['fwm']} |",
            flush=True,
        )
    sums = {s: totals(r) for s, r in rows.items()}
    print(f"\n| {first} | k | vessels | f+w+m | vessel RMSE m | floats | vessel ANIS in | all in |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for (q, k), t in sums.items():
        print(
            f"| {q:g} | {k:g} | {t['vessels']} | {t['fwm']} | {t['rmse_mean']:.4f} | "
            f"{t['floats']} | {t['vessel_in']} | {t['all_in']} |"
        )
    if shipped in sums and len(sums) > 1 and set(args.seeds) == set(HELDOUT_SEEDS):
        pick = choose(sums, shipped)
        print(f"passing: {[s for s, t in sums.items() if passes(sums[shipped], t)]}")
        print(f"decision: {'KEEP the shipped setting' if pick == shipped else f'ADOPT {pick}'}")


if __name__ == "__main__":
    main()
