"""A held-out (2-fold) figure for the shipped Joyride preset `joyride`: the search of
benches/search_joyride_presets.py run from `joyride` on one half of the recording (scans 0-118,
then 119-237) and its best setting scored on the other, held-out half; then how flat the
shipped preset's neighbourhood is.

Decided before any held-out figure was seen (and not changed after):
- two search variants, both from the shipped `joyride`, --runs hill-climbing runs per seed:
  "full": every numeric setting perturbed, log-normal scale 0.3 then 0.1, the search's score
  (coverage aim 96 %, false tracks over 2 penalised);
  "reg" (regularised): only q, prob_detect, clutter_density, ct_q and ct_q_turn perturbed,
  scale 0.1 then 0.033, scored with a margin (coverage aim 97 %, false tracks over 1
  penalised).
- per fold and variant, seeds 0, 1, 2; the seed with the lowest in-sample score (the variant's
  own score on the tuning half) gives that variant's setting (marked *). "reg" is the
  primary recipe; "full" is reported beside it; no choice is made between them by held-out
  figures.
- the shipped preset would be replaced only by the "reg" recipe, and only if both folds' "reg"
  settings meet all four aims (RMSE <= 20.5 m, coverage >= 96 %, 1 fragment, <= 2 false
  tracks) on their held-out half; the recipe is then run on the whole recording and its
  setting must meet the aims there too (printed only in that case).
- flatness: 200 draws of the shipped preset with every searched setting perturbed
  log-normally at scale 0.05 (seed 0; probabilities near one have 1 - p perturbed), and 200
  with only the five "reg" settings perturbed: the fraction meeting all four aims over the
  whole recording, and each aim alone.

Each part is scored from one run over all 238 scans (the tracker sees every plot; only the
scoring is split). Time per scan: best wall clock of 30 tracker runs.

Result (--runs 1500: 18,000 search runs at ~4 ms each, 80 s in all), RMSE m / coverage % /
fragments / false tracks; no held-out figure meets all four aims:
- shipped `joyride`, tuned on all scans (in-sample): all 20.43 / 96.6 / 1 / 2; scans 0-118
  22.91 / 96.6 / 1 / 0; scans 119-237 17.61 / 96.6 / 1 / 2.
- "reg" tuned on 0-118: in-sample 22.88 / 96.6 / 1 / 0, held-out 119-237 18.29 / 94.1 / 1 / 2
  (coverage misses); tuned on 119-237: in-sample 18.00 / 97.5 / 1 / 2, held-out 0-118
  23.39 / 96.6 / 1 / 0 (RMSE misses). Both halves held out together: 21.03 / 95.4 (1 fragment
  and 0 / 2 false tracks per half).
- "full" tuned on 0-118: in-sample 22.23 / 96.6 / 1 / 2, held-out 21.82 / 94.1 / 1 / 6; tuned
  on 119-237: in-sample 17.28 / 96.6 / 1 / 2, held-out 23.39 / 94.1 / 2 / 0. Together 22.62 /
  94.1. It moves settings by up to 7x and its held-out figures swing from seed to seed.
- No searched setting reaches 20.5 m on scans 0-118 even in-sample (best 22.23 m): that half is
  the harder one; RMSE <= 20.5 m on it held out was out of reach of these searches.
- flatness: 34.5 % of the 5 % draws of every setting meet all four aims on all scans (51.5 %
  of the five-setting draws); every miss is an RMSE miss (median 20.54 m; coverage, fragments,
  false tracks hold in >= 99.5 %): the 20.43 m sits 0.07 m under the aim on a sharp optimum.
The shipped preset is unchanged (the "reg" recipe misses the aims on both held-out halves).

`--calibrated` adds the FULLY held-out figure of a calibrated radar, as a deployment would get
it: a one-off installation calibration against a reference target, then tuning on that
calibration's data. Decided and committed before any of its figures was run (and not changed
after); for each fold A -> B (A = scans 0-118 and B = 119-237, then the reverse):
1. calibration on half A only: the bearing bias b_A of `usvfast.radar.bearing_bias_deg` (per
   scan of A the plot nearest the target's GNSS position within 60 m, the least-squares turn
   of those plots about the own ship); every plot of the recording is then turned by
   `bearing_correction_deg = -b_A` (the tracker still sees all 238 scans, as above);
2. tuning on half A: the same search as the uncalibrated folds (the code above, not a second
   copy), started from the shipped `joyride` plus that correction (the correction itself is
   not searched); "reg" is the primary recipe, "full" is reported beside it; seeds 0, 1, 2,
   --runs 1500 per seed (as the uncalibrated figures); the seed with the lowest in-sample
   score (the variant's own score on A) gives that variant's setting (marked *); no choice is
   made by held-out figures;
3. scoring on half B: that setting with the same A-calibration.
Reported: per fold the start (shipped settings + b_A, whose settings saw the whole recording:
not a held-out figure), then per variant and seed the in-sample (A) and held-out (B) RMSE /
coverage / fragments / false tracks, the chosen setting's time per scan, both held-out halves
pooled, and whether "reg" meets all four aims (RMSE <= 20.5 m, coverage >= 96 %, 1 fragment,
<= 2 false tracks) on each held-out half. The uncalibrated 2-fold
is run again in the same process for comparison (the flatness part is skipped with
--calibrated). This part changes no preset (the shipped `joyride` is for an uncalibrated radar;
a calibrated installation brings its own calibration); if the calibrated "reg" settings meet
all four aims on both held-out halves, they are written into a test with their held-out figures
(tests/test_joyride_errors.py); if not, the misses are reported as measured.

Result of --calibrated (--runs 1500; the same run reproduced the uncalibrated figures above
exactly; 3 min under nice on a shared machine), RMSE m / coverage % / fragments / false tracks:
- calibration: b = -2.0202 degrees on scans 0-118, -1.6014 on 119-237.
- start (shipped settings + b_A, settings tuned on all scans, so not held out): calibrated on
  0-118, 17.57 / 98.3 / 1 / 0 there and 18.57 / 98.3 / 1 / 2 on 119-237; calibrated on
  119-237, 17.08 / 97.5 / 1 / 2 there and 17.88 / 98.3 / 1 / 0 on 0-118.
- "reg" calibrated and tuned on 0-118 (seed 0): in-sample 17.37 / 97.5 / 1 / 0, held-out
  119-237 16.68 / 95.0 / 1 / 2: coverage MISSES (113 of 119 scans, 115 needed; the three
  seeds give 95.0 / 95.8 / 95.0 % there). It moved P_D 0.725 -> 0.935 and ct_q_turn 3.7x up
  and loses scans 126, 142 and 214-217 (the start loses 121 and 142).
- "reg" calibrated and tuned on 119-237 (seed 1): in-sample 15.92 / 97.5 / 1 / 2, held-out
  0-118 18.40 / 98.3 / 1 / 0: meets all four aims.
- both held-out halves together: "reg" 17.57 m / 96.6 % (1 fragment a half, 2 + 0 false
  tracks); "full" 18.14 / 91.6 (its chosen settings: 16.48 / 93.3 / 1 / 2 on 119-237 and
  19.71 / 89.9 / 1 / 0 on 0-118).
- time per scan of the chosen "reg" settings: 0.0136 and 0.0134 ms.
The calibrated recipe does not meet the aims on both held-out halves (coverage 95.0 % on
scans 119-237), so no test pins its settings; no preset is changed.

`--estimated` replaces the search by ESTIMATION, as a radar engineer sets a tracker from a
calibration run against a GNSS-logged target. Decided and committed before any of its figures
was run (and not changed after); for each fold A -> B (A = scans 0-118 and B = 119-237, then
the reverse), on half A only, from A's plots and the target's GNSS (positions and velocities:
`target` of the .mat) with `usvfast.radar.calibration` (no tracker run informs any estimate;
no score is searched):
- two variants: "raw" (the plots as recorded) and "calibrated" (every plot turned by -b_A,
  b_A the bearing bias of A as in --calibrated; sigma, P_D and clutter are then measured on
  the turned plots);
- sigma (plot noise, m per axis): `plot_statistics(...).sigma_m`, the median distance of the
  target's plot (per scan the plot nearest the GNSS position, if within 60 m) over
  sqrt(2 ln 2), the Rayleigh median;
- prob_detect and clutter_density (per m^2 per scan): `plot_statistics`' joint method-of-
  moments fit (Poisson clutter): the mean number of plots within 100 m of the GNSS position
  (= P_D + lambda pi 100^2) and the fraction of scans with a plot within 60 m
  (= P_D + (1 - P_D)(1 - exp(-lambda pi 60^2)));
- q (the quiet constant-velocity mode, and tentative tracks) and the manoeuvre mode's cv_q:
  `cv_noise_mixture`, the maximum-likelihood two-mode white-noise-acceleration mixture (EM)
  of A's GNSS velocity increments; the high mode is the component of the manoeuvring
  intervals (the larger intensity);
- ct_q and ct_q_turn (the coordinated turn with the rate in the state): `turn_noise` on A's
  GNSS velocities: the speed increments' maximum-likelihood intensity, and the turn-rate
  increments' moment equation less the cross-track velocity noise (speeds >= 1 m/s);
- everything else kept from the shipped `joyride`, as the search's "reg" variant keeps it:
  prob_gate, delete_steps, initiate_in_gates, the initiator (min_points, delete_steps,
  missed_distance, prior_velocity_var, prior_turn_rate_var), the IMM's cv_q_turn,
  ct_predictor and stay, and the whole existence table;
- scoring: the tracker of those settings over all 238 scans (as above), figures on A
  (in-sample) and on B (HELD OUT); a fold is met when B's figures meet all four aims
  (RMSE <= 20.5 m, coverage >= 96 %, 1 fragment, <= 2 false tracks), a variant when both of
  its folds are; time per scan (aim <= 0.02 ms) reported beside.
Reported: per fold and variant the estimates, the in-sample and held-out figures, the time per
scan, both held-out halves pooled, and whether each variant meets the aims on both held-out
halves; then each variant estimated on the whole recording (bias too) and scored on it:
IN-SAMPLE, labelled so. If a variant meets the aims on both held-out halves a test runs it
(tests/test_joyride_estimated.py, the estimation on A inside the test) and asserts its
held-out figures; no preset is changed either way. The search and the flatness are skipped
with --estimated (their figures are above).

Result of --estimated (run once, after the commit of the protocol above; 3 s), RMSE m /
coverage % / fragments / false tracks; NEITHER VARIANT MEETS THE AIMS on either held-out half:
- estimates on 0-118 / 119-237: sigma raw 17.82 / 9.07 m, calibrated (b_A -2.0202 / -1.6014
  degrees) 11.79 / 5.76 m; P_D 0.864 / 0.745 raw, 0.864 / 0.753 calibrated; clutter
  1.13e-6 / 1.18e-6 per m^2 (8x under the shipped 9.50e-6); q 0.0633 / 0.0590, cv_q 1.79 / 1.40
  (shipped 8.63), ct_q 0.130 / 0.108, ct_q_turn 3.4e-3 / 1.7e-3 (shipped 6.4e-4).
- raw, estimated on 0-118: in-sample 23.60 / 95.0 / 1 / 0, held-out 119-237 21.07 / 88.2 /
  1 / 4; estimated on 119-237: in-sample 18.79 / 92.4 / 1 / 4, held-out 0-118 23.83 / 95.0 /
  4 / 1; pooled held-out 22.54 / 91.6 (5 fragments, 5 false tracks).
- calibrated, estimated on 0-118: in-sample 17.49 / 96.6 / 1 / 0, held-out 119-237 17.29 /
  92.4 / 4 / 3; estimated on 119-237: in-sample 15.92 / 94.1 / 2 / 6, held-out 0-118 21.03 /
  92.4 / 6 / 1; pooled held-out 19.25 / 92.4 (10 fragments, 4 false tracks).
- estimated on all 238 scans, scored on them (IN-SAMPLE): raw 22.02 / 92.0 / 1 / 5 (sigma
  13.74 m, P_D 0.804, clutter 1.15e-6); calibrated (bias -1.8497) 17.85 / 94.1 / 8 / 4
  (sigma 9.18 m, P_D 0.809): they miss even in-sample.
- time per scan 0.0142-0.0201 ms (shared machine; the calibrated 119-237 setting's 0.0201 is
  over the 0.02 aim).
The two halves are not one population: on 119-237 the target is nearer (median range 289 m
against 411 m) and the Rayleigh-median sigma halves, with heavier tails (calibrated RMS per
axis 9.55 m against the median's 5.76 m; 12.83 against 11.79 m on 0-118). A diagnostic run
once after the result (not part of the protocol): putting back any ONE shipped setting in place
of its estimate meets the aims on no held-out half, so the misses are not one estimator's. The
search's figures
(above) stay the better held-out ones: "reg" 21.03 m / 95.4 % raw and 17.57 m / 96.6 %
calibrated, pooled. No test pins estimated settings; no preset is changed.

    USVFAST_SHARED_DATA=/work/shared/data PYTHONPATH=python \\
        nice -n 10 python benches/cv_joyride_preset.py --runs 1500 [--calibrated | --estimated]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_tracker_joyride import HALF, fmt
from search_joyride_presets import figures, perturb, search

from usvfast.datasets import load_joyride
from usvfast.radar import bearing_bias_deg, cv_noise_mixture, plot_statistics, turn_noise
from usvfast.trackcmd import (
    corrected_plots,
    load_config,
    plot_covariances,
    read_plots,
    tracker_from_config,
)

from timing import best_of

# The scales as first run (0.3 / 3 is one ulp below 0.1; kept so the figures reproduce).
VARIANTS = {
    "full": {"scale": (0.3, 0.3 / 3), "few": False, "cover": 0.96, "max_false": 2},
    "reg": {"scale": (0.1, 0.1 / 3), "few": True, "cover": 0.97, "max_false": 1},
}
# (tuning part, index of its figures, index of the held-out figures) in [all, 0-118, 119-237]
FOLDS = (("first", 1, 2), ("second", 2, 1))
SEEDS = (0, 1, 2)
NAMES = {0: "all 238", 1: "scans 0-118", 2: "scans 119-237"}


def meets(q) -> bool:
    """All four track-quality aims: RMSE <= 20.5 m, coverage >= 96 %, 1 fragment, <= 2 false
    tracks."""
    return q.rmse <= 20.5 and q.coverage >= 0.96 and q.fragments == 1 and q.tracks_elsewhere <= 2


def pooled(held: list) -> str:
    """The held-out halves of the two folds put together (238 scans, each scored by the
    setting tuned on the other half): RMSE over the covered scans, coverage, and the sums of
    fragments and of false tracks."""
    e = np.concatenate([q.errors for q in held])
    ok = np.isfinite(e)
    rmse = float(np.sqrt(np.mean(e[ok] ** 2)))
    fr = sum(q.fragments for q in held)
    ft = sum(q.tracks_elsewhere for q in held)
    return f"{rmse:6.2f} {ok.mean() * 100:5.1f} {fr:3d} {ft:3d}"


def ms_per_scan(plots, c: dict) -> float:
    """Best wall clock of 30 tracker runs over the recording, ms per scan."""
    t = plots.times - plots.times[0]
    z, cov = corrected_plots(c, plots), plot_covariances(c, plots)

    def go():
        tr = tracker_from_config(c)
        return tr.run(t, z, plots.sensor, plots.scan_index, covariances=cov)

    best, _ = best_of(go, 30)
    return best / len(plots.times) * 1e3


def flatness(plots, base: dict, draws: int, scale: float, few: bool) -> str:
    """Fractions of `draws` perturbations of `base` meeting all four aims on all scans, and
    each aim alone."""
    rng = np.random.default_rng(0)
    ok = np.zeros((draws, 5), dtype=bool)
    rmse = np.zeros(draws)
    for k in range(draws):
        q = figures(plots, perturb(base, rng, scale, polar=False, few=few))[0]
        rmse[k] = q.rmse
        ok[k] = (
            meets(q),
            q.rmse <= 20.5,
            q.coverage >= 0.96,
            q.fragments == 1,
            q.tracks_elsewhere <= 2,
        )
    f = ok.mean(0) * 100
    return (
        f"all four {f[0]:5.1f} %; RMSE {f[1]:5.1f} %, coverage {f[2]:5.1f} %, "
        f"fragments {f[3]:5.1f} %, false tracks {f[4]:5.1f} %; RMSE 10/50/90th percentile "
        + "/".join(f"{v:.2f}" for v in np.percentile(rmse, [10, 50, 90]))
        + " m"
    )


def part_scans(plots, part: str) -> np.ndarray:
    """The scans of `part`: "first" 0-118, "second" 119-237, "whole" all."""
    lo, hi = {"first": (0, HALF), "second": (HALF, len(plots.times))}.get(
        part, (0, len(plots.times))
    )
    return np.arange(lo, hi)


def calibrated(plots, base: dict, part: str) -> dict:
    """`base` with the plots' bearing bias measured on `part` ("first": scans 0-118, "second":
    119-237, "whole") against the target's GNSS only (`usvfast.radar.bearing_bias_deg`)
    removed by `bearing_correction_deg`: a radar calibrated on that part."""
    bias = bearing_bias_deg(
        plots.plots, plots.scan_index, plots.origins, plots.truth, scans=part_scans(plots, part)
    )
    return base | {"bearing_correction_deg": -bias}


def estimated(plots, velocities: np.ndarray, base: dict, part: str) -> tuple[dict, dict]:
    """`base` (with its bearing correction, if any) with sigma, prob_detect, clutter_density,
    q, the manoeuvre mode's cv_q, ct_q and ct_q_turn ESTIMATED on `part`'s scans from the
    plots the tracker will see and the target's GNSS positions and `velocities` (s, 2) m/s
    (`usvfast.radar.calibration`, see the module doc; no tracker run). Returns the tracker
    table and the estimates with their counts."""
    scans = part_scans(plots, part)
    stats = plot_statistics(
        corrected_plots(base, plots), plots.scan_index, plots.truth, scans=scans
    )
    cv = cv_noise_mixture(plots.times[scans], velocities[scans])
    ct = turn_noise(plots.times[scans], velocities[scans])
    imm = base["imm"] | {"cv_q": [cv.q_high], "ct_q": [ct.q], "ct_q_turn": [ct.q_turn]}
    c = base | {
        "sigma": stats.sigma_m,
        "prob_detect": stats.prob_detect,
        "clutter_density": stats.clutter_density,
        "q": cv.q_quiet,
        "imm": imm,
    }
    return c, {"plots": stats, "cv": cv, "ct": ct}


def show_estimates(e: dict, base: dict) -> str:
    """One line of the estimates of `estimated` (and the bias correction of `base`)."""
    p, cv, ct = e["plots"], e["cv"], e["ct"]
    return (
        f"bearing_correction_deg {base.get('bearing_correction_deg', 0.0):+.4f}; "
        f"sigma {p.sigma_m:.3f} m, P_D {p.prob_detect:.4f} ({p.pairs}/{p.scans} scans paired), "
        f"clutter {p.clutter_density:.3e} /m2 (~{p.clutter_plots} plots in 100 m); "
        f"q {cv.q_quiet:.4g}, cv_q {cv.q_high:.4g} (quiet weight {cv.weight_quiet:.3f}, "
        f"{cv.intervals} intervals), ct_q {ct.q:.4g}, ct_q_turn {ct.q_turn:.4g} "
        f"({ct.rate_increments} rate increments)"
    )


def estimated_two_fold(plots, velocities: np.ndarray, shipped: dict) -> dict:
    """The --estimated protocol (module doc) for both variants: per fold the estimates on A,
    the in-sample (A) and held-out (B) figures and the time per scan, the pooled held-out
    halves and whether each variant meets the aims on both; then the whole-recording
    estimate, in-sample. Returns {variant: held-out figures [fold first, fold second]}."""
    head = "RMSE m  cov%  fr  ft"
    out: dict = {}
    for variant in ("raw", "calibrated"):
        print(f"\nESTIMATED settings, {variant} plots")
        held_out = []
        for part, tune, held in FOLDS:
            base = calibrated(plots, shipped, part) if variant == "calibrated" else shipped
            c, e = estimated(plots, velocities, base, part)
            q = figures(plots, c)
            held_out.append(q[held])
            print(f"  estimated on {NAMES[tune]}: {show_estimates(e, base)}")
            print(
                f"    in-sample {NAMES[tune]} {fmt(q[tune])}   HELD-OUT {NAMES[held]} "
                f"{fmt(q[held])} {'meets' if meets(q[held]) else 'MISSES'} the aims   "
                f"({ms_per_scan(plots, c):.4f} ms/scan)"
            )
        out[variant] = held_out
        print(f"  held-out halves together, {head}: {pooled(held_out)}")
        print(
            f"  {variant}: estimation meets the aims on both held-out halves: "
            f"{all(meets(q) for q in held_out)}"
        )
        base = calibrated(plots, shipped, "whole") if variant == "calibrated" else shipped
        c, e = estimated(plots, velocities, base, "whole")
        q = figures(plots, c)
        print(f"  estimated on all 238 scans: {show_estimates(e, base)}")
        print(
            f"    IN-SAMPLE (estimated and scored on all scans): all {fmt(q[0])} "
            f"{'meets' if meets(q[0]) else 'MISSES'} the aims; halves {fmt(q[1])} / {fmt(q[2])}"
            f"   ({ms_per_scan(plots, c):.4f} ms/scan)"
        )
    return out


def two_fold(plots, bases: dict[str, dict], runs: int) -> tuple[dict, dict]:
    """Each variant's search on each fold's tuning half from `bases[part]`, the seed of lowest
    in-sample score chosen (see the module doc), with in-sample and held-out figures printed.
    Returns the chosen settings {"part/variant": tracker table} and the held-out figures
    {variant: [fold first, fold second]}."""
    head = "RMSE m  cov%  fr  ft"
    print(
        f"\n{'tuned on':12s} {'variant':7s} {'seed':>4s} {'score':>8s}  {'in-sample ' + head:30s}"
        f"  {'HELD-OUT ' + head:29s}  whole (half in-sample)"
    )
    chosen: dict = {}
    held_out: dict = {name: [] for name in VARIANTS}
    for part, tune, held in FOLDS:
        base = bases[part]
        if "bearing_correction_deg" in base:
            q = figures(plots, base)
            print(
                f"{NAMES[tune]:12s} start: shipped settings + bearing_correction_deg "
                f"{base['bearing_correction_deg']:+.4f} (calibrated on {NAMES[tune]}): "
                f"{fmt(q[tune])} / {NAMES[held]} {fmt(q[held])} (settings saw all scans)"
            )
        for name, v in VARIANTS.items():
            rows = []
            for seed in SEEDS:
                t0 = time.perf_counter()
                best, s, q = search(plots, base, part=part, runs=runs, seed=seed, **v)
                per_run = (time.perf_counter() - t0) / runs * 1e3
                rows.append((s, seed, best, q, per_run))
            pick = min(rows, key=lambda r: r[0])
            for s, seed, _, q, per_run in rows:
                mark = "*" if seed == pick[1] else " "
                print(
                    f"{NAMES[tune]:12s} {name:7s} {seed:3d}{mark} {s:8.3f}  {fmt(q[tune]):30s}"
                    f"  {fmt(q[held]):20s}{'' if meets(q[held]) else ' miss':5s}"
                    f"     {fmt(q[0])}   ({per_run:.1f} ms/run)"
                )
            chosen[f"{part}/{name}"] = pick[2]
            q = pick[3]
            held_out[name].append(q[held])
            print(
                f"{'':26s} chosen: held-out {fmt(q[held])} "
                f"{'meets' if meets(q[held]) else 'MISSES'} the aims; "
                f"{ms_per_scan(plots, pick[2]):.4f} ms/scan"
            )
    print("\nheld-out halves of the two folds together (chosen settings), " + head)
    for name, held in held_out.items():
        print(f"  {name:7s} {pooled(held)}")
    return chosen, held_out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1500, help="hill-climbing runs per seed")
    ap.add_argument("--draws", type=int, default=200, help="perturbations for the flatness")
    ap.add_argument("--out", type=Path, help="write the chosen settings here as JSON")
    ap.add_argument(
        "--calibrated",
        action="store_true",
        help="also the 2-fold of a radar calibrated on each tuning half (skips the flatness)",
    )
    ap.add_argument(
        "--estimated",
        action="store_true",
        help="only the 2-fold of settings estimated on each tuning half (no search, no flatness)",
    )
    a = ap.parse_args()
    path = Path(os.environ.get("USVFAST_SHARED_DATA", "../shared/data")) / "joyride/joyride.mat"
    plots = read_plots(path)
    shipped = load_config("joyride")
    q_ship = figures(plots, shipped)
    print(f"shipped joyride ({ms_per_scan(plots, shipped):.4f} ms/scan), RMSE m  cov%  fr  ft:")
    for i, q in enumerate(q_ship):
        print(f"  {NAMES[i]:14s} {fmt(q)}  {'meets' if meets(q) else 'MISSES'} the aims")
    if a.estimated:
        velocities = load_joyride(path).target[:, [1, 3]]
        if len(velocities) != len(plots.times):
            raise SystemExit("joyride.mat: scans were skipped; the GNSS rows do not match")
        estimated_two_fold(plots, velocities, shipped)
        return
    print("\nUNCALIBRATED radar: search from the shipped joyride")
    chosen, _ = two_fold(plots, {part: shipped for part, _, _ in FOLDS}, a.runs)
    print(f"  {'joyride':7s} {fmt(q_ship[0])}   (shipped, in-sample: tuned on all scans)")
    if a.calibrated:
        print("\nCALIBRATED radar: bias measured on the tuning half, search from joyride + it")
        bases = {part: calibrated(plots, shipped, part) for part, _, _ in FOLDS}
        cal, held = two_fold(plots, bases, a.runs)
        chosen |= {f"calibrated {k}": v for k, v in cal.items()}
        for (_, t, h), q in zip(FOLDS, held["reg"], strict=True):
            print(
                f"calibrated reg, tuned on {NAMES[t]}: "
                f"held-out {NAMES[h]} {fmt(q)} {'meets' if meets(q) else 'MISSES'} the aims"
            )
        print(
            "calibrated reg recipe meets the aims on both held-out halves: "
            f"{all(meets(q) for q in held['reg'])}"
        )
    else:
        for few in (False, True):
            what = "the five reg settings" if few else "every searched setting"
            print(
                f"\nflatness, {a.draws} draws of joyride, 5 % noise on {what}, all 238 scans:\n  "
                + flatness(plots, shipped, a.draws, 0.05, few)
            )
    held_ok = all(meets(figures(plots, chosen[f"{p}/reg"])[h]) for p, _, h in FOLDS)
    print(f"\nreg recipe meets the aims on both held-out halves: {held_ok}")
    if held_ok:
        rows = [
            search(plots, shipped, part="whole", runs=a.runs, seed=s, **VARIANTS["reg"])
            for s in SEEDS
        ]
        best, _, q = min(rows, key=lambda r: r[1])
        chosen["whole/reg"] = best
        print(f"reg recipe on the whole recording: {fmt(q[0])} meets the aims: {meets(q[0])}")
    if a.out:
        a.out.write_text(json.dumps(chosen, indent=1))


if __name__ == "__main__":
    main()
