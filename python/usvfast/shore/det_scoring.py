"""Scoring helpers of the leave-one-video-out detection evaluation
(:mod:`usvfast.shore.evaluate_det`): a video's frames with their horizons in memory, Bloisi et
al.'s TPR and FAR (eqs. 4–5, IoU ≥ 0.5) with the errors' causes (:mod:`usvfast.shore.errors`),
and the rule that picks a parameter setting on the training videos only."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from usvfast.shore.boxes import Detections
from usvfast.shore.daynight import DayNightClassifier
from usvfast.shore.errors import ErrorBreakdown
from usvfast.shore.horizon import HorizonConfig, HorizonLine, detect_horizon, horizon_keep
from usvfast.shore.mardct import AnnotatedFrame
from usvfast.shore.scores import DetectionCounts

#: The FAR bound of the aim (Bloisi et al.'s EO range); :func:`pick` maximises TPR under it.
FAR_AIM = 0.15


@dataclass
class VideoFrames:
    """The frames of one video in memory with their horizons (None: no valid line)."""

    frames: list[AnnotatedFrame]
    images: list[np.ndarray]
    horizons: list[HorizonLine | None]


def load_video(frames: Sequence[AnnotatedFrame], hcfg: HorizonConfig) -> VideoFrames:
    """Read a video's frames and find each frame's horizon (IR frames normalised first)."""
    classifier = DayNightClassifier.default()
    images, horizons = [], []
    for f in frames:
        image = cv2.imread(str(f.path), cv2.IMREAD_COLOR)
        if image is None:
            raise ValueError(f"data: cannot read {f.path}")
        images.append(image)
        ir = classifier.classify(image) == "ir"
        horizons.append(detect_horizon(image, infrared=ir, config=hcfg))
    return VideoFrames(list(frames), images, horizons)


def score(
    video: VideoFrames,
    dets: Sequence[Detections],
    hcfg: HorizonConfig,
    use_horizon: bool,
    extra: Callable[[np.ndarray, Detections], np.ndarray] | None = None,
) -> dict:
    """TPR, FAR, TP, FP, FN of per-frame detections after the horizon filter (when
    `use_horizon`) and an extra filter `extra(image, detections) -> keep mask`, and the
    errors' causes (`errors`: :meth:`usvfast.shore.errors.ErrorBreakdown.summary`)."""
    c = DetectionCounts()
    e = ErrorBreakdown()
    for f, im, hz, d in zip(video.frames, video.images, video.horizons, dets, strict=True):
        if use_horizon:
            d = d.subset(horizon_keep(d, hz, im.shape[0], hcfg))
        if extra is not None and len(d):
            d = d.subset(extra(im, d))
        c.add(f.boxes, d.boxes)
        e.add(f.boxes, d.boxes)
    return {"tpr": c.tpr, "far": c.far, "tp": c.tp, "fp": c.fp, "fn": c.fn, "errors": e.summary()}


def f1(s: dict) -> float:
    """2 TP / (2 TP + FP + FN) (0 without any box)."""
    n = 2 * s["tp"] + s["fp"] + s["fn"]
    return 2 * s["tp"] / n if n else 0.0


def both_horizons(video, dets, hcfg, extra=None, label: str = "") -> list[dict]:
    """Rows with the horizon filter off and on."""
    return [
        {"horizon": h, "filters": label, **score(video, dets, hcfg, h, extra)}
        for h in (False, True)
    ]


def pick(
    candidates: Sequence, pooled: Callable[[object], dict], low_far_ties: bool = False
) -> object:
    """The candidate whose pooled scores on the training videos (`pooled(c)`: TP, FP, FN)
    have the highest TPR with FAR ≤ :data:`FAR_AIM`; when none reaches that FAR, the best
    F1 (ties: the first; with `low_far_ties`, among equal TPRs the lowest FAR)."""
    scored = [(c, pooled(c)) for c in candidates]

    def rate(s: dict) -> tuple[float, float]:
        tpr = s["tp"] / max(s["tp"] + s["fn"], 1)
        far = s["fp"] / max(s["tp"] + s["fp"], 1)
        return tpr, far

    ok = [(c, s) for c, s in scored if rate(s)[1] <= FAR_AIM and s["tp"] > 0]
    if ok:
        if low_far_ties:
            return max(ok, key=lambda cs: (rate(cs[1])[0], -rate(cs[1])[1]))[0]
        return max(ok, key=lambda cs: rate(cs[1])[0])[0]
    return max(scored, key=lambda cs: f1(cs[1]))[0]


def pooled_score(
    videos: dict[str, VideoFrames], names: Sequence[str], dets: dict, hcfg: HorizonConfig
) -> dict:
    """TP, FP, FN summed over videos `names` of per-video detections `dets[v]` (horizon on)."""
    tot = {"tp": 0, "fp": 0, "fn": 0}
    for v in names:
        s = score(videos[v], dets[v], hcfg, True)
        tot = {k: tot[k] + s[k] for k in tot}
    return tot
