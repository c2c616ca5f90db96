"""Per-detector scores in the protocol of the thesis's LiDAR test (§4.3.1, Table 6.1).

For each truth object and each sensor frame in which it is visible, the frame scores 1 (a true
positive) when the sensor produced a detection within `gate` m of the object's true position
at that frame, else 0 (a false negative). TP and FN are the counts, CN the longest run of
consecutive false negatives, TP rate = TP / frames. The thesis scored 50 consecutive frames
(5 s) per object: `max_frames=50` reproduces that, the default scores every visible frame.

Example::

    s = detector_scores(truth, detections, sensor="lidar", visible=in_range(truth, nav, 30))
    [(o.object_id, o.tp, o.fn, o.cn, o.tp_rate) for o in s]
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from usvfast._core import DimensionError
from usvfast._validate import instance
from usvfast.metrics.protocol import EXCLUDED_KINDS, truth_at
from usvfast.metrics.tables import Detections, Truth


@dataclass(frozen=True)
class DetectorScore:
    """Table 6.1 figures of one object (name: its id in the truth file): frames scored, tp,
    fn, cn (longest run of consecutive misses), tp_rate = tp / frames (NaN when no frame was
    scored)."""

    object_id: int
    name: str
    kind: str
    frames: int
    tp: int
    fn: int
    cn: int
    tp_rate: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return asdict(self)


def longest_run(flags: ArrayLike) -> int:
    """Length of the longest run of True in a 1-D boolean array."""
    f = np.asarray(flags, bool)
    if not f.any():
        return 0
    edges = np.diff(np.r_[0, f.astype(np.int8), 0])
    return int((np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)).max())


def detector_scores(
    truth: Truth,
    detections: Detections,
    *,
    sensor: str = "lidar",
    frame_times: ArrayLike | None = None,
    period: float = 0.1,
    gate: float = 1.0,
    visible: ArrayLike | None = None,
    max_frames: int | None = None,
    exclude_kinds: tuple[str, ...] = EXCLUDED_KINDS,
) -> list[DetectorScore]:
    """Table 6.1 scores of `sensor`'s detections for every truth object whose kind is not
    excluded (module doc). frame_times: (F,) s, the sensor's frame times; default a grid of
    `period` s from its first to its last detection. A detection belongs to the nearest frame
    within period/2. gate: metres. visible: (N,) bool over the truth rows (default all).
    Raises ValueError on a bad period/gate/max_frames, DimensionError on a wrong `visible`."""
    instance("truth", truth, Truth)
    instance("detections", detections, Detections)
    if not period > 0:
        raise ValueError(f"period: must be positive, got {period}")
    if not gate > 0:
        raise ValueError(f"gate: must be positive, got {gate}")
    if max_frames is not None and max_frames < 1:
        raise ValueError(f"max_frames: must be >= 1, got {max_frames}")
    vis = np.ones(len(truth.time), bool) if visible is None else np.asarray(visible, bool)
    if vis.shape != truth.time.shape:
        raise DimensionError(f"visible: expected shape {truth.time.shape}, got {vis.shape}")
    mine = detections.sensor == sensor
    dt, dp = detections.time[mine], detections.positions[mine]
    if frame_times is None:
        if len(dt) == 0:
            frames = np.zeros(0)
        else:
            t0 = dt.min()
            frames = t0 + period * np.arange(int(np.rint((dt.max() - t0) / period)) + 1)
    else:
        frames = np.sort(np.asarray(frame_times, float))
    out: list[DetectorScore] = []
    # frame of each detection: the nearest frame time within period / 2
    if len(frames) and len(dt):
        i = np.clip(np.searchsorted(frames, dt), 1, max(len(frames) - 1, 1))
        i = np.where(np.abs(frames[i - 1] - dt) <= np.abs(frames[i] - dt), i - 1, i)
        i = np.clip(i, 0, len(frames) - 1)
        ok = np.abs(frames[i] - dt) <= period / 2
        det_frame, det_pos = i[ok], dp[ok]
    else:
        det_frame, det_pos = np.zeros(0, np.int64), np.zeros((0, 2))
    for oid, kind in truth.kinds().items():
        if kind in exclude_kinds:
            continue
        sel = truth.object_id == oid
        ts = truth.time[sel]
        order = np.argsort(ts, kind="stable")
        ts, vs = ts[order], vis[sel][order].astype(float)
        pos = truth_at(truth, oid, frames, window=period / 2)
        inside = np.all(np.isfinite(pos), axis=1) & (np.interp(frames, ts, vs) >= 0.5)
        scored = np.flatnonzero(inside)
        if max_frames is not None:
            scored = scored[:max_frames]
        hit = np.zeros(len(frames), bool)
        if len(det_frame):
            near = np.linalg.norm(det_pos - pos[det_frame], axis=1) <= gate  # NaN: False
            hit[det_frame[near]] = True
        h = hit[scored]
        # consecutive misses count along consecutive scored frames only
        runs = np.split(~h, np.flatnonzero(np.diff(scored) > 1) + 1) if len(h) else []
        out.append(
            DetectorScore(
                object_id=oid,
                name=truth.name(oid),
                kind=kind,
                frames=len(scored),
                tp=int(h.sum()),
                fn=int((~h).sum()),
                cn=max((longest_run(r) for r in runs), default=0),
                tp_rate=float(h.mean()) if len(h) else float("nan"),
            )
        )
    return out
