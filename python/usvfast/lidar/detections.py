"""Clusters -> detections: the last stage of the thesis's LiDAR chain (section 3.3, Figure 3.6).

The buffered world points are mean-shifted (`usvfast.lidar.clustering.mean_shift`); every
cluster with enough members becomes a `LidarDetection` (its members' mean and floored sample
covariance). Two refinements, both off by default (the thesis): a cluster may count only its
core (`core_radius`), and a core too small for `min_cluster_points` may still be a detection
when most of it lies within centimetres of its median (`small_cluster_points`,
`small_cluster_radius`): the few returns of one ring grazing a small float.

Frames: world (north, east) metres; heights above the water, metres.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from usvfast._core import DimensionError
from usvfast._validate import as_float_array, integer, real


@dataclass
class LidarDetection:
    """One LiDAR point detection for the tracker.

    time : UNIX s; position : (2,) world (north, east) m; covariance : (2, 2) m²;
    n_points : cluster size; sensor_id : the LiDAR's id; extended : a vessel's detection
    (`usvfast.lidar.vessels`): its position is the hull's estimated centre and its covariance
    the finder's, not a cluster centroid's; spread : (2, 2) m², the members' sample
    covariance without the `min_position_std` floor (the cluster's shape; None when not
    known, e.g. for a vessel); top : the highest member's height above the water, m (None
    when the points' heights were not given); small : the cluster had fewer than
    `min_cluster_points` members and was kept by the small-cluster rule
    (`LidarConfig.small_cluster_points`); its members are then the ones near its median.
    """

    time: float
    position: np.ndarray
    covariance: np.ndarray
    n_points: int
    sensor_id: str = "lidar"
    extended: bool = False
    spread: np.ndarray | None = None
    top: float | None = None
    small: bool = False


def check_small_cluster(points: Any, radius: Any) -> tuple[int | None, float]:
    """(small_cluster_points, small_cluster_radius) checked: None or an integer >= 2
    (TypeError for a non-integer, ValueError below 2) and a number > 0 m (TypeError for a
    non-number, ValueError otherwise)."""
    count = None if points is None else integer("small_cluster_points", points, low=2)
    return count, real("small_cluster_radius", radius, positive=True)


def near_median(points: np.ndarray, radius: float) -> np.ndarray:
    """(n,) bool mask of the points (n, 2) m within `radius` m (inclusive) of their
    coordinate-wise median (numpy's: the mean of the two middle values for an even n).

    With more than half of the points in a tight group the median lies inside the group's
    bounding box, so a stray member (a wave crest 0.5 m off) neither moves it far nor counts.
    Raises ValueError for a radius that is not > 0 or not finite, DimensionError for points
    not (n, 2) with n >= 1, NonFiniteError (a ValueError) for NaN or inf in them, TypeError
    for anything that is not real numbers."""
    radius = real("radius", radius, positive=True)
    pts = as_float_array("points", points, ndim=2)
    if pts.shape[1] != 2 or pts.shape[0] == 0:
        raise DimensionError(f"points: expected shape (n, 2) with n >= 1, got {pts.shape}")
    d = pts - np.median(pts, axis=0)
    return np.hypot(d[:, 0], d[:, 1]) <= radius


def cluster_detections(
    points: np.ndarray,
    *,
    time: float,
    bandwidth: float = 2.0,
    min_cluster_points: int = 15,
    min_position_std: float = 0.1,
    core_radius: float | None = None,
    small_cluster_points: int | None = None,
    small_cluster_radius: float = 0.1,
    bin_seeding: bool = False,
    cluster_all: bool = False,
    backend: str = "rust",
    sensor_id: str = "lidar",
    heights: np.ndarray | None = None,
) -> tuple[list[LidarDetection], np.ndarray, np.ndarray]:
    """Mean-shift (n, 2) world points and turn every big enough cluster into a detection.

    Clusters with fewer than `min_cluster_points` members, and orphans (label −1 with
    `cluster_all=False`), produce nothing. A detection's position is the mean of its
    members; its covariance is their sample covariance with every eigenvalue raised to at
    least `min_position_std`². With `core_radius` (m) a cluster keeps only its core: the
    members within core_radius of where a flat-kernel mean shift of that radius settles from
    the members' median (`_core_members`); the count, mean and covariance are the core's (two
    floats in one cluster: one of them, where the thesis's mean lies between them).

    Small-cluster rule: with `small_cluster_points` K (an integer >= 2) a cluster (core) of
    fewer than `min_cluster_points` members is still a detection when at least K of its
    members lie within `small_cluster_radius` m of the members' coordinate-wise median
    (`near_median`); the detection is made of those members only (the others get label −1)
    and is marked `small`. One ring grazing a 5 cm high float in one rotation gives 4–5
    returns within a few centimetres; sparse water returns that happen to form a small core
    scatter over decimetres, so few of them lie near their median.

    heights: optional (n,) height of each point above the water, m; each detection's `top`
    is then its members' highest.

    Returns (detections, labels (n,) int with −1 for points in no kept cluster, centres
    (c, 2) of all mean-shift clusters). Labels of kept clusters index `centres`.
    """
    from usvfast.lidar.clustering import mean_shift

    time = real("time", time)
    min_position_std = real("min_position_std", min_position_std, positive=True)
    if core_radius is not None:
        core_radius = real("core_radius", core_radius, positive=True)
    small_cluster_points, small_cluster_radius = check_small_cluster(
        small_cluster_points, small_cluster_radius
    )
    pts = as_float_array("points", points, ndim=2)
    if heights is not None:
        heights = as_float_array("heights", heights, ndim=1)
        if heights.shape[0] != pts.shape[0]:
            raise ValueError(
                f"heights: expected one height per point ({pts.shape[0]}), got {heights.shape[0]}"
            )
    if pts.shape[0] == 0:
        return [], np.zeros(0, dtype=np.int64), np.zeros((0, 2))
    centres, labels = mean_shift(
        pts,
        bandwidth=bandwidth,
        bin_seeding=bin_seeding,
        cluster_all=cluster_all,
        backend=backend,
    )
    labels = np.asarray(labels, dtype=np.int64).copy()
    detections = []
    floor = min_position_std**2
    for k in range(np.asarray(centres).shape[0]):
        members = labels == k
        if core_radius is not None and members.any():
            outer = members.copy()
            members[outer] = _core_members(pts[outer], core_radius)
            labels[outer & ~members] = -1
        count = int(members.sum())
        small = count < min_cluster_points
        if small:
            if small_cluster_points is None or count < small_cluster_points:
                labels[members] = -1
                continue
            inner = members.copy()
            inner[members] = near_median(pts[members], small_cluster_radius)
            if int(inner.sum()) < small_cluster_points:
                labels[members] = -1
                continue
            labels[members & ~inner] = -1
            members, count = inner, int(inner.sum())
        m = pts[members]
        spread = np.cov(m, rowvar=False)
        spread = (spread + spread.T) / 2
        w, v = np.linalg.eigh(spread)
        cov = (v * np.maximum(w, floor)) @ v.T
        top = None if heights is None else float(heights[members].max())
        detections.append(
            LidarDetection(
                float(time),
                m.mean(axis=0),
                cov,
                count,
                sensor_id,
                spread=spread,
                top=top,
                small=small,
            )
        )
    return detections, labels, np.asarray(centres, dtype=np.float64).reshape(-1, 2)


def _core_members(points: np.ndarray, radius: float, iterations: int = 10) -> np.ndarray:
    """(n,) mask of the points (n, 2) within `radius` of their core: start at the
    coordinate-wise median (or, with no point within `radius` of it, at the point nearest
    it), move to the mean of the points within `radius` until it stops (at most `iterations`
    steps; a flat-kernel mean shift, Comaniciu & Meer 2002)."""
    r2 = radius * radius
    centre = np.median(points, axis=0)
    d2 = np.sum((points - centre) ** 2, axis=1)
    if not (d2 <= r2).any():
        centre = points[int(np.argmin(d2))]
    inside = np.sum((points - centre) ** 2, axis=1) <= r2
    for _ in range(iterations):
        new = points[inside].mean(axis=0)
        if abs(new[0] - centre[0]) <= 1e-6 and abs(new[1] - centre[1]) <= 1e-6:
            break
        centre = new
        inside = np.sum((points - centre) ** 2, axis=1) <= r2
        if not inside.any():
            break
    return inside
