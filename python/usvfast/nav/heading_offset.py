"""A constant offset of the GNSS heading, estimated from what the LiDAR sees of the static
world (quays, piers, moored boats, buildings).

A dual-antenna GNSS compass whose baseline is not exactly along the hull, or a LiDAR mounted
a little turned, gives every point and every camera ray a heading error δ that no innovation
shows (both sensors share it) but that moves a target at range r by δ·r across the line of
sight: 0.17 m at 10 m for 1°. A static point p seen from the vessel at s with the heading
biased by δ lands at s + Rz(δ)(p − s) = Rz(δ) p + (I − Rz(δ)) s: the map is rotated, and
shifted by about δ × the distance travelled. So the static world, accumulated along a path
of some tens of metres, is sharpest at the heading correction −δ. `estimate_heading_offset`
searches that correction: every frame's points are placed in NED with the heading plus each
candidate offset, counted on a grid of `cell` m (twice, the second grid shifted by half a
cell), and the sharpness is Σ n² / (Σ n)² over the cells (the map-entropy idea of LiDAR
self-calibration, with a quadratic score); a coarse search over ±`span_deg`, a fine one
around its best, and a parabola through the fine peak.

The offset is observable only when the vessel has moved: turning on the spot rotates every
frame's points the same way. `HeadingOffset.observable` is False when the positions used
span less than `min_baseline` m (the diagonal of their box) or no peak stands out (the
pipeline then keeps the heading as it is).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from usvfast import _core
from usvfast._validate import as_float_array, real

__all__ = ["HeadingOffset", "estimate_heading_offset", "sharpness"]


@dataclass(frozen=True)
class HeadingOffset:
    """offset_deg: the correction to add to the GNSS heading, degrees clockwise (NaN when not
    observable). frames, points: the frames and (decimated) points used. baseline_m: the
    diagonal of the box around the vessel positions used, m. contrast: the sharpness at the
    peak over the median of the coarse search (1: flat). observable: whether offset_deg can
    be used. angles_deg, scores: the coarse search's candidates and sharpness."""

    offset_deg: float
    frames: int
    points: int
    baseline_m: float
    contrast: float
    observable: bool
    angles_deg: np.ndarray
    scores: np.ndarray

    def as_dict(self) -> dict:
        """The scalar fields, for summary.json."""
        return {
            "offset_deg": None if not np.isfinite(self.offset_deg) else self.offset_deg,
            "frames": self.frames,
            "points": self.points,
            "baseline_m": self.baseline_m,
            "contrast": self.contrast,
            "observable": self.observable,
        }


def _decimate(xy: np.ndarray, cell: float) -> np.ndarray:
    """One point per occupied cell of a frame (its first): a near wall's hundreds of hits
    weigh no more than the far structure's few."""
    key = np.floor(xy / cell).astype(np.int64)
    _, first = np.unique(key[:, 0] * 1_000_003 + key[:, 1], return_index=True)
    return xy[np.sort(first)]


def sharpness(
    xy: np.ndarray,
    north: np.ndarray,
    east: np.ndarray,
    heading: np.ndarray,
    offsets_deg: np.ndarray,
    cell: float,
) -> np.ndarray:
    """Σ n² / (Σ n)² of the points' NED cell counts (two grids, the second shifted by half a
    cell; mean of the two) for each heading correction of `offsets_deg` (m,), degrees. xy
    (n, 2): body FRD horizontal coordinates (x forward, y starboard) from the vessel
    reference point, m; north, east, heading (n,): the pose of each point's frame (m, m, rad
    clockwise from north). In Rust (`usvfast._core.map_sharpness`)."""
    return _core.map_sharpness(
        as_float_array("xy", xy, 2),
        as_float_array("north", north, 1),
        as_float_array("east", east, 1),
        as_float_array("heading", heading, 1),
        np.radians(as_float_array("offsets_deg", offsets_deg, 1)),
        real("cell", cell, positive=True),
    )


def estimate_heading_offset(
    points: Sequence[np.ndarray],
    poses: np.ndarray,
    *,
    span_deg: float = 3.0,
    coarse_step_deg: float = 0.2,
    fine_step_deg: float = 0.02,
    cell: float = 0.1,
    min_baseline: float = 10.0,
    min_contrast: float = 1.5,
) -> HeadingOffset:
    """The heading correction that makes the static world sharpest (module docstring).

    points: one (n_i, 2) array per frame of static returns (points above the water: quays,
    boats, buildings), body FRD horizontal coordinates from the vessel reference point, m,
    levelled (roll and pitch removed). poses (k, 3): each frame's north, east (m, local NED)
    and heading (rad clockwise from north) as the navigation gives them. span_deg: the
    search's half-width; coarse_step_deg, fine_step_deg: its steps (degrees); cell: the grid
    (and per-frame decimation) cell, m; min_baseline: least span of the positions, m;
    min_contrast: least peak-to-median sharpness ratio of an observable offset.

    Raises ValueError/TypeError naming the argument on bad input (a frame that is not
    (n, 2) finite numbers, poses not (len(points), 3), no points at all, steps not > 0)."""
    poses = as_float_array("poses", poses, 2)
    if poses.shape != (len(points), 3):
        raise ValueError(
            f"poses: expected shape ({len(points)}, 3) (one north, east, heading per frame), "
            f"got {poses.shape}"
        )
    span = real("span_deg", span_deg, positive=True)
    coarse = real("coarse_step_deg", coarse_step_deg, positive=True)
    fine = real("fine_step_deg", fine_step_deg, positive=True)
    cell = real("cell", cell, positive=True)
    min_baseline = real("min_baseline", min_baseline, low=0.0)
    min_contrast = real("min_contrast", min_contrast, low=1.0)
    frames = []
    for k, p in enumerate(points):
        p = as_float_array(f"points[{k}]", p)
        if p.ndim != 2 or p.shape[1] != 2:
            raise ValueError(f"points[{k}]: expected an (n, 2) array, got shape {p.shape}")
        frames.append(_decimate(p, cell) if len(p) else p)
    counts = np.array([len(p) for p in frames], dtype=np.int64)
    if counts.sum() == 0:
        raise ValueError("points: no static point in any frame")
    xy = np.concatenate(frames)
    frame = np.repeat(np.arange(len(frames)), counts)
    north, east, heading = poses[frame, 0], poses[frame, 1], poses[frame, 2]
    baseline = float(np.hypot(*np.ptp(poses[counts > 0, :2], axis=0)))
    angles = np.arange(-span, span + coarse / 2, coarse)
    scores = sharpness(xy, north, east, heading, angles, cell)
    best = float(angles[int(np.argmax(scores))])
    near = np.arange(best - coarse, best + coarse + fine / 2, fine)
    near_scores = sharpness(xy, north, east, heading, near, cell)
    k = int(np.argmax(near_scores))
    offset = float(near[k])
    if 0 < k < len(near) - 1:
        a, b, c = near_scores[k - 1 : k + 2]
        curvature = a - 2.0 * b + c
        if curvature < 0:
            offset += 0.5 * fine * (a - c) / curvature
    contrast = float(near_scores[k] / np.median(scores))
    observable = bool(baseline >= min_baseline and contrast >= min_contrast and abs(offset) < span)
    return HeadingOffset(
        offset_deg=offset if observable else float("nan"),
        frames=int((counts > 0).sum()),
        points=int(counts.sum()),
        baseline_m=baseline,
        contrast=contrast,
        observable=observable,
        angles_deg=angles,
        scores=scores,
    )
