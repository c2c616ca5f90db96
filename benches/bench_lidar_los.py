"""Line-of-sight filter: Rust bearing sweep vs the numpy O(n·m) peers, same input, one process.

A harbour-like frame: 30,000 points (one VLP-16 rotation) in a 20 m square and 200 LSD-like
segments along four walls. Peers: the numpy broadcast version
(`usvfast.lidar.line_of_sight_filter_numpy`, the same predicates) and a matrix-product variant
(cross products and projections as BLAS matrix products, the thesis's t/u test). Prints
the best-of-N times and the ratios.

    python benches/bench_lidar_los.py [--points 30000] [--segments 200] [--repeat 5] [--chunk 1024]
"""

from __future__ import annotations

import argparse

import numpy as np

from usvfast.lidar import (
    line_of_sight_filter,
    line_of_sight_filter_naive,
    line_of_sight_filter_numpy,
)

from timing import best_of


def harbour_scene(n: int, m: int, seed: int = 42) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    points = rng.uniform(-10, 10, (n, 2))
    walls = np.array([[-9, 6, 9, 7], [-7, -9, -6, 5], [3, -8, 8, -3], [9, -9, 9.5, 5]], float)
    per = -(-m // len(walls))
    segs = []
    for w in walls:
        t0 = np.arange(per) / per
        t1 = (np.arange(per) + 0.9) / per
        a = w[:2] + t0[:, None] * (w[2:] - w[:2])
        b = w[:2] + t1[:, None] * (w[2:] - w[:2])
        segs.append(np.hstack([a, b]) + rng.normal(0, 0.03, (per, 4)))
    return points, np.vstack(segs)[:m]


def line_of_sight_matmul(points, segments, tolerance=0.1, chunk=4096):
    """Matrix-product variant (sensor at the origin): sight segment O->p against every
    segment with the thesis's t/u test (eqs. 3.20-3.21) and point-segment distances, the
    n×m products done by BLAS."""
    a, b = segments[:, :2], segments[:, 2:]
    e = b - a
    ee = np.einsum("ij,ij->i", e, e)
    ae = np.einsum("ij,ij->i", a, e)
    aa = np.einsum("ij,ij->i", a, a)
    cross_ae = e[:, 0] * a[:, 1] - e[:, 1] * a[:, 0]
    rot_a = np.stack([a[:, 1], -a[:, 0]])  # p @ rot_a = cross(p, a)
    rot_b = np.stack([b[:, 1], -b[:, 0]])
    rot_e = np.stack([-e[:, 1], e[:, 0]])  # p @ rot_e = cross(e, p)
    safe_ee = np.where(ee > 0, ee, 1.0)
    keep = np.ones(len(points), dtype=bool)
    for s in range(0, len(points), chunk):
        p = points[s : s + chunk]
        oa = p @ rot_a
        ob = p @ rot_b
        sp = p @ rot_e - cross_ae  # side of p relative to a->b
        hidden = (oa * ob <= 0) & (sp * -cross_ae <= 0) & (cross_ae != 0)
        pe = p @ e.T
        t = np.clip((pe - ae) / safe_ee, 0.0, 1.0)
        pp = np.einsum("ij,ij->i", p, p)[:, None]
        pa = p @ a.T
        d2 = pp + aa - 2 * pa + t * t * ee - 2 * t * (pe - ae)
        near = d2 <= tolerance * tolerance
        keep[s : s + chunk] = ~(hidden | near).any(axis=1)
    return keep


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=30_000)
    ap.add_argument("--segments", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--chunk", type=int, default=1024, help="points per numpy block")
    args = ap.parse_args()
    points, segments = harbour_scene(args.points, args.segments)
    r = args.repeat
    t_fast, keep = best_of(lambda: line_of_sight_filter(points, segments), r * 4)
    t_naive, keep_naive = best_of(lambda: line_of_sight_filter_naive(points, segments), r)
    ch = args.chunk
    t_np, keep_np = best_of(lambda: line_of_sight_filter_numpy(points, segments, chunk=ch), r)
    t_mm, keep_mm = best_of(lambda: line_of_sight_matmul(points, segments, chunk=ch), r)
    assert (keep == keep_naive).all() and (keep == keep_np).all()
    print(f"line-of-sight filter, {len(points)} points x {len(segments)} segments")
    print(f"  kept {keep.sum()} points; matmul variant disagrees on {(keep != keep_mm).sum()}")
    print(f"  rust sweep            {t_fast * 1e3:9.2f} ms")
    print(f"  rust naive O(n*m)     {t_naive * 1e3:9.2f} ms   {t_naive / t_fast:7.1f}x slower")
    print(f"  numpy broadcast       {t_np * 1e3:9.2f} ms   {t_np / t_fast:7.1f}x slower")
    print(f"  numpy matrix product  {t_mm * 1e3:9.2f} ms   {t_mm / t_fast:7.1f}x slower")


if __name__ == "__main__":
    main()
