"""The false-positive filters of Bloisi et al. (VTS camera surveillance, §IV "Noise filter"),
for the boxes of any detector (cascade, CNN, the user's YOLO).

* Reflection filter: a box holding a negligible number of keypoints is dropped (reflections on
  the water give few keypoints). The paper counts SURF keypoints; SURF is patented/non-free
  and absent from opencv-python-headless, so ORB (FAST corners with an orientation, free) is
  used instead.
* Wake filter: the paper adds a 25th boosted level to its cascade, trained with 4000 wake
  images and other false positives as negatives. Here that level is a boosted Haar stage
  (`usvfast._core.HaarCascade`, the 60 × 30 window of the cascade) trained on the annotated
  boats against water windows below the horizon (wakes, waves, reflections) and the
  detector's own false positives on the training frames; a box the stage rejects is dropped.

Boxes are x, y, w, h pixels of the frame (`usvfast.shore.boxes`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from usvfast._core import HaarCascade
from usvfast.shore.boxes import Detections, iou_matrix
from usvfast.shore.cascade import WINDOW, CascadeConfig, crop_window, positives, preprocess
from usvfast.shore.horizon import detect_horizon
from usvfast.shore.mardct import AnnotatedFrame


@dataclass(frozen=True)
class ReflectionFilter:
    """Drop boxes with fewer than `min_keypoints` ORB keypoints inside. `fast_threshold`:
    ORB's FAST corner threshold (8-bit levels); `max_keypoints`: ORB's cap per box;
    `margin_px`: the context around the box ORB sees (its border needs it)."""

    min_keypoints: int = 4
    fast_threshold: int = 12
    max_keypoints: int = 200
    margin_px: int = 16

    def __post_init__(self) -> None:
        if self.min_keypoints < 0 or self.max_keypoints < 1:
            raise ValueError("min_keypoints: must be >= 0 (and max_keypoints >= 1)")

    def counts(self, image: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """(k,) ORB keypoints whose centres lie inside each box of a BGR or grey frame."""
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
        h, w = gray.shape
        orb = cv2.ORB_create(  # pyright: ignore[reportAttributeAccessIssue]  # (not in the contrib stubs)
            nfeatures=self.max_keypoints,
            edgeThreshold=8,
            patchSize=15,
            fastThreshold=self.fast_threshold,
        )
        out = np.zeros(len(boxes), dtype=np.int64)
        for i, (x, y, bw, bh) in enumerate(np.asarray(boxes, dtype=float).reshape(-1, 4)):
            m = self.margin_px
            x0, y0 = max(int(x) - m, 0), max(int(y) - m, 0)
            x1, y1 = min(int(np.ceil(x + bw)) + m, w), min(int(np.ceil(y + bh)) + m, h)
            if x1 - x0 < 4 or y1 - y0 < 4:
                continue
            kps = orb.detect(np.ascontiguousarray(gray[y0:y1, x0:x1]), None)
            pts = np.array([k.pt for k in kps], dtype=float).reshape(-1, 2) + np.array([x0, y0])
            inside = (pts[:, 0] >= x) & (pts[:, 0] < x + bw) & (pts[:, 1] >= y)
            out[i] = int(np.sum(inside & (pts[:, 1] < y + bh)))
        return out

    def keep(self, image: np.ndarray, detections: Detections) -> np.ndarray:
        """Boolean mask (k,) of the detections holding at least `min_keypoints` keypoints."""
        if len(detections) == 0:
            return np.ones(0, dtype=bool)
        return self.counts(image, detections.boxes) >= self.min_keypoints


class WakeFilter:
    """A boosted stage that tells boats from wakes and water, applied to detected boxes
    (module doc). Build it with :meth:`train`; `keep(image, detections)` -> mask."""

    def __init__(self, stage: HaarCascade, config: CascadeConfig | None = None) -> None:
        self.stage = stage
        self.config = config or CascadeConfig()

    def windows(self, image: np.ndarray, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n, 30, 60) windows of the boxes (median-filtered grey, as the cascade) and the
        (k,) mask of the boxes that gave one (boxes under 4 px give none)."""
        gray = preprocess(image, self.config)
        wins, ok = [], np.zeros(len(boxes), dtype=bool)
        for i, b in enumerate(np.asarray(boxes, dtype=float).reshape(-1, 4)):
            win = crop_window(gray, b)
            if win is not None:
                wins.append(win)
                ok[i] = True
        arr = np.array(wins, dtype=np.uint8).reshape(-1, WINDOW[1], WINDOW[0])
        return np.ascontiguousarray(arr), ok

    def keep(self, image: np.ndarray, detections: Detections) -> np.ndarray:
        """Boolean mask (k,) of the detections the stage accepts (a box too small to cut a
        window from is kept)."""
        if len(detections) == 0:
            return np.ones(0, dtype=bool)
        wins, ok = self.windows(image, detections.boxes)
        out = np.ones(len(detections), dtype=bool)
        if len(wins):
            out[ok] = self.stage.accepts(wins)
        return out

    def save(self, path) -> None:
        """Write the stage as OpenCV cascade XML (`ShoreConfig.wake_model` reads it)."""
        from pathlib import Path

        Path(path).write_text(self.stage.to_opencv_xml(), encoding="utf-8")

    @staticmethod
    def train(
        frames: Sequence[AnnotatedFrame],
        detect: Callable[[np.ndarray], Detections] | None = None,
        *,
        negatives: int = 4000,
        min_hit_rate: float = 0.995,
        max_false_alarm: float = 0.5,
        max_weak: int = 40,
        seed: int = 0,
        config: CascadeConfig | None = None,
    ) -> WakeFilter:
        """Train the stage on annotated frames: positives are the boats (and mirror images);
        up to `negatives` negatives are the false positives of `detect` on the frames (IoU
        < 0.1 with every boat) and windows under the horizon that overlap no boat (the
        paper's 4000 wake images). `min_hit_rate`, `max_false_alarm`, `max_weak`: the
        stage's targets (as `HaarCascade.train`)."""
        cfg = config or CascadeConfig()
        rng = np.random.default_rng(seed)
        pos = positives(frames, cfg)
        if len(pos) == 0:
            raise ValueError("frames: no annotated boat to train on")
        per_frame = max(negatives // max(len(frames), 1), 1)
        negs: list[np.ndarray] = []
        for f in frames:
            image = cv2.imread(str(f.path), cv2.IMREAD_COLOR)
            if image is None:
                raise ValueError(f"frames: cannot read {f.path}")
            gray = preprocess(image, cfg)
            h, w = gray.shape
            cand = []
            if detect is not None:
                d = detect(image).boxes
                if len(d) and len(f.boxes):
                    d = d[iou_matrix(d, f.boxes).max(axis=1) < 0.1]
                cand += list(d)
            hz = detect_horizon(image)
            top = 0.0 if hz is None else float(np.clip(hz.y_at(w / 2), 0, h - 8))
            for _ in range(4 * per_frame):
                if len(cand) >= 2 * per_frame:
                    break
                bw = float(np.exp(rng.uniform(np.log(24), np.log(max(w * 0.6, 25)))))
                bh = bw / 2
                if h - top - bh <= 0:
                    continue
                b = np.array([rng.uniform(0, w - bw), rng.uniform(top, h - bh), bw, bh])
                if len(f.boxes) and iou_matrix(b[None], f.boxes).max() >= 0.05:
                    continue
                cand.append(b)
            for b in cand[: 2 * per_frame]:
                win = crop_window(gray, np.asarray(b))
                if win is not None:
                    negs.append(win)
        if len(negs) < 20:
            raise ValueError("frames: fewer than 20 wake/water negatives could be cut")
        neg = np.array(negs, dtype=np.uint8)[rng.permutation(len(negs))[:negatives]]
        stage = HaarCascade.train(
            pos,
            np.ascontiguousarray(neg),
            min_hit_rate=min_hit_rate,
            max_false_alarm=max_false_alarm,
            max_weak=max_weak,
            max_stages=1,
            negatives_per_stage=len(neg),
            feature_step=cfg.feature_step,
            target_false_alarm=max_false_alarm,
        )
        return WakeFilter(stage, cfg)
