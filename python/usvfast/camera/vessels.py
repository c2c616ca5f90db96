"""Moving vessels in the camera chain: one box per hull, moving boats told from moored ones by
their own motion, and the hull's centre with a covariance that spans the hull.

A demo (or any) network may box a vessel under way in several pieces and call it a moored
boat: the class alone cannot tell a boat that moves from one tied to a quay. Here the boxes
of the "boat" classes are handled apart from the floating objects:

1. :func:`fuse_boxes`: boat boxes of one frame that overlap (intersection over the smaller
   box's area ≥ `min_overlap`) become their union, so a hull boxed in pieces (bow, stern,
   cabin) gives one detection;
2. :class:`MovingBoats`: each frame's boat positions (NED m, the box bottom's waterline point)
   are kept for `history_s` seconds; p_k is an earlier frame's boat position nearest to the
   present one p (within `max_speed` · dt + `gate` m, dt ≥ `min_dt`). With at least
   `min_frames` such frames spanning at least `history_s` / 2 s, the line p_k = c − v dt_k
   is fitted by least squares; the boat counts as moving — and is passed to the tracker —
   when the line passes through p (|c − p| ≤ `max_residual` m: a box that just appeared
   beside another boat's trail does not), the median distance of the p_k from it is
   ≤ `max_residual` m and its speed |v| is ≥ `min_speed` m/s. A moored boat only jitters
   (the box edges move by a pixel or two): over ≥ 1 s that stays well below a vessel's
   1.5–2.5 m/s. Of the moving boats of a frame within `separation` m of each other only the
   best-scoring one is kept (the bow wave or the stern of a hull boxed apart moves with it);
3. :func:`hull_centre`: the box bottom images the hull's nearest waterline; the centre lies
   farther along the line of sight by half the hull's depth seen along that line,
   d = (L |cos α| + B |sin α|) / 2 for a hull of length L and beam B whose heading (the
   velocity's direction) makes the angle α with the line of sight; the covariance adds
   σ² along the line of sight and across it (:func:`hull_covariance`).
"""

from __future__ import annotations

from collections import deque

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

__all__ = ["MovingBoats", "fuse_boxes", "hull_centre", "hull_covariance", "separate"]


def fuse_boxes(
    boxes: np.ndarray, scores: np.ndarray, min_overlap: float = 0.3
) -> tuple[np.ndarray, np.ndarray]:
    """Union boxes (k', 4) xyxy px and their best scores (k',) of the groups of `boxes` (k, 4)
    that overlap, directly or through another box, by at least `min_overlap` of the smaller
    box's area (groups: connected components of the overlap graph)."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    if len(b) != len(s):
        raise ValueError(f"scores: expected {len(b)} values (one per box), got {len(s)}")
    if not 0.0 < min_overlap <= 1.0:
        raise ValueError(f"min_overlap: expected a fraction in (0, 1], got {min_overlap}")
    if len(b) < 2:
        return b.copy(), s.copy()
    w = np.clip(
        np.minimum(b[:, None, 2], b[None, :, 2]) - np.maximum(b[:, None, 0], b[None, :, 0]), 0, None
    )
    h = np.clip(
        np.minimum(b[:, None, 3], b[None, :, 3]) - np.maximum(b[:, None, 1], b[None, :, 1]), 0, None
    )
    area = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    small = np.maximum(np.minimum(area[:, None], area[None, :]), 1e-9)
    i, j = np.nonzero(w * h / small >= min_overlap)
    n, label = connected_components(coo_matrix((np.ones(len(i)), (i, j)), shape=(len(b),) * 2))
    out = np.zeros((n, 4))
    best = np.zeros(n)
    for g in range(n):
        m = label == g
        out[g] = [b[m, 0].min(), b[m, 1].min(), b[m, 2].max(), b[m, 3].max()]
        best[g] = s[m].max()
    order = np.argsort(-best, kind="stable")
    return out[order], best[order]


class MovingBoats:
    """Boat positions of the last `history_s` s and the velocity test of the module doc.

    min_speed, max_speed: m/s; gate: m added to max_speed · dt when looking for a boat's
    position in an earlier frame; min_dt: s, earlier frames closer in time are not used (a
    jitter of a pixel over 0.1 s would look like a speed); min_frames: earlier frames needed;
    max_residual: m, the fitted line's distance from the present position and the median
    distance of the earlier positions from it.
    """

    def __init__(
        self,
        *,
        history_s: float = 1.5,
        min_speed: float = 0.8,
        max_speed: float = 5.0,
        gate: float = 1.5,
        min_dt: float = 0.5,
        min_frames: int = 3,
        max_residual: float = 1.5,
    ) -> None:
        if not history_s > min_dt >= 0:
            raise ValueError(
                f"history_s, min_dt: expected history_s > min_dt >= 0, got {history_s}, {min_dt}"
            )
        if not 0 <= min_speed < max_speed:
            raise ValueError(
                f"min_speed, max_speed: expected 0 <= min_speed < max_speed, got {min_speed}, "
                f"{max_speed}"
            )
        if gate < 0 or min_frames < 1:
            raise ValueError(f"gate, min_frames: expected >= 0 and >= 1, got {gate}, {min_frames}")
        self.history_s, self.min_speed, self.max_speed = history_s, min_speed, max_speed
        self.gate, self.min_dt, self.min_frames = gate, min_dt, int(min_frames)
        self.max_residual = float(max_residual)
        self._frames: deque[tuple[float, np.ndarray]] = deque()

    def update(self, t: float, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Velocities (k, 2) NED m/s of this frame's boats at `positions` (k, 2) NED m taken at
        `t` s (NaN where no earlier frame gives one) and the (k,) mask of the moving ones;
        then remembers the frame (frames must come in time order)."""
        p = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        while self._frames and self._frames[0][0] < t - self.history_s:
            self._frames.popleft()
        vel = np.full((len(p), 2), np.nan)
        for k in range(len(p)):
            gaps, past = [], []
            for tk, pk in self._frames:
                dt = t - tk
                if dt < self.min_dt or len(pk) == 0:
                    continue
                d = p[k] - pk
                dist = np.hypot(d[:, 0], d[:, 1])
                j = int(np.argmin(dist))
                if dist[j] <= self.max_speed * dt + self.gate:
                    gaps.append(dt)
                    past.append(pk[j])
            if len(gaps) < self.min_frames or max(gaps) - min(gaps) < self.history_s / 2:
                continue
            # the earlier positions as a line in time, p_k = c - v dt_k (least squares): a
            # boat's own trail passes through its present position (c = p) and lies on the
            # line; a box that just appeared beside another boat's trail does not
            a = np.column_stack([np.ones(len(gaps)), -np.asarray(gaps)])
            coef, *_ = np.linalg.lstsq(a, np.asarray(past), rcond=None)
            res = np.hypot(*(np.asarray(past) - a @ coef).T)
            if np.hypot(*(coef[0] - p[k])) <= self.max_residual and np.median(res) <= (
                self.max_residual
            ):
                vel[k] = coef[1]
        speed = np.hypot(vel[:, 0], vel[:, 1])
        moving = np.isfinite(speed) & (speed >= self.min_speed)
        self._frames.append((float(t), p[np.all(np.isfinite(p), axis=1)]))
        return vel, moving


def separate(positions: np.ndarray, scores: np.ndarray, separation: float) -> np.ndarray:
    """Mask (k,) of the positions (k, 2) m kept when, greedily by descending score (k,), a
    position within `separation` m of a kept one is dropped."""
    p = np.asarray(positions, float).reshape(-1, 2)
    keep = np.zeros(len(p), bool)
    for i in np.argsort(-np.asarray(scores, float), kind="stable"):
        near = np.hypot(*(p[keep] - p[i]).T) < separation
        keep[i] = not near.any()
    return keep


def hull_centre(
    contact: np.ndarray,
    camera_ne: np.ndarray,
    velocity: np.ndarray,
    length: float,
    beam: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Hull centres (k, 2) NED m and the depths d (k,) m of the module doc: `contact` (k, 2)
    the nearest waterline points, `camera_ne` (2,) the camera's position, `velocity` (k, 2)
    m/s (its direction is the heading), `length`, `beam` m."""
    los = np.asarray(contact, float) - np.asarray(camera_ne, float)[None]
    rng = np.maximum(np.hypot(los[:, 0], los[:, 1]), 1e-9)
    u = los / rng[:, None]
    v = np.asarray(velocity, float)
    speed = np.maximum(np.hypot(v[:, 0], v[:, 1]), 1e-9)
    cos_a = np.abs((u * v).sum(1)) / speed
    sin_a = np.sqrt(np.clip(1.0 - cos_a**2, 0.0, 1.0))
    depth = 0.5 * (length * cos_a + beam * sin_a)
    return contact + depth[:, None] * u, depth


def hull_covariance(
    contact: np.ndarray, camera_ne: np.ndarray, along_std: float, across_std: float
) -> np.ndarray:
    """(k, 2, 2) m² covariance with `along_std` m along each line of sight (camera ->
    `contact`) and `across_std` m across it: the spread of a hull's centre about the point
    taken from a box that boxes it whole or in part (and of a floating object's centre about
    the point taken from its box)."""
    los = np.asarray(contact, float) - np.asarray(camera_ne, float)[None]
    u = los / np.maximum(np.hypot(los[:, 0], los[:, 1]), 1e-9)[:, None]
    c = np.stack([-u[:, 1], u[:, 0]], axis=1)
    return (
        along_std**2 * u[:, :, None] * u[:, None, :] + across_std**2 * c[:, :, None] * c[:, None, :]
    )
