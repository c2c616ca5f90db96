"""Truth and track objects grouped by frame, with their pairwise distance and similarity.

A `FrameSequence` is the common input of the multi-target scores (`mot_metrics`, `hota_metrics`,
`gospa_metrics`): for every frame it holds the truth ids, the track ids and the (n_truth,
n_tracks) matrices

- `distance`: the cost a match pays, NaN where the pair may not match. World positions:
  Euclidean metres, NaN beyond `max_distance`. Image boxes: 1 − IoU, NaN where IoU <
  `iou_threshold` (py-motmetrics' `iou_matrix` convention).
- `similarity`: in [0, 1], what HOTA scores. Boxes: IoU. Positions: max(0, 1 − d /
  `zero_distance`) (TrackEval's Euclidean similarity).

Frames are integers (a scan or image index); `frames_from_times` turns times into frame
indices. Example::

    seq = FrameSequence.from_positions(gt_frame, gt_id, gt_ne, trk_frame, trk_id, trk_ne,
                                       max_distance=5.0)
    seq = FrameSequence.from_boxes(gt_frame, gt_id, gt_xywh, trk_frame, trk_id, trk_xywh,
                                   iou_threshold=0.5)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from usvfast._core import DimensionError
from usvfast._validate import as_float_array


def _as_ints(name: str, value: Any) -> np.ndarray:
    arr = np.asarray(value)
    if arr.ndim != 1 or (arr.size and arr.dtype.kind not in "iu"):
        raise TypeError(f"{name}: expected a 1-D integer array, got {arr.dtype} {arr.shape}")
    return arr.astype(np.int64)


def _rows(prefix: str, frame: Any, ids: Any, values: Any, width: int) -> tuple[np.ndarray, ...]:
    f = _as_ints(f"{prefix}_frame", frame)
    i = _as_ints(f"{prefix}_ids", ids)
    v = as_float_array(f"{prefix}_values", np.reshape(values, (-1, width)), ndim=2)
    if not (len(f) == len(i) == len(v)):
        raise DimensionError(
            f"{prefix}_frame, {prefix}_ids, {prefix}_values: lengths differ "
            f"({len(f)}, {len(i)}, {len(v)})"
        )
    if len(i) and (i.min() < 0):
        raise ValueError(f"{prefix}_ids: ids must be non-negative")
    if len(i) and len(np.unique(np.column_stack([f, i]), axis=0)) != len(i):
        raise ValueError(f"{prefix}_ids: an id appears twice in one frame")
    return f, i, v


def box_iou(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """IoU of every box of `a` (n, 4) with every box of `b` (m, 4), boxes as (x, y, w, h)
    pixels with (x, y) the top-left corner (MOTChallenge). Returns (n, m) in [0, 1]."""
    a = np.reshape(np.asarray(a, float), (-1, 4))
    b = np.reshape(np.asarray(b, float), (-1, 4))
    ax1, ay1 = a[:, 0:1], a[:, 1:2]
    ax2, ay2 = ax1 + a[:, 2:3], ay1 + a[:, 3:4]
    bx1, by1 = b[:, 0], b[:, 1]
    bx2, by2 = bx1 + b[:, 2], by1 + b[:, 3]
    iw = np.clip(np.minimum(ax2, bx2) - np.maximum(ax1, bx1), 0.0, None)
    ih = np.clip(np.minimum(ay2, by2) - np.maximum(ay1, by1), 0.0, None)
    inter = iw * ih
    union = a[:, 2:3] * a[:, 3:4] + b[:, 2] * b[:, 3] - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        iou = np.where(union > 0, inter / union, 0.0)
    return iou


@dataclass(frozen=True)
class FrameSequence:
    """Per-frame truth/track ids and their distance and similarity matrices (module doc).

    frames: (F,) the frame numbers, ascending; truth_ids[k], track_ids[k]: (n_k,), (m_k,)
    integer ids at frames[k]; distance[k], similarity[k]: (n_k, m_k). kind: "position" or
    "box". truth_values[k], track_values[k]: the positions (metres) or boxes (pixels).
    """

    frames: np.ndarray
    truth_ids: list[np.ndarray]
    track_ids: list[np.ndarray]
    distance: list[np.ndarray]
    similarity: list[np.ndarray]
    truth_values: list[np.ndarray]
    track_values: list[np.ndarray]
    kind: str

    @property
    def n_truth(self) -> int:
        """Truth objects summed over frames."""
        return int(sum(len(g) for g in self.truth_ids))

    @property
    def n_tracks(self) -> int:
        """Track objects summed over frames."""
        return int(sum(len(t) for t in self.track_ids))

    @staticmethod
    def _group(
        gf: np.ndarray,
        gi: np.ndarray,
        gv: np.ndarray,
        tf: np.ndarray,
        ti: np.ndarray,
        tv: np.ndarray,
        frames: Any,
    ) -> tuple[np.ndarray, list[tuple[np.ndarray, ...]]]:
        if frames is None:
            allf = np.union1d(gf, tf)
        else:
            allf = np.union1d(_as_ints("frames", frames), np.union1d(gf, tf))
        go, to = np.argsort(gf, kind="stable"), np.argsort(tf, kind="stable")
        gb = np.searchsorted(gf[go], allf, side="left"), np.searchsorted(gf[go], allf, "right")
        tb = np.searchsorted(tf[to], allf, side="left"), np.searchsorted(tf[to], allf, "right")
        out = []
        for k in range(len(allf)):
            g = go[gb[0][k] : gb[1][k]]
            t = to[tb[0][k] : tb[1][k]]
            out.append((gi[g], gv[g], ti[t], tv[t]))
        return allf, out

    @classmethod
    def from_positions(
        cls,
        truth_frame: Any,
        truth_ids: Any,
        truth_positions: Any,
        track_frame: Any,
        track_ids: Any,
        track_positions: Any,
        *,
        max_distance: float = 5.0,
        zero_distance: float | None = None,
        frames: Any = None,
    ) -> FrameSequence:
        """World objects: positions (N, 2) metres (north, east) or any (N, d) with d the same for
        both. max_distance: metres, a pair matches only within it (CLEAR MOT, IDF1, GOSPA
        cut-off elsewhere). zero_distance: metres where HOTA's similarity reaches 0 (default
        max_distance). frames: extra frame numbers to include even when empty."""
        if not max_distance > 0:
            raise ValueError(f"max_distance: must be positive, got {max_distance}")
        zero = max_distance if zero_distance is None else zero_distance
        if not zero > 0:
            raise ValueError(f"zero_distance: must be positive, got {zero_distance}")
        d = np.shape(truth_positions)[-1] if np.ndim(truth_positions) == 2 else 2
        gf, gi, gv = _rows("truth", truth_frame, truth_ids, truth_positions, d)
        tf, ti, tv = _rows("track", track_frame, track_ids, track_positions, d)
        allf, groups = cls._group(gf, gi, gv, tf, ti, tv, frames)
        dist, sim = [], []
        for _, g, _, t in groups:
            dd = np.linalg.norm(g[:, None, :] - t[None, :, :], axis=2).reshape(len(g), len(t))
            sim.append(np.clip(1.0 - dd / zero, 0.0, None))
            dist.append(np.where(dd <= max_distance, dd, np.nan))
        return cls._of_groups(allf, groups, dist, sim, "position")

    @classmethod
    def _of_groups(cls, allf: Any, groups: list, dist: list, sim: list, kind: str) -> FrameSequence:
        """The sequence of `_group`'s frames and per-frame (truth ids, truth values, track
        ids, track values) with their distance and similarity matrices."""
        return cls(
            frames=allf,
            truth_ids=[x[0] for x in groups],
            track_ids=[x[2] for x in groups],
            distance=dist,
            similarity=sim,
            truth_values=[x[1] for x in groups],
            track_values=[x[3] for x in groups],
            kind=kind,
        )

    @classmethod
    def from_boxes(
        cls,
        truth_frame: Any,
        truth_ids: Any,
        truth_boxes: Any,
        track_frame: Any,
        track_ids: Any,
        track_boxes: Any,
        *,
        iou_threshold: float = 0.5,
        frames: Any = None,
    ) -> FrameSequence:
        """Image objects: boxes (N, 4) as (x, y, w, h) pixels, top-left origin (MOTChallenge).
        A pair matches when IoU ≥ iou_threshold; its CLEAR MOT distance is 1 − IoU."""
        if not 0 < iou_threshold <= 1:
            raise ValueError(f"iou_threshold: must lie in (0, 1], got {iou_threshold}")
        gf, gi, gv = _rows("truth", truth_frame, truth_ids, truth_boxes, 4)
        tf, ti, tv = _rows("track", track_frame, track_ids, track_boxes, 4)
        for name, v in (("truth_boxes", gv), ("track_boxes", tv)):
            if len(v) and (v[:, 2:] < 0).any():
                raise ValueError(f"{name}: widths and heights must be non-negative")
        allf, groups = cls._group(gf, gi, gv, tf, ti, tv, frames)
        dist, sim = [], []
        for _, g, _, t in groups:
            iou = box_iou(g, t)
            sim.append(iou)
            dist.append(np.where(iou >= iou_threshold - 1e-12, 1.0 - iou, np.nan))
        return cls._of_groups(allf, groups, dist, sim, "box")


def frames_from_times(times: ArrayLike, *, period: float, start: float | None = None) -> np.ndarray:
    """Frame index of each time: round((t − start) / period). times: (N,) seconds; period:
    seconds (> 0); start: seconds (default the smallest time)."""
    t = as_float_array("times", times, ndim=1)
    if not period > 0:
        raise ValueError(f"period: must be positive, got {period}")
    t0 = float(t.min()) if start is None and len(t) else (start or 0.0)
    return np.rint((t - t0) / period).astype(np.int64)
