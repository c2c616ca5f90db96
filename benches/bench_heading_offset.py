"""The heading calibration's grid score: usvfast (`usvfast._core.map_sharpness`, Rust) against
the plain numpy version a skilled user would write (np.bincount over the cell indices), on the
same points and trial corrections, in one process; the two scores must agree.

    PYTHONPATH=python python benches/bench_heading_offset.py [--points 84000] [--trials 52]

Input: a synthetic harbour (two quays, a pier, two moored boats) seen by a vessel running 30 m
with turns, decimated to one point per 0.1 m cell per frame, as the pipeline gives it on the
bundled recording (~84,000 points over 60 frames, 52 trial corrections per estimate).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from usvfast.nav.heading_offset import sharpness


def sharpness_numpy(xy, north, east, heading, offsets_deg, cell):
    """The peer: one np.bincount per grid per trial correction."""
    out = []
    for d in np.radians(offsets_deg):
        c, s = np.cos(heading + d), np.sin(heading + d)
        pn = (north + c * xy[:, 0] - s * xy[:, 1]) / cell
        pe = (east + s * xy[:, 0] + c * xy[:, 1]) / cell
        total = 0.0
        for shift in (0.0, 0.5):
            i = np.floor(pn + shift).astype(np.int64)
            j = np.floor(pe + shift).astype(np.int64)
            i -= i.min()
            j -= j.min()
            counts = np.bincount(i * (int(j.max()) + 1) + j).astype(np.float64)
            total += float(np.dot(counts, counts))
        out.append(total / (2.0 * len(xy) ** 2))
    return np.array(out)


def scene(n_points: int, frames: int = 60, seed: int = 0):
    """Body-frame points and per-point poses of a vessel running past quays."""
    rng = np.random.default_rng(seed)
    k = np.arange(frames) / (frames - 1)
    poses = np.column_stack([2 + 30 * k, 3 * np.sin(4 * k), 0.3 * np.sin(6 * k)])
    per = n_points // frames
    f = rng.uniform(0, 1, (frames, per))
    side = rng.integers(0, 3, (frames, per))
    north = np.where(side == 2, 30.0, -5 + 50 * f)
    east = np.choose(side, [np.full_like(f, 12.0), -14 - 2 * f, -16 + 12 * f])
    xy, pose_rows = [], []
    for i, (n0, e0, h) in enumerate(poses):
        d = np.column_stack([north[i] - n0, east[i] - e0])
        c, s = np.cos(h), np.sin(h)
        xy.append(np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]]))
        pose_rows.append(np.repeat(poses[i][None], per, axis=0))
    xy = np.concatenate(xy) + rng.normal(0, 0.02, (frames * per, 2))
    p = np.concatenate(pose_rows)
    return xy, p[:, 0], p[:, 1], p[:, 2] + np.radians(0.8)


def best(fn, repeat: int = 5) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=84_000)
    ap.add_argument("--trials", type=int, default=52)
    args = ap.parse_args()
    xy, n, e, h = scene(args.points)
    offsets = np.linspace(-3.0, 3.0, args.trials)
    ours = sharpness(xy, n, e, h, offsets, 0.1)
    peer = sharpness_numpy(xy, n, e, h, offsets, 0.1)
    assert np.allclose(ours, peer, rtol=1e-12), "the two scores differ"
    t_ours = best(lambda: sharpness(xy, n, e, h, offsets, 0.1))
    t_peer = best(lambda: sharpness_numpy(xy, n, e, h, offsets, 0.1))
    print(f"map sharpness, {len(xy)} points x {args.trials} trial corrections (best of 5)")
    print(f"  usvfast (Rust)   {t_ours * 1e3:8.1f} ms")
    print(f"  numpy bincount   {t_peer * 1e3:8.1f} ms")
    print(f"  ratio            {t_peer / t_ours:8.1f}x")
    print(f"  best correction  {offsets[int(np.argmax(ours))]:+.2f} deg (true -0.80)")


if __name__ == "__main__":
    main()
