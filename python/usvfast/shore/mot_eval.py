"""Tracking scores of the shore chain on annotated frames, in the layout of Bloisi et al.'s
Table III: CLEAR MOT with IoU ≥ 0.5 (MOTA with c_m = c_f = 1 and the switch cost log10 of eq. 6
as `mota_log10`, MOTA with unit switch cost as py-motmetrics, MOTP as the mean box IoU of the
matches, eq. 7), precision, recall, the false-positive share, IDF1 and HOTA
(`usvfast.metrics`, equal to py-motmetrics and TrackEval).

The trackers run over the annotated frames of one video in order; the particle tracker is
told the frame gaps (`dt` = difference of the frames' indices in their video), the SORT-like
and adaptive trackers step once per annotated frame. `truth_detections` turns the annotations
into detections (score 1), so a run on them measures the tracker alone (noise-free input).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import cv2
import numpy as np

from usvfast._validate import instance
from usvfast.metrics import FrameSequence, hota_metrics, mot_metrics
from usvfast.shore.boxes import Detections
from usvfast.shore.mardct import AnnotatedFrame
from usvfast.shore.particle import ParticleConfig, ParticleTracker
from usvfast.shore.pixel_kalman import AdaptiveTracker
from usvfast.shore.sort import SortConfig, SortTracker

#: Trackers scored.
TRACKERS: tuple[str, ...] = ("sort", "particle", "adaptive")

Tracks = tuple[np.ndarray, np.ndarray, np.ndarray]


def truth_detections(frames: Sequence[AnnotatedFrame]) -> list[Detections]:
    """The annotated boxes of each frame as detections (score 1, keypoints not counted)."""
    return [
        Detections(f.boxes.copy(), np.ones(len(f.boxes)), np.full(len(f.boxes), -1)) for f in frames
    ]


def derive_truth_ids(frames: Sequence[AnnotatedFrame], gate: float = 2.0) -> list[np.ndarray]:
    """Identities of the annotated boxes of one video (MarDCT's boxes carry none): each
    frame's boxes are linked to the previous frame's by optimal assignment on centre distance,
    a pair allowed within `gate` box diagonals; unlinked boxes get new ids (from 1)."""
    from scipy.optimize import linear_sum_assignment

    ids: list[np.ndarray] = []
    prev, prev_ids, next_id = np.zeros((0, 4)), np.zeros(0, np.int64), 1
    for f in frames:
        cur = np.full(len(f.boxes), -1, np.int64)
        if len(prev) and len(f.boxes):
            pc = prev[:, :2] + prev[:, 2:] / 2
            cc = f.boxes[:, :2] + f.boxes[:, 2:] / 2
            d = np.linalg.norm(pc[:, None] - cc[None], axis=2)
            limit = gate * np.hypot(prev[:, 2], prev[:, 3])[:, None]
            cost = np.where(d <= limit, d, 1e9)
            for i, j in zip(*linear_sum_assignment(cost), strict=True):
                if cost[i, j] < 1e9:
                    cur[j] = prev_ids[i]
        for j in np.flatnonzero(cur < 0):
            cur[j] = next_id
            next_id += 1
        ids.append(cur)
        prev, prev_ids = f.boxes, cur
    return ids


def run_tracker(
    frames: Sequence[AnnotatedFrame],
    dets: Sequence[Detections],
    tracker: str,
    images: Sequence[np.ndarray | None] | None = None,
    seed: int = 0,
    sort: SortConfig | None = None,
    particle: ParticleConfig | None = None,
) -> Tracks:
    """(frame numbers from 1, ids, boxes (n, 4) px) of `tracker` ('sort', 'particle' or
    'adaptive') over the frames with their detections. `images`: the BGR frames (read from
    the frames' paths when None). `sort`: the SORT-like tracker's parameters (default
    :class:`SortConfig`, one-stage association); `particle`: the particle tracker's (default
    :class:`ParticleConfig`; its seed is `seed`)."""
    if tracker not in TRACKERS:
        raise ValueError(f"tracker: expected one of {TRACKERS}, got {tracker!r}")
    if sort is not None:
        instance("sort", sort, SortConfig)
    if particle is not None:
        instance("particle", particle, ParticleConfig)
    if tracker == "particle":
        t: SortTracker | ParticleTracker | AdaptiveTracker = ParticleTracker(
            replace(particle or ParticleConfig(), seed=seed)
        )
    else:
        t = SortTracker(sort) if tracker == "sort" else AdaptiveTracker()
    fr, ids, boxes = [], [], []
    prev_index = None
    for n, (f, d) in enumerate(zip(frames, dets, strict=True), 1):
        image = images[n - 1] if images is not None else None
        if image is None and not isinstance(t, AdaptiveTracker):
            image = cv2.imread(str(f.path), cv2.IMREAD_COLOR)
        if isinstance(t, ParticleTracker):
            dt = 1.0 if prev_index is None else float(max(f.index - prev_index, 1))
            i, b, _ = t.step(image, d, dt)
        elif isinstance(t, SortTracker):
            if image is None:
                raise ValueError(f"images: cannot read {f.path}")
            i, b, _ = t.step(image, d)
        else:
            r = t.step(d)
            i, b = np.ones(len(r), np.int64), r.boxes
        prev_index = f.index
        fr += [n] * len(i)
        ids.append(np.asarray(i, np.int64))
        boxes.append(np.asarray(b, float).reshape(-1, 4))
    return (
        np.array(fr, np.int64),
        np.concatenate(ids) if ids else np.zeros(0, np.int64),
        np.concatenate(boxes) if boxes else np.zeros((0, 4)),
    )


def truth_sequence(frames: Sequence[AnnotatedFrame], tracks: Tracks) -> FrameSequence:
    """The IoU ≥ 0.5 frame sequence of the annotations (derived ids) against `tracks`."""
    gid = derive_truth_ids(frames)
    gf = np.concatenate([[n] * len(f.boxes) for n, f in enumerate(frames, 1)]).astype(np.int64)
    gi = np.concatenate(gid)
    gb = np.concatenate([f.boxes for f in frames])
    tf, ti, tb = tracks
    return FrameSequence.from_boxes(gf, gi, gb, tf, ti, tb, iou_threshold=0.5)


def mot_scores(frames: Sequence[AnnotatedFrame], tracks: Tracks) -> dict[str, float]:
    """Table III figures of `tracks` against the annotations (module doc): mota (unit switch
    cost), mota_log10 (eq. 6), motp_iou, precision, recall, fp_share (FP / reported boxes),
    idf1, hota, switches, misses, false_positives, n_truth."""
    seq = truth_sequence(frames, tracks)
    m = mot_metrics(seq)
    h = hota_metrics(seq)
    reported = m.matches + m.false_positives
    return {
        "mota": m.mota,
        "mota_log10": m.mota_log10,
        "motp_iou": m.motp_iou,
        "precision": m.precision,
        "recall": m.recall,
        "fp_share": m.false_positives / reported if reported else 0.0,
        "idf1": m.idf1,
        "hota": h.hota,
        "switches": int(m.switches),
        "misses": int(m.misses),
        "false_positives": int(m.false_positives),
        "n_truth": int(m.n_truth),
    }


def tracking_rows(
    frames: Sequence[AnnotatedFrame],
    dets: Sequence[Detections],
    trackers: Sequence[str] = TRACKERS,
    sort: SortConfig | None = None,
) -> dict[str, dict[str, float]]:
    """mot_scores of each tracker on one video's detections (frames read once); `sort`: the
    SORT-like tracker's parameters (see :func:`run_tracker`)."""
    images: list[np.ndarray | None] = [cv2.imread(str(f.path), cv2.IMREAD_COLOR) for f in frames]
    return {
        t: mot_scores(frames, run_tracker(frames, dets, t, images, sort=sort)) for t in trackers
    }
