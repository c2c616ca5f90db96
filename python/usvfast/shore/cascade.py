"""The boat cascade of Bloisi et al. (§IV): Haar-like features in a 60 × 30 window, boosted
stumps per stage, trained here in Rust (`usvfast._core.HaarCascade`: OpenCV 4 removed
`opencv_traincascade`) and written as OpenCV cascade XML. Pre-processing as the paper's: a
median filter against wakes. Negatives are windows of boat-free regions of the training
frames; a final stage is trained on the cascade's own false positives on the water (wakes,
waves, reflections), as their 25th level.

Detection scans an image pyramid (scale step `scale_factor`) with the Rust evaluator and
groups overlapping raw windows (at least `min_neighbors` per group), as OpenCV's
`detectMultiScale` does.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from usvfast._core import HaarCascade
from usvfast._files import read_image
from usvfast.shore.boxes import Detections, iou_matrix
from usvfast.shore.horizon import detect_horizon
from usvfast.shore.mardct import AnnotatedFrame

#: The paper's detection window (width, height), pixels.
WINDOW = (60, 30)


@dataclass(frozen=True)
class CascadeConfig:
    """Training and detection parameters. median_kernel: median filter (odd, 1 = none).
    min_hit_rate, max_false_alarm, max_weak, max_stages, negatives_per_stage, feature_step,
    target_false_alarm: as `HaarCascade.train`. initial_stages: stages trained on the random
    pool before hard-negative mining. pool_size: negative windows cut from the boat-free
    regions; seed: their random draw. augment_copies: jittered copies of each boat (more
    positives, `positives`). wake_stage: train the final stage on water false positives.
    scale_factor, step_px, min_neighbors, group_iou: detection."""

    median_kernel: int = 3
    min_hit_rate: float = 0.995
    max_false_alarm: float = 0.5
    max_weak: int = 40
    max_stages: int = 14
    initial_stages: int = 3
    negatives_per_stage: int = 1000
    feature_step: int = 4
    target_false_alarm: float = 2e-5
    pool_size: int = 20000
    seed: int = 0
    wake_stage: bool = True
    augment_copies: int = 0
    scale_factor: float = 1.15
    step_px: int = 2
    min_neighbors: int = 3
    group_iou: float = 0.3


def preprocess(image: np.ndarray, cfg: CascadeConfig) -> np.ndarray:
    """Grey uint8 image, median-filtered."""
    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    return cv2.medianBlur(gray, cfg.median_kernel) if cfg.median_kernel > 1 else gray


def crop_window(gray: np.ndarray, box: np.ndarray) -> np.ndarray | None:
    """The box (x, y, w, h px) of a grey image resized to the 60 × 30 window (None if empty)."""
    h, w = gray.shape
    x0, y0 = max(int(np.rint(box[0])), 0), max(int(np.rint(box[1])), 0)
    x1 = min(int(np.rint(box[0] + box[2])), w)
    y1 = min(int(np.rint(box[1] + box[3])), h)
    if x1 - x0 < 4 or y1 - y0 < 4:
        return None
    return cv2.resize(gray[y0:y1, x0:x1], WINDOW, interpolation=cv2.INTER_AREA)


def positives(frames: Sequence[AnnotatedFrame], cfg: CascadeConfig) -> np.ndarray:
    """(p, 30, 60) uint8 windows of every annotated boat and of its mirror image, and
    `augment_copies` more per boat: the box shifted (± 8 % of its size), rescaled (± 10 %)
    and the window's contrast and brightness jittered (× 0.7–1.3, ± 25 levels), seeded."""
    rng = np.random.default_rng([cfg.seed, 1])
    out = []
    for f in frames:
        gray = preprocess(read_image(f.path, cv2.IMREAD_COLOR), cfg)
        for b in f.boxes:
            win = crop_window(gray, b)
            if win is not None:
                out += [win, win[:, ::-1]]
            for _ in range(cfg.augment_copies):
                s = rng.uniform(0.9, 1.1)
                w, h = b[2] * s, b[3] * s
                x = b[0] + b[2] / 2 - w / 2 + rng.uniform(-0.08, 0.08) * b[2]
                y = b[1] + b[3] / 2 - h / 2 + rng.uniform(-0.08, 0.08) * b[3]
                jit = crop_window(gray, np.array([x, y, w, h]))
                if jit is None:
                    continue
                v = (jit.astype(float) - 127.5) * rng.uniform(0.7, 1.3) + 127.5
                jit = np.clip(v + rng.uniform(-25, 25), 0, 255).astype(np.uint8)
                out.append(jit[:, ::-1] if rng.random() < 0.5 else jit)
    return np.ascontiguousarray(np.array(out, dtype=np.uint8).reshape(-1, WINDOW[1], WINDOW[0]))


def negative_pool(frames: Sequence[AnnotatedFrame], cfg: CascadeConfig) -> np.ndarray:
    """(n, 30, 60) uint8 windows of random position and size (2:1, 40 px wide up to the frame)
    that overlap no annotated boat (IoU < 0.05 and no boat centre inside)."""
    rng = np.random.default_rng(cfg.seed)
    per_frame = max(cfg.pool_size // max(len(frames), 1), 1)
    out = []
    for f in frames:
        gray = preprocess(read_image(f.path, cv2.IMREAD_COLOR), cfg)
        h, w = gray.shape
        got, tries = 0, 0
        centres = f.boxes[:, :2] + f.boxes[:, 2:] / 2
        while got < per_frame and tries < 20 * per_frame:
            tries += 1
            bw = float(np.exp(rng.uniform(np.log(40), np.log(min(w, 2 * h) * 0.9))))
            bh = bw / 2
            x, y = rng.uniform(0, w - bw), rng.uniform(0, h - bh)
            box = np.array([[x, y, bw, bh]])
            if len(f.boxes):
                if iou_matrix(box, f.boxes).max() >= 0.05:
                    continue
                inside = (centres[:, 0] > x) & (centres[:, 0] < x + bw)
                if np.any(inside & (centres[:, 1] > y) & (centres[:, 1] < y + bh)):
                    continue
            win = crop_window(gray, box[0])
            if win is not None:
                out.append(win)
                got += 1
    pool = np.array(out, dtype=np.uint8).reshape(-1, WINDOW[1], WINDOW[0])
    return np.ascontiguousarray(pool[rng.permutation(len(pool))])


def group_boxes(boxes: np.ndarray, min_neighbors: int, iou: float) -> Detections:
    """Groups raw windows (k, 4) whose IoU with a group's first window exceeds `iou`; groups
    with at least `min_neighbors` windows give their mean box, score = size / (size + 1)."""
    order = np.argsort(-(boxes[:, 2] * boxes[:, 3]), kind="stable") if len(boxes) else []
    boxes = boxes[order] if len(boxes) else boxes
    left = np.ones(len(boxes), bool)
    out, scores = [], []
    for i in range(len(boxes)):
        if not left[i]:
            continue
        members = left & (iou_matrix(boxes[i : i + 1], boxes)[0] > iou)
        members[i] = True
        left &= ~members
        n = int(members.sum())
        if n >= min_neighbors:
            out.append(boxes[members].mean(axis=0))
            scores.append(n / (n + 1))
    return Detections(
        np.array(out).reshape(-1, 4), np.array(scores), np.full(len(out), -1, dtype=np.int64)
    )


class CascadeDetector:
    """Boat detector with a trained `HaarCascade`; `detect(image)` -> Detections."""

    def __init__(self, cascade: HaarCascade, config: CascadeConfig | None = None) -> None:
        self.cascade = cascade
        self.config = config or CascadeConfig()

    def raw_windows(self, image: np.ndarray) -> np.ndarray:
        """(k, 4) accepted windows (x, y, w, h px of the frame) over the pyramid."""
        cfg = self.config
        gray = preprocess(image, cfg)
        h, w = gray.shape
        out = []
        s = 1.0
        while w / s >= WINDOW[0] and h / s >= WINDOW[1]:
            size = (int(w / s), int(h / s))
            img = gray if s == 1.0 else cv2.resize(gray, size, interpolation=cv2.INTER_LINEAR)
            hits = self.cascade.scan(np.ascontiguousarray(img), cfg.step_px)
            for x, y in hits:
                out.append([x * s, y * s, WINDOW[0] * s, WINDOW[1] * s])
            s *= cfg.scale_factor
        return np.array(out, dtype=float).reshape(-1, 4)

    def detect(self, image: np.ndarray) -> Detections:
        """Grouped detections of a BGR or grey uint8 frame."""
        cfg = self.config
        return group_boxes(self.raw_windows(image), cfg.min_neighbors, cfg.group_iou)


def false_windows(
    detector: CascadeDetector,
    frames: Sequence[AnnotatedFrame],
    limit: int,
    rng: np.random.Generator,
    water_only: bool = False,
) -> np.ndarray:
    """(n ≤ limit, 30, 60) windows the cascade accepts that overlap no boat (IoU < 0.1),
    drawn evenly over the frames; with `water_only`, only those under the horizon line
    (wakes, waves and reflections, for the final stage)."""
    per_frame = max(2 * limit // max(len(frames), 1), 1)
    out: list[np.ndarray] = []
    for k in rng.permutation(len(frames)):
        f = frames[k]
        image = read_image(f.path, cv2.IMREAD_COLOR)
        gray = preprocess(image, detector.config)
        raw = detector.raw_windows(image)
        if len(raw) and len(f.boxes):
            raw = raw[iou_matrix(raw, f.boxes).max(axis=1) < 0.1]
        if water_only and len(raw):
            hz = detect_horizon(image)
            if hz is not None:
                raw = raw[raw[:, 1] + raw[:, 3] / 2 > hz.y_at(raw[:, 0] + raw[:, 2] / 2)]
        if len(raw) > per_frame:
            raw = raw[rng.choice(len(raw), per_frame, replace=False)]
        for b in raw:
            win = crop_window(gray, b)
            if win is not None:
                out.append(win)
        if len(out) >= limit:
            break
    arr = np.array(out[:limit], dtype=np.uint8).reshape(-1, WINDOW[1], WINDOW[0])
    return np.ascontiguousarray(arr)


def train_detector(
    frames: Sequence[AnnotatedFrame], config: CascadeConfig | None = None
) -> tuple[CascadeDetector, dict]:
    """Train a cascade on annotated frames: the first `initial_stages` on random boat-free
    windows, each later stage on the false positives the cascade so far finds when it scans
    the training frames (hard negatives, as `opencv_traincascade` mines them), then the final
    stage on its false positives on the water. Returns the detector and a report."""
    cfg = config or CascadeConfig()
    rng = np.random.default_rng(cfg.seed)
    pos = positives(frames, cfg)
    if len(pos) == 0:
        raise ValueError("frames: no annotated boat to train on")
    pool = negative_pool(frames, cfg)
    cascade = HaarCascade.train(
        pos,
        pool,
        min_hit_rate=cfg.min_hit_rate,
        max_false_alarm=cfg.max_false_alarm,
        max_weak=cfg.max_weak,
        max_stages=cfg.initial_stages,
        negatives_per_stage=cfg.negatives_per_stage,
        feature_step=cfg.feature_step,
        target_false_alarm=cfg.target_false_alarm,
    )
    detector = CascadeDetector(cascade, cfg)
    report: dict = {"positives": len(pos), "negative_pool": len(pool), "mined": []}
    while cascade.num_stages < cfg.max_stages:
        negs = false_windows(detector, frames, cfg.negatives_per_stage, rng)
        report["mined"].append(len(negs))
        if len(negs) < 20:
            break
        cascade.add_stage(pos, negs)
    report["wake_negatives"] = 0
    if cfg.wake_stage and cascade.num_stages:
        wakes = false_windows(detector, frames, 4000, rng, water_only=True)
        report["wake_negatives"] = len(wakes)
        if len(wakes) >= 20:
            cascade.add_stage(pos, wakes)
    report["stages"] = cascade.stage_reports
    return detector, report


def save_cascade(detector: CascadeDetector, path: Path | str) -> None:
    """Write the detector's cascade as OpenCV cascade XML."""
    Path(path).write_text(detector.cascade.to_opencv_xml(), encoding="utf-8")
