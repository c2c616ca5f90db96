"""Time the LiDAR chain per stage on a realistic VLP-16 frame (a marina with finger piers,
~21,000 points, or 28,800 with `--rough`), against a thesis-style implementation (per-point
Python loop prefilter, numpy O(n·m) line-of-sight) in the same run.

    PYTHONPATH=python python benches/bench_lidar_pipeline.py [--repeat N] [--full] [--rough]

Quick by default; `--full` also times scikit-learn's mean shift on a buffered cycle;
`--rough` makes every beam meeting the water return (a full 28,800-point frame).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from usvfast.lidar import (
    Box,
    LidarConfig,
    LineMemory,
    Scene,
    VLP16Simulator,
    Wall,
    blur,
    cluster_detections,
    detect_segments,
    extend_segments,
    line_of_sight_filter,
    line_of_sight_filter_numpy,
    prefilter,
    rasterize,
    sensor_motion,
    sensor_to_world,
)
from usvfast.lidar.simulator import Cylinder


def marina(seed: int = 0, rough: bool = False) -> Scene:
    """A marina basin: quays at east = ±7 m with finger piers (0.6 m high, 3 m long) every
    3.5 m, boats in some berths, floats in the fairway, buildings at 30 m; distant water
    (beyond 12.5 m) returns every beam (~21,000 points); `rough` makes all the water return
    every beam, the worst case: a full 28,800-point frame."""
    rng = np.random.default_rng(seed)
    square = np.array([[-30.0, -30.0], [30.0, -30.0], [30.0, 30.0], [-30.0, 30.0], [-30, -30]])
    objects: list = [Wall(square, 15.0)]
    for side in (-1.0, 1.0):
        objects.append(Wall(np.array([[-25.0, 7.0 * side], [25.0, 7.0 * side]]), 1.0))
        for n in np.arange(-24.0, 25.0, 3.5):
            objects.append(Box((n, side * 5.5), 3.0, 0.4, np.pi / 2, 0.0, 0.6, "wall"))
            if rng.random() < 0.4:
                objects.append(
                    Box((n + 1.75, side * 5.2), 2.4, 1.6, rng.normal(0, 0.05), 0.0, 1.2, "boat")
                )
    for _ in range(6):
        objects.append(
            Cylinder((rng.uniform(-9, 9), rng.uniform(-2.5, 2.5)), 0.25, 0.0, 0.2, "float")
        )
    near = 0.0 if rough else 12.5
    return Scene(objects, clutter_probability=1.0, clutter_range=80.0, clutter_min_range=near)


def timed(fn, repeat):
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best * 1e3, out


def thesis_prefilter(points, radius, height):
    """Thesis Code 5.4: np.unique then a per-point loop."""
    data = np.column_stack([points["x"], points["y"], points["z"]])
    out = []
    for p in np.unique(data, axis=0):
        if np.linalg.norm([p[0], p[1]]) <= radius and p[2] + 1.0 <= height:
            out.append(p)
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--full", action="store_true", help="also time scikit-learn mean shift")
    ap.add_argument("--rough", action="store_true", help="water returns everywhere: 28,800 pts")
    args = ap.parse_args()
    cfg = LidarConfig()
    sim = VLP16Simulator(marina(rough=args.rough), seed=0)
    poses = [(0.1 * i, 0.0, 0.01 * i) for i in range(cfg.buffer_frames)]
    frames = [sim.scan(p, 100.0 + 0.1 * i).frame for i, p in enumerate(poses)]
    frame = frames[-1]
    pts = frame.points
    R = cfg.radius + cfg.line_margin
    t_pre, (xy_all, _) = timed(
        lambda: prefilter(pts, radius=R, mount_height=1.0, slice_min=-0.5, slice_max=0.5),
        args.repeat,
    )
    inside = (xy_all**2).sum(1) <= cfg.radius**2
    xy = xy_all[inside]
    t_ras, image = timed(lambda: blur(rasterize(xy_all, radius=R, pixel=cfg.pixel)), args.repeat)
    t_lsd, segs = timed(lambda: detect_segments(image, radius=R, pixel=cfg.pixel), args.repeat)

    def memory_step():
        mem = LineMemory(cfg.line_memory_frames, cfg.cover_tolerance)
        for _ in range(cfg.line_memory_frames - 1):
            mem.update(segs, (0.1, 0.0, 0.0))
        return mem.update(segs, sensor_motion(poses[-2], poses[-1]))

    t_mem, active = timed(memory_step, args.repeat)
    t_mem /= cfg.line_memory_frames
    los_segs = extend_segments(active, cfg.segment_extension)
    t_los, keep = timed(
        lambda: line_of_sight_filter(xy, los_segs, tolerance=cfg.los_tolerance), args.repeat
    )
    t_np, keep_np = timed(
        lambda: line_of_sight_filter_numpy(xy, los_segs, tolerance=cfg.los_tolerance),
        max(1, args.repeat // 2),
    )
    assert np.array_equal(keep, keep_np)
    t_world, _ = timed(lambda: sensor_to_world(xy[keep], poses[-1]), args.repeat)
    t_thesis_pre, _ = timed(lambda: thesis_prefilter(pts, cfg.radius, 0.5), 1)

    # LOS at the reference size: 30,000 points x 200 segments
    rng = np.random.default_rng(1)
    big_pts = rng.uniform(-10, 10, (30_000, 2))
    a = rng.uniform(-10, 10, (200, 2))
    ang = rng.uniform(0, np.pi, 200)
    big_seg = np.hstack([a, a + 1.5 * np.column_stack([np.cos(ang), np.sin(ang)])])
    t_los_big, k1 = timed(lambda: line_of_sight_filter(big_pts, big_seg, tolerance=0.1), 3)
    t_np_big, k2 = timed(lambda: line_of_sight_filter_numpy(big_pts, big_seg, tolerance=0.1), 1)
    assert np.array_equal(k1, k2)

    print(f"frame: {len(pts)} points, {len(xy_all)} after prefilter, {len(xy)} within radius,")
    print(f"       {len(segs)} LSD segments, {len(active)} in line memory, {keep.sum()} kept")
    print(f"stage times (best of {args.repeat}), ms:")
    rows = [
        ("prefilter", t_pre),
        ("raster + blur", t_ras),
        ("LSD", t_lsd),
        ("line memory", t_mem),
        ("line of sight (Rust)", t_los),
        ("to world", t_world),
    ]
    for name, t in rows:
        print(f"  {name:<24} {t:8.3f}")
    core = t_pre + t_ras + t_lsd + t_los
    print(f"  {'prefilter+raster+LSD+LOS':<24} {core:8.3f}   (aim < 10 ms)")
    print(f"  {'per frame (all above)':<24} {sum(t for _, t in rows):8.3f}")
    print("thesis-style peers, same input:")
    print(f"  prefilter loop (Code 5.4) {t_thesis_pre:8.3f} ms  ratio {t_thesis_pre / t_pre:6.1f}x")
    print(f"  LOS numpy O(n*m)          {t_np:8.3f} ms  ratio {t_np / t_los:6.1f}x")
    print(
        f"  LOS 30,000 x 200 random: Rust {t_los_big:.3f} ms, numpy {t_np_big:.1f} ms, "
        f"ratio {t_np_big / t_los_big:.0f}x"
    )

    # one buffered cycle of clustering
    det_pts = []
    for fr, pose in zip(frames, poses, strict=True):
        p2, _ = prefilter(fr.points, radius=cfg.radius)
        det_pts.append(sensor_to_world(p2[line_of_sight_filter(p2, los_segs, tolerance=0.4)], pose))
    buffered = np.vstack(det_pts)
    cluster_detections(buffered[:20], time=0.0, backend="rust")  # warm up imports
    backends = ["rust"] + (["sklearn"] if args.full else [])
    print(f"clustering one cycle ({len(buffered)} buffered points, bandwidth 2 m):")
    times = {}
    for backend in backends:
        try:
            times[backend], (dets, _, _) = timed(
                lambda b=backend: cluster_detections(buffered, time=0.0, backend=b), 1
            )
            print(f"  mean shift [{backend}]   {times[backend]:10.3f} ms, {len(dets)} detections")
        except Exception as exc:  # backend not built
            print(f"  mean shift [{backend}]   unavailable: {exc}")
    if len(times) == 2:
        print(f"  ratio sklearn/rust {times['sklearn'] / times['rust']:.1f}x")


if __name__ == "__main__":
    main()
