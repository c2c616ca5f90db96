"""Line-of-sight filter: drop LiDAR points hidden behind line segments or on them.

Thesis section 3.3.4 / Algorithm 1, done as a bearing sweep in Rust in
O((n + m) log(n + m)) instead of the O(n·m) double loop.

Frame: the sensor's horizontal plane (x, y in metres, e.g. the LiDAR frame after dropping z).
A point ``p`` is dropped (keep-mask ``False``) when, for some segment ``s = [a, b]``:

- **wall return**: the distance from ``p`` to the closed segment ``s`` is ``<= tolerance``;
- **hidden**: ``s`` intersects the half-open sight segment ``(sensor, p]``, i.e. some point
  of ``s`` lies on the sight line strictly after the sensor and not beyond ``p``.

Degenerate cases, identical in all three implementations (they evaluate the same float64
predicates, written out in ``line_of_sight_filter_numpy``, so they agree bit for bit):

- a point exactly at the sensor is never hidden (its sight segment is empty); it is still
  dropped when within ``tolerance`` of a segment;
- a segment collinear with a sight line hides the point when the two overlap anywhere in
  ``(sensor, p]``; a segment that touches the sight line only at the sensor does not hide
  (so a segment through the sensor hides only the points along it);
- a segment endpoint exactly on the sight line hides (segments are closed), so the two rays
  through a wall's ends belong to its shadow;
- a zero-length segment is a point obstacle: it hides the points exactly behind it on its
  ray, and drops the points within ``tolerance`` of it.

The fast filter's equality with the naive one relies on ``tolerance`` being above ~1e-7 of
the scene extent (any practical value): see ``rust/src/line_of_sight.rs``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from usvfast import _core
from usvfast._validate import as_float_array

__all__ = [
    "line_of_sight_filter",
    "line_of_sight_filter_naive",
    "line_of_sight_filter_numpy",
]


def _rows(name: str, value: Any, cols: int) -> np.ndarray:
    arr = as_float_array(name, value)
    if arr.size == 0:
        return np.zeros((0, cols))
    if arr.ndim != 2 or arr.shape[1] != cols:
        raise _core.DimensionError(f"{name}: expected shape (n, {cols}), got {arr.shape}")
    return arr


def _check(
    points: Any, segments: Any, sensor: Any, tolerance: Any
) -> tuple[np.ndarray, np.ndarray, tuple[float, float], float]:
    p = _rows("points", points, 2)
    s = _rows("segments", segments, 4)
    o = as_float_array("sensor", sensor)
    if o.shape != (2,):
        raise _core.DimensionError(f"sensor: expected 2 values (x, y), got shape {o.shape}")
    tol = float(tolerance)
    if not (np.isfinite(tol) and tol > 0.0):
        raise ValueError(f"tolerance: must be a finite positive distance in metres, got {tol}")
    return p, s, (float(o[0]), float(o[1])), tol


def line_of_sight_filter(
    points: Any, segments: Any, *, sensor: Any = (0.0, 0.0), tolerance: float = 0.1
) -> np.ndarray:
    """Keep-mask of the points neither hidden behind nor within `tolerance` of a segment.

    points: (n, 2) metres in the sensor's horizontal frame; segments: (m, 4) rows
    (x1, y1, x2, y2) in the same frame; sensor: (x, y) of the sight-line origin;
    tolerance: metres (> 0). Returns a bool array (n,), True = keep. Semantics and
    degenerate cases: see the module docstring. Rust bearing sweep,
    O((n + m) log(n + m)). Raises DimensionError / NonFiniteError / TypeError naming the
    argument for bad arrays, ValueError for a non-positive tolerance.
    """
    p, s, o, tol = _check(points, segments, sensor, tolerance)
    return _core.line_of_sight_filter(p, s, sensor=o, tolerance=tol)


def line_of_sight_filter_naive(
    points: Any, segments: Any, *, sensor: Any = (0.0, 0.0), tolerance: float = 0.1
) -> np.ndarray:
    """The O(n·m) Rust reference of `line_of_sight_filter`: same contract, same result."""
    p, s, o, tol = _check(points, segments, sensor, tolerance)
    return _core.line_of_sight_filter_naive(p, s, sensor=o, tolerance=tol)


def _drop_numpy(p: np.ndarray, s: np.ndarray, o: tuple[float, float], tol2: float) -> np.ndarray:
    """(n, m) bool: segment j hides or is within tolerance of point i (broadcast)."""
    sx, sy = o
    # Hidden: the float64 predicate of rust/src/line_of_sight.rs `blocks`, op for op.
    dx = (p[:, 0] - sx)[:, None]
    dy = (p[:, 1] - sy)[:, None]
    ax = (s[:, 0] - sx)[None, :]
    ay = (s[:, 1] - sy)[None, :]
    bx = (s[:, 2] - sx)[None, :]
    by = (s[:, 3] - sy)[None, :]
    oa = dx * ay - dy * ax
    ob = dx * by - dy * bx
    same_side = ((oa > 0) & (ob > 0)) | ((oa < 0) & (ob < 0))
    collinear = (oa == 0) & (ob == 0)
    ta = dx * ax + dy * ay
    tb = dx * bx + dy * by
    dd = dx * dx + dy * dy
    overlap = (np.maximum(ta, tb) > 0) & (np.minimum(ta, tb) <= dd)
    ex = bx - ax
    ey = by - ay
    so = ey * ax - ex * ay
    sp = ex * (dy - ay) - ey * (dx - ax)
    crossing = (so != 0) & ((sp == 0) | ((sp > 0) != (so > 0)))
    at_sensor = (dx == 0) & (dy == 0)
    hidden = ~same_side & ~at_sensor & np.where(collinear, overlap, crossing)
    # Wall return: the `within_tolerance` predicate, op for op.
    vx = (s[:, 2] - s[:, 0])[None, :]
    vy = (s[:, 3] - s[:, 1])[None, :]
    wx = p[:, 0, None] - s[None, :, 0]
    wy = p[:, 1, None] - s[None, :, 1]
    c2 = vx * vx + vy * vy
    num = wx * vx + wy * vy
    t = np.divide(num, c2, out=np.zeros_like(num), where=c2 > 0)
    t = np.clip(t, 0.0, 1.0)
    qx = s[None, :, 0] + t * vx
    qy = s[None, :, 1] + t * vy
    rx = p[:, 0, None] - qx
    ry = p[:, 1, None] - qy
    near = rx * rx + ry * ry <= tol2
    return hidden | near


def line_of_sight_filter_numpy(
    points: Any,
    segments: Any,
    *,
    sensor: Any = (0.0, 0.0),
    tolerance: float = 0.1,
    chunk: int = 4096,
) -> np.ndarray:
    """Vectorised numpy O(n·m) peer of `line_of_sight_filter` (same result): all point ×
    segment pairs broadcast at once, `chunk` points at a time to bound memory."""
    p, s, o, tol = _check(points, segments, sensor, tolerance)
    keep = np.ones(len(p), dtype=bool)
    if len(s) == 0:
        return keep
    for start in range(0, len(p), chunk):
        block = p[start : start + chunk]
        keep[start : start + chunk] = ~_drop_numpy(block, s, o, tol * tol).any(axis=1)
    return keep
