"""Multi-target metrics, ours vs the reference implementations on the same frames, one process:

* CLEAR MOT + IDF1: usvfast.metrics.mot_metrics vs py-motmetrics (MOTAccumulator + compute);
* HOTA: usvfast.metrics.hota_metrics vs TrackEval's HOTA.eval_sequence (same similarities);
* GOSPA/OSPA: usvfast.metrics.gospa_metrics vs Stone Soup's GOSPAMetric / OSPAMetric per frame
  (OSPA with Stone Soup's assignment rule, `ospa_assignment="distance"`).

The scene: `--frames` frames (default 1000) of 20 objects on random walks, tracks with noise,
misses, id swaps and clutter (≈ 20 truth and 22 tracks per frame). The figures are checked
equal before the times are printed.

Run: python benches/bench_metrics.py [--frames N] [--repeat R]
"""

from __future__ import annotations

import argparse
import sys
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np

from usvfast.metrics import FrameSequence, gospa_metrics, hota_metrics, mot_metrics

sys.path.insert(0, str(Path(__file__).parent))
from timing import best_of


def scene(n_frames: int, n_obj: int = 20, seed: int = 1):
    rng = np.random.default_rng(seed)
    path = rng.uniform(0, 200, (n_obj, 2))[None] + np.cumsum(
        rng.normal(0, 0.5, (n_frames, n_obj, 2)), axis=0
    )
    gf, gi, gp, tf, ti, tp = [], [], [], [], [], []
    owner = np.arange(n_obj) + 100
    for k in range(n_frames):
        if rng.random() < 0.05:
            a, b = rng.choice(n_obj, 2, replace=False)
            owner[[a, b]] = owner[[b, a]]
        gf += [k] * n_obj
        gi += list(range(n_obj))
        gp.append(path[k])
        seen = rng.random(n_obj) > 0.1
        tf += [k] * int(seen.sum())
        ti += list(owner[seen])
        tp.append(path[k][seen] + rng.normal(0, 1.0, (seen.sum(), 2)))
        n_fp = 3
        tf += [k] * n_fp
        ti += list(1000 + rng.choice(50, n_fp, replace=False))
        tp.append(rng.uniform(0, 200, (n_fp, 2)))
    return (
        np.array(gf),
        np.array(gi),
        np.concatenate(gp),
        np.array(tf),
        np.array(ti),
        np.concatenate(tp),
    )


def ours_mot(rows, gate):
    return mot_metrics(FrameSequence.from_positions(*rows, max_distance=gate))


def motmetrics_mot(rows, gate):
    import motmetrics as mm

    gf, gi, gp, tf, ti, tp = rows
    acc = mm.MOTAccumulator(auto_id=True)
    for k in np.unique(np.r_[gf, tf]):
        g, t = gf == k, tf == k
        d = np.sqrt(mm.distances.norm2squared_matrix(gp[g], tp[t], max_d2=gate**2))
        acc.update(gi[g], ti[t], d)
    names = ["mota", "motp", "idf1", "num_switches"]
    return mm.metrics.create().compute(acc, metrics=names, name="run").iloc[0]


def trackeval_hota(seq):
    from trackeval.metrics import HOTA

    all_g = np.unique(np.concatenate(seq.truth_ids))
    all_t = np.unique(np.concatenate(seq.track_ids))
    data = {
        "num_timesteps": len(seq.frames),
        "num_gt_ids": len(all_g),
        "num_tracker_ids": len(all_t),
        "num_gt_dets": seq.n_truth,
        "num_tracker_dets": seq.n_tracks,
        "gt_ids": [np.searchsorted(all_g, g) for g in seq.truth_ids],
        "tracker_ids": [np.searchsorted(all_t, t) for t in seq.track_ids],
        "similarity_scores": seq.similarity,
    }
    return HOTA().eval_sequence(data)


def stonesoup_gospa(seq, c):
    from stonesoup.metricgenerator.ospametric import GOSPAMetric, OSPAMetric
    from stonesoup.types.state import State

    g, o = GOSPAMetric(c=c, p=2), OSPAMetric(c=c, p=2)
    t0 = datetime(2025, 1, 1)
    dist, ospa = [], []
    for k, (gv, tv) in enumerate(zip(seq.truth_values, seq.track_values, strict=True)):
        ts = t0 + timedelta(seconds=k)
        truth = [State(v.reshape(2, 1), timestamp=ts) for v in gv]
        track = [State(v.reshape(2, 1), timestamp=ts) for v in tv]
        dist.append(g.compute_gospa_metric(track, truth)[0].value["distance"])
        ospa.append(o.compute_OSPA_distance(track, truth).value)
    return np.array(dist), np.array(ospa)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rows = scene(args.frames)
    gate = 3.0
    seq = FrameSequence.from_positions(*rows, max_distance=gate)
    print(f"{args.frames} frames, {seq.n_truth} truth objects, {seq.n_tracks} track objects")
    print(f"{'metric':<24}{'usvfast s':>12}{'reference s':>14}{'ratio':>9}")

    t_ours, ours = best_of(lambda: ours_mot(rows, gate), args.repeat)
    t_ref, ref = best_of(lambda: motmetrics_mot(rows, gate), 1)
    assert ours.switches == ref.num_switches and np.isclose(ours.mota, ref.mota)
    assert np.isclose(ours.idf1, ref.idf1) and np.isclose(ours.motp, ref.motp)
    print(f"{'CLEAR MOT+IDF1 (motmetr.)':<24}{t_ours:>12.3f}{t_ref:>14.3f}{t_ref / t_ours:>8.1f}x")

    t_ours, h = best_of(lambda: hota_metrics(seq), args.repeat)
    t_ref, r = best_of(lambda: trackeval_hota(seq), 1)
    assert np.isclose(h.hota, np.mean(r["HOTA"]))
    print(f"{'HOTA (TrackEval)':<24}{t_ours:>12.3f}{t_ref:>14.3f}{t_ref / t_ours:>8.1f}x")

    t_ours, g = best_of(
        lambda: gospa_metrics(seq, cutoff=5.0, ospa_assignment="distance"), args.repeat
    )
    t_ref, (gd, od) = best_of(lambda: stonesoup_gospa(seq, 5.0), 1)
    assert np.allclose(g.distance, gd) and np.allclose(g.ospa, od)
    print(f"{'GOSPA+OSPA (Stone Soup)':<24}{t_ours:>12.3f}{t_ref:>14.3f}{t_ref / t_ours:>8.1f}x")
    print(f"MOTA {ours.mota:.3f} IDF1 {ours.idf1:.3f} HOTA {h.hota:.3f}")
    print(f"GOSPA {g.mean_distance:.3f} m, OSPA {g.mean_ospa:.3f} m (Stone Soup's assignment)")


if __name__ == "__main__":
    main()
