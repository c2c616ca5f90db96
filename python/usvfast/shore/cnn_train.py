"""Train the shore CNN boat detector (HarbourNet, one class "boat") with torch on annotated
frames (MarDCT layout: `NAME_FRAME.png` + `NAME_FRAME.txt`), and export it for both backends.

    python -m usvfast.shore.cnn_train ANNOTATIONS_DIR --out DIR [--seed 0] [--steps 900]
        [--exclude VIDEO ...]

A few hundred boxes are enough because every training sample is a fresh random view of a
frame: random scale (0.6–1.5 × the size the frame has at the network input), random crop
near a boat or anywhere, left–right flip, contrast, brightness and per-channel colour gain,
occasional grey, blur and noise. Reproducible from `seed` (torch.manual_seed, a seeded numpy
generator, a fixed thread count). Writes `NAME.onnx` (:class:`usvfast.camera.dnn.OnnxDetector`,
OpenCV DNN, no torch), `NAME.pt` (TorchScript, :class:`usvfast.camera.yolo.YoloDetector`) and
`NAME.json` (model card: input size, training set-up and time, the videos trained on).
Needs torch and onnx (`pip install usvfast[yolo]`).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

from usvfast.shore.mardct import AnnotatedFrame, load_mardct

#: Name of the model files `usvfast shore-train --detector cnn` writes by default.
MODEL_NAME = "shore-cnn"


@dataclass(frozen=True)
class CnnTrainConfig:
    """Training set-up (recorded in the model card). Sizes (width, height) in network input
    pixels; `scale_range` multiplies the letterbox scale of a frame to `input_size`."""

    seed: int = 0
    input_size: tuple[int, int] = (224, 176)
    crop_size: tuple[int, int] = (224, 176)
    width: int = 16
    steps: int = 900
    batch: int = 12
    lr: float = 4e-3
    scale_range: tuple[float, float] = (0.6, 1.5)
    near_box: float = 0.7
    min_visible: float = 0.5
    min_box_px: float = 6.0
    threads: int = 1
    conf_threshold: float = 0.3
    #: probability that a training view is centred on one of its frame's hard negatives
    #: (:attr:`TrainFrame.negatives`, a former model's false alarms); 0 disables
    hard_negative: float = 0.0

    def __post_init__(self) -> None:
        for name in ("input_size", "crop_size"):
            w, h = getattr(self, name)
            if w % 16 or h % 16 or w <= 0 or h <= 0:
                raise ValueError(f"{name}: width and height must be positive multiples of 16")
        if not 0.0 <= self.hard_negative <= 1.0:
            raise ValueError(f"hard_negative: expected a probability, got {self.hard_negative}")
        if self.steps < 1 or self.batch < 1:
            raise ValueError("steps: steps and batch must be >= 1")
        lo, hi = self.scale_range
        if not 0 < lo <= hi:
            raise ValueError(f"scale_range: expected 0 < low <= high, got {self.scale_range}")


@dataclass(frozen=True)
class TrainFrame:
    """A training frame: `image` (H, W, 3) uint8 BGR, `boxes` (k, 4) x1, y1, x2, y2 px, and
    `negatives` (m, 4) x1, y1, x2, y2 px: hard negatives (boat-free regions where a former
    model fired) that views are centred on with probability `CnnTrainConfig.hard_negative`."""

    image: np.ndarray
    boxes: np.ndarray
    negatives: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))


def load_frames(frames: Sequence[AnnotatedFrame]) -> list[TrainFrame]:
    """Read the images of annotated frames; boxes become corner form (x1, y1, x2, y2)."""
    out = []
    for f in frames:
        image = cv2.imread(str(f.path), cv2.IMREAD_COLOR)
        if image is None:
            raise ValueError(f"frames: cannot read {f.path}")
        b = np.asarray(f.boxes, dtype=float).reshape(-1, 4)
        out.append(TrainFrame(image, np.concatenate([b[:, :2], b[:, :2] + b[:, 2:]], axis=1)))
    return out


def augment(
    frame: TrainFrame, cfg: CnnTrainConfig, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """One random view of a frame: (crop (ch, cw, 3) float32 RGB in [0, 1], boxes (k, 4)
    x1, y1, x2, y2 crop px). Boxes left with less than `min_visible` of their area or shorter
    than `min_box_px` are dropped."""
    h, w = frame.image.shape[:2]
    iw, ih = cfg.input_size
    cw, ch = cfg.crop_size
    lo, hi = cfg.scale_range
    s = min(iw / w, ih / h) * float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
    nw, nh = max(1, round(w * s)), max(1, round(h * s))
    img = cv2.resize(
        frame.image, (nw, nh), interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR
    )
    boxes = frame.boxes * [nw / w, nh / h, nw / w, nh / h]
    # the crop's top-left corner in the resized image (negative: padding)
    negatives = frame.negatives * [nw / w, nh / h, nw / w, nh / h]
    if cfg.hard_negative > 0 and len(negatives) and rng.random() < cfg.hard_negative:
        b = negatives[rng.integers(len(negatives))]
        cx = (b[0] + b[2]) / 2 + rng.uniform(-0.35, 0.35) * cw
        cy = (b[1] + b[3]) / 2 + rng.uniform(-0.35, 0.35) * ch
        x0, y0 = round(cx - cw / 2), round(cy - ch / 2)
    elif len(boxes) and rng.random() < cfg.near_box:
        b = boxes[rng.integers(len(boxes))]
        cx = (b[0] + b[2]) / 2 + rng.uniform(-0.35, 0.35) * cw
        cy = (b[1] + b[3]) / 2 + rng.uniform(-0.35, 0.35) * ch
        x0, y0 = round(cx - cw / 2), round(cy - ch / 2)
    else:
        x0 = int(rng.integers(min(0, nw - cw), max(0, nw - cw) + 1))
        y0 = int(rng.integers(min(0, nh - ch), max(0, nh - ch) + 1))
    x0 = int(np.clip(x0, min(0, nw - cw), max(0, nw - cw)))
    y0 = int(np.clip(y0, min(0, nh - ch), max(0, nh - ch)))
    out = np.full((ch, cw, 3), 114, np.uint8)
    sx0, sy0 = max(x0, 0), max(y0, 0)
    sx1, sy1 = min(x0 + cw, nw), min(y0 + ch, nh)
    out[sy0 - y0 : sy1 - y0, sx0 - x0 : sx1 - x0] = img[sy0:sy1, sx0:sx1]
    boxes = boxes - [x0, y0, x0, y0]
    clipped = np.clip(boxes, 0, [cw, ch, cw, ch])
    area = np.prod(np.clip(boxes[:, 2:] - boxes[:, :2], 1e-9, None), axis=1)
    size = clipped[:, 2:] - clipped[:, :2]
    keep = (np.prod(np.clip(size, 0, None), axis=1) / area >= cfg.min_visible) & (
        size.min(axis=1) >= cfg.min_box_px
    )
    boxes = clipped[keep].reshape(-1, 4)
    x = out[..., ::-1].astype(np.float32)  # BGR -> RGB as the detectors' preprocessing
    if rng.random() < 0.5:
        x = x[:, ::-1]
        boxes = np.stack([cw - boxes[:, 2], boxes[:, 1], cw - boxes[:, 0], boxes[:, 3]], 1)
    if rng.random() < 0.1:
        x = np.repeat(x.mean(axis=2, keepdims=True), 3, axis=2)
    x = x * rng.uniform(0.85, 1.15, 3).astype(np.float32)
    x = (x - 127.5) * rng.uniform(0.6, 1.4) + 127.5 + rng.uniform(-30, 30)
    if rng.random() < 0.2:
        x = cv2.GaussianBlur(np.ascontiguousarray(x), (0, 0), rng.uniform(0.5, 1.5))
    if rng.random() < 0.3:
        x = x + rng.normal(0, rng.uniform(1, 6), x.shape).astype(np.float32)
    return np.clip(x, 0, 255).astype(np.float32) / 255.0, boxes.reshape(-1, 4)


def train_cnn(
    frames: Sequence[AnnotatedFrame] | Sequence[TrainFrame],
    config: CnnTrainConfig | None = None,
    log: Callable[[str], None] = print,
) -> object:
    """Train a one-class :class:`usvfast.camera.harbour_net.HarbourNet` on annotated frames;
    returns the network (eval mode) sized for `config.input_size`."""
    import torch

    cfg = config or CnnTrainConfig()
    if all(isinstance(f, TrainFrame) for f in frames):
        data: list[TrainFrame] = [f for f in frames if isinstance(f, TrainFrame)]
    else:
        data = load_frames([f for f in frames if isinstance(f, AnnotatedFrame)])
    if not data or not sum(len(f.boxes) for f in data):
        raise ValueError("frames: no annotated boat to train on")
    threads = (torch.get_num_threads(), cv2.getNumThreads())
    torch.set_num_threads(cfg.threads)  # one thread: steady under a shared, loaded CPU
    cv2.setNumThreads(1)
    # flush denormals to zero while training (as the evaluated models were trained), and
    # restore the process-wide state afterwards (it would change float behaviour elsewhere)
    torch.set_flush_denormal(True)
    try:
        net = _fit(data, cfg, log)
    finally:
        torch.set_flush_denormal(False)
        torch.set_num_threads(threads[0])
        cv2.setNumThreads(threads[1])
    return net


def _fit(data: Sequence[TrainFrame], cfg: CnnTrainConfig, log: Callable[[str], None]):
    """The training loop of :func:`train_cnn` (global thread and float state already set)."""
    from usvfast.camera.harbour_net import fit

    def batch(rng: np.random.Generator) -> list:
        views = [augment(data[i], cfg, rng) for i in rng.integers(len(data), size=cfg.batch)]
        return [(img, boxes, np.zeros(len(boxes), np.int64)) for img, boxes in views]

    return fit(
        1,
        cfg.input_size,
        cfg.crop_size,
        cfg.width,
        steps=cfg.steps,
        lr=cfg.lr,
        seed=cfg.seed,
        batch=batch,
        log=log,
        log_every=100,
    )


def model_card(cfg: CnnTrainConfig, videos: Sequence[str], seconds: float, net) -> dict:
    """The JSON card written beside the weights (read by `usvfast.camera.backends`)."""
    return {
        "name": MODEL_NAME,
        "about": (
            "Shore-camera boat detector (one class), HarbourNet trained by "
            "usvfast.shore.cnn_train on annotated frames of the videos listed in 'videos'."
        ),
        "layout": "v8",
        "input_size": list(cfg.input_size),
        "classes": ["boat"],
        "conf_threshold": cfg.conf_threshold,
        "iou_threshold": 0.45,
        "parameters": int(sum(p.numel() for p in net.parameters())),
        "videos": list(videos),
        "train": {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(cfg).items()},
        "train_seconds": round(seconds, 1),
    }


def export_model(net, out_dir: Path | str, card: dict, name: str = MODEL_NAME) -> list[Path]:
    """Write `name`.onnx, `name`.pt (TorchScript) and the `name`.json model card."""
    from usvfast.camera.export import export_onnx, export_torchscript

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    size = tuple(card["input_size"])
    paths = [
        export_onnx(net, out / f"{name}.onnx", size),
        export_torchscript(net, out / f"{name}.pt", size),
    ]
    js = out / f"{name}.json"
    js.write_text(json.dumps(card, indent=2) + "\n", encoding="utf-8")
    return [*paths, js]


def train_and_export(
    annotations: Path | str,
    out_dir: Path | str,
    config: CnnTrainConfig | None = None,
    exclude: Sequence[str] = (),
    name: str = MODEL_NAME,
    log: Callable[[str], None] = print,
) -> dict:
    """Train on every video of `annotations` except `exclude`, export; the model card."""
    cfg = config or CnnTrainConfig()
    videos = load_mardct(annotations)
    names = [v for v in videos if v not in set(exclude)]
    if not names:
        raise ValueError("exclude: every video is excluded")
    t0 = time.perf_counter()
    net = train_cnn([f for v in names for f in videos[v]], cfg, log)
    card = model_card(cfg, names, time.perf_counter() - t0, net)
    for p in export_model(net, out_dir, card, name):
        log(f"wrote {p} ({p.stat().st_size / 1e3:.0f} kB)")
    return card


def main(argv: Sequence[str] | None = None) -> None:
    """Command-line entry point (module doc)."""
    ap = argparse.ArgumentParser(
        prog="python -m usvfast.shore.cnn_train", description=(__doc__ or "").splitlines()[0]
    )
    ap.add_argument("annotations", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--name", default=MODEL_NAME)
    ap.add_argument("--seed", type=int, default=CnnTrainConfig.seed)
    ap.add_argument("--steps", type=int, default=CnnTrainConfig.steps)
    ap.add_argument("--exclude", nargs="*", default=[])
    a = ap.parse_args(argv)
    cfg = CnnTrainConfig(seed=a.seed, steps=a.steps)
    train_and_export(a.annotations, a.out, cfg, a.exclude, a.name)


if __name__ == "__main__":
    main()
