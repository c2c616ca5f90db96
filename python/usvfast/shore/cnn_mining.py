"""A second training round of the shore CNN on hard negatives, with its confidence threshold
chosen by inner validation on the training videos.

    python -m usvfast.shore.cnn_mining ANNOTATIONS_DIR --base FIRST.onnx --out DIR
        [--exclude VIDEO ...] [--steps 900] [--hard-negative 0.35] [--name NAME]

1. Inner split: the last `val_fraction` of each training video's frames (in time; at least
   one frame) are kept out of training; they choose the confidence threshold.
2. Hard negatives: the first-round model `base` runs on the remaining training frames at a
   low confidence (`mine_conf`); its boxes that overlap no annotated boat (IoU < `max_iou`)
   are the frame's hard negatives — along an empty horizon on open sea, mostly.
3. A new network is trained from scratch on the same frames, a share `hard_negative` of its
   views centred on a hard negative (the focal loss then pushes those cells down).
4. The threshold: on the inner-validation frames, the grid value with the highest TPR whose
   FAR ≤ `max_far`; when none reaches it, the value of best F1. It is written as the model
   card's `conf_threshold`, with the validation scores. The held-out video is never used.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from usvfast._files import read_image
from usvfast.shore.boxes import Detections, iou_matrix
from usvfast.shore.cnn_train import (
    CnnTrainConfig,
    TrainFrame,
    export_model,
    load_frames,
    model_card,
    train_cnn,
)
from usvfast.shore.mardct import AnnotatedFrame, load_mardct
from usvfast.shore.scores import DetectionCounts

#: Confidence thresholds tried on the inner-validation frames.
THRESHOLD_GRID: tuple[float, ...] = tuple(round(0.05 * k, 2) for k in range(2, 14))


def inner_split(
    videos: dict[str, list[AnnotatedFrame]], val_fraction: float = 0.25
) -> tuple[list[AnnotatedFrame], list[AnnotatedFrame]]:
    """(training frames, validation frames): the last `val_fraction` of each video's frames
    (time order, at least one) go to validation, the rest to training."""
    if not 0.0 < val_fraction < 1.0:
        raise ValueError(f"val_fraction: expected 0 < f < 1, got {val_fraction}")
    fit, val = [], []
    for frames in videos.values():
        n_val = max(1, int(np.ceil(val_fraction * len(frames))))
        if n_val >= len(frames):
            raise ValueError("videos: a video needs at least two frames for the inner split")
        fit += frames[:-n_val]
        val += frames[-n_val:]
    return fit, val


def mine_negatives(
    frames: Sequence[TrainFrame],
    detect: Callable[[np.ndarray], Detections],
    max_iou: float = 0.1,
) -> list[TrainFrame]:
    """The frames with their hard negatives: `detect`'s boxes that overlap no annotated boat
    by IoU ≥ `max_iou` (corner form x1, y1, x2, y2 px, as the boxes)."""
    out = []
    for f in frames:
        d = detect(f.image)
        truth = np.concatenate([f.boxes[:, :2], f.boxes[:, 2:] - f.boxes[:, :2]], axis=1)
        if len(d) and len(truth):
            free = iou_matrix(truth, d.boxes).max(axis=0) < max_iou
        else:
            free = np.ones(len(d), dtype=bool)
        b = d.boxes[free].reshape(-1, 4)
        neg = np.concatenate([b[:, :2], b[:, :2] + b[:, 2:]], axis=1)
        out.append(TrainFrame(f.image, f.boxes, neg))
    return out


def choose_threshold(
    truth: Sequence[np.ndarray],
    dets: Sequence[Detections],
    max_far: float = 0.15,
    grid: Sequence[float] = THRESHOLD_GRID,
) -> tuple[float, list[dict]]:
    """(threshold, scores per grid value) on validation frames: `truth` (k, 4) x, y, w, h px
    per frame, `dets` scored at the lowest grid value or below. Highest TPR with FAR ≤
    `max_far` (ties: the higher threshold); none: best F1 = 2 TP / (2 TP + FP + FN)."""
    rows = []
    for c in grid:
        dc = DetectionCounts()
        for t, d in zip(truth, dets, strict=True):
            dc.add(t, d.boxes[d.scores >= c])
        n = 2 * dc.tp + dc.fp + dc.fn
        rows.append(
            {
                "conf": float(c),
                "tpr": dc.tpr,
                "far": dc.far,
                "f1": 2 * dc.tp / n if n else 0.0,
                "tp": dc.tp,
                "fp": dc.fp,
                "fn": dc.fn,
            }
        )
    ok = [r for r in rows if r["far"] <= max_far and r["tp"] > 0]
    if ok:
        best = max(ok, key=lambda r: (r["tpr"], r["conf"]))
    else:
        best = max(rows, key=lambda r: (r["f1"], r["conf"]))
    return best["conf"], rows


def train_hard_negative_round(
    annotations: Path | str,
    base_model: Path | str,
    out_dir: Path | str,
    config: CnnTrainConfig | None = None,
    exclude: Sequence[str] = (),
    name: str = "shore-cnn-hn",
    val_fraction: float = 0.25,
    mine_conf: float = 0.1,
    max_far: float = 0.15,
    log: Callable[[str], None] = print,
) -> dict:
    """Steps 1–4 of the module doc on every video of `annotations` except `exclude`; writes
    `name`.onnx/.pt/.json into `out_dir` and returns the model card."""
    from usvfast.shore.cnn import CnnDetector

    cfg = config or CnnTrainConfig(hard_negative=0.35)
    videos = load_mardct(annotations)
    names = [v for v in videos if v not in set(exclude)]
    if not names:
        raise ValueError("exclude: every video is excluded")
    fit, val = inner_split({v: videos[v] for v in names}, val_fraction)
    t0 = time.perf_counter()
    base = CnnDetector(base_model, conf_threshold=mine_conf)
    frames = mine_negatives(load_frames(fit), base.detect)
    n_neg = int(sum(len(f.negatives) for f in frames))
    log(f"{len(fit)} training frames, {n_neg} hard negatives; {len(val)} validation frames")
    net = train_cnn(frames, cfg, log)
    low = CnnDetector(net, conf_threshold=min(THRESHOLD_GRID), input_size=cfg.input_size)
    val_images = [read_image(f.path) for f in val]
    conf, rows = choose_threshold(
        [f.boxes for f in val], [low.detect(im) for im in val_images], max_far
    )
    seconds = time.perf_counter() - t0
    card = model_card(replace(cfg, conf_threshold=conf), names, seconds, net)
    card["conf_threshold"] = conf
    card["hard_negatives"] = {
        "base_model": Path(base_model).name,
        "mine_conf": mine_conf,
        "count": n_neg,
        "training_frames": len(fit),
    }
    card["inner_validation"] = {
        "frames": [f.path.name for f in val],
        "max_far": max_far,
        "chosen": conf,
        "sweep": rows,
    }
    log(f"threshold {conf:g} chosen on {len(val)} inner-validation frames")
    for p in export_model(net, out_dir, card, name):
        log(f"wrote {p} ({p.stat().st_size / 1e3:.0f} kB)")
    return card


def main(argv: Sequence[str] | None = None) -> None:
    """Command-line entry point (module doc)."""
    ap = argparse.ArgumentParser(
        prog="python -m usvfast.shore.cnn_mining", description=(__doc__ or "").splitlines()[0]
    )
    ap.add_argument("annotations", type=Path)
    ap.add_argument("--base", type=Path, required=True, help="First-round model (.onnx)")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--name", default="shore-cnn-hn")
    ap.add_argument("--seed", type=int, default=CnnTrainConfig.seed)
    ap.add_argument("--steps", type=int, default=CnnTrainConfig.steps)
    ap.add_argument("--hard-negative", type=float, default=0.35)
    ap.add_argument("--exclude", nargs="*", default=[])
    a = ap.parse_args(argv)
    cfg = CnnTrainConfig(seed=a.seed, steps=a.steps, hard_negative=a.hard_negative)
    card = train_hard_negative_round(a.annotations, a.base, a.out, cfg, a.exclude, a.name)
    print(json.dumps({k: card[k] for k in ("conf_threshold", "hard_negatives")}))


if __name__ == "__main__":
    main()
