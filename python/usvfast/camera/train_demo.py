"""Train the bundled harbour demo detector on frames of the harbour simulator, evaluate it on
frames of unseen seeds, and export it for both backends.

    python -m usvfast.camera.train_demo --out python/usvfast/data/models

Reproducible from `--seed` (torch.manual_seed, seeded numpy, one torch thread by default): the
training frames come from simulator seeds `TRAIN_SEEDS`, the held-out frames from
`HELDOUT_SEEDS` (neither overlaps the seeds of the demo and test recordings). Writes
`harbour-demo.pt` (TorchScript, :class:`usvfast.camera.yolo.YoloDetector`),
`harbour-demo.onnx` (:class:`usvfast.camera.dnn.OnnxDetector`, no torch) and
`harbour-demo.json` (the model card: input size, classes, training set-up, held-out
precision/recall at IoU >= 0.5, training time).

This is a demo model for the simulated harbour, not a detector of real floating trash: for
real recordings bring your own YOLO weights through the pipeline config.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from usvfast.camera.detect import Detections, letterbox

#: Simulator seeds the training frames come from, and the held-out ones for the evaluation.
TRAIN_SEEDS = tuple(range(1000, 1018))
HELDOUT_SEEDS = (2000, 2001, 2002)


@dataclass(frozen=True)
class Frame:
    """One rendered frame: `image` (H, W, 3) uint8 BGR, ground-truth `boxes` (k, 4) xyxy px,
    `classes` (k,) int64 indices into the model's class names."""

    image: np.ndarray
    boxes: np.ndarray
    classes: np.ndarray


@dataclass
class TrainConfig:
    """Training set-up (all recorded in the model card). Sizes in input pixels (w, h).

    `min_box_px` is the evaluation's floor for the IoU figures (smaller boxes are scored by
    :func:`small_recall`); training uses every rendered box. Crops are centred on objects with
    per-class weights (`trash_weight` for the three float kinds, `vessel_weight`) times
    `small_weight` for boxes whose shorter side is under `small_px`; `tiny_px` and `balance`
    are the tiny-box assignment and the per-box loss weights of
    :func:`usvfast.camera.harbour_net.assign`."""

    seed: int = 0
    input_size: tuple[int, int] = (640, 368)
    crop_size: tuple[int, int] = (320, 192)
    width: int = 16
    steps: int = 2500
    batch: int = 12
    lr: float = 3e-3
    frames_per_seed: int = 24
    heldout_frames_per_seed: int = 8
    min_box_px: float = 3.0
    conf_threshold: float = 0.3
    trash_weight: float = 2.0
    vessel_weight: float = 8.0
    small_px: float = 4.0
    small_weight: float = 3.0
    tiny_px: float = 8.0
    balance: bool = True
    threads: int = 1
    train_seeds: tuple[int, ...] = TRAIN_SEEDS
    heldout_seeds: tuple[int, ...] = HELDOUT_SEEDS
    classes: tuple[str, ...] = field(default_factory=tuple)


def _box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU matrix (n, m) of boxes a (n, 4) and b (m, 4) xyxy."""
    lt = np.maximum(a[:, None, :2], b[None, :, :2])
    rb = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(rb - lt, 0, None), axis=2)
    area_a = np.prod(a[:, 2:] - a[:, :2], axis=1)
    area_b = np.prod(b[:, 2:] - b[:, :2], axis=1)
    return inter / np.maximum(area_a[:, None] + area_b[None, :] - inter, 1e-12)


def match_counts(
    det: Detections,
    boxes: np.ndarray,
    classes: np.ndarray,
    ignore: np.ndarray | None = None,
    iou: float = 0.5,
    class_aware: bool = False,
) -> tuple[int, int, int]:
    """(true positives, false positives, false negatives) of one frame: detections, in
    descending score, take the unmatched ground-truth box of highest IoU >= `iou` (of the same
    class when `class_aware`). Ground truth flagged in `ignore` (k,) counts neither as a miss
    nor, when matched, as a false positive (too small to ask for)."""
    ignore = np.zeros(len(boxes), bool) if ignore is None else np.asarray(ignore, bool)
    ious = _box_iou(det.boxes, boxes) if len(det.boxes) and len(boxes) else None
    taken = np.zeros(len(boxes), bool)
    tp = fp = 0
    for i in np.argsort(-det.scores, kind="stable"):
        if ious is None:
            fp += 1
            continue
        cand = ious[i] * ~taken
        if class_aware:
            cand = cand * (classes == det.classes[i])
        j = int(np.argmax(cand))
        if cand[j] >= iou:
            taken[j] = True
            tp += int(not ignore[j])
        else:
            fp += 1
    fn = int((~taken & ~ignore).sum())
    return tp, fp, fn


def evaluate(
    detector: Callable[[list[np.ndarray]], Sequence[Detections]],
    frames: Iterable[Frame],
    min_box_px: float,
    iou: float = 0.5,
) -> dict[str, float]:
    """Precision and recall at IoU >= `iou` over `frames`, class-agnostic and class-aware, and
    each class's class-aware recall (`class{k}_recall`, over `class{k}_truth` boxes);
    ground-truth boxes whose shorter side is under `min_box_px` px are ignored."""
    tot = np.zeros((2, 3), dtype=np.int64)
    per_class: dict[int, np.ndarray] = {}
    n_frames = 0
    for f in frames:
        (det,) = detector([f.image])
        small = np.min(f.boxes[:, 2:] - f.boxes[:, :2], axis=1) < min_box_px
        for k, aware in enumerate((False, True)):
            tot[k] += match_counts(det, f.boxes, f.classes, small, iou, aware)
        # class-aware recall of each class: the other classes' boxes are ignored
        for c in np.unique(f.classes).tolist():
            counts = match_counts(det, f.boxes, f.classes, small | (f.classes != c), iou, True)
            per_class[c] = per_class.get(c, np.zeros(3, np.int64)) + counts
        n_frames += 1
    out: dict[str, float] = {"frames": n_frames, "truth": int(tot[0, 0] + tot[0, 2])}
    for k, name in enumerate(("", "class_")):
        tp, fp, fn = (int(v) for v in tot[k])
        out[f"{name}precision"] = tp / max(tp + fp, 1)
        out[f"{name}recall"] = tp / max(tp + fn, 1)
        out[f"{name}tp"], out[f"{name}fp"], out[f"{name}fn"] = tp, fp, fn
    for c in sorted(per_class):
        tp, fn = int(per_class[c][0]), int(per_class[c][2])
        out[f"class{c}_recall"] = tp / max(tp + fn, 1)
        out[f"class{c}_truth"] = tp + fn
    return out


def small_recall(
    detector: Callable[[list[np.ndarray]], Sequence[Detections]],
    frames: Iterable[Frame],
    min_box_px: float,
    classes: Sequence[int] = (0, 1, 2),
    max_offset_px: float = 2.0,
) -> dict[str, float]:
    """Recall of the small floats: ground-truth boxes of `classes` whose shorter side is under
    `min_box_px` (those :func:`evaluate` ignores), each found when a detection of any class has
    its centre within `max_offset_px` px of the box's centre (one detection finds one box,
    nearest first). IoU is no measure at this size: 1 px of offset on a 2 px box is IoU 0.14."""
    found = truth = 0
    for f in frames:
        (det,) = detector([f.image])
        side = np.min(f.boxes[:, 2:] - f.boxes[:, :2], axis=1)
        small = (side < min_box_px) & np.isin(f.classes, classes)
        truth += int(small.sum())
        if not small.any() or not len(det.boxes):
            continue
        tc = (f.boxes[small, :2] + f.boxes[small, 2:]) / 2
        dc = (det.boxes[:, :2] + det.boxes[:, 2:]) / 2
        d = np.linalg.norm(tc[:, None] - dc[None], axis=2)  # (small truth, detections) px
        for _ in range(min(d.shape)):
            i, j = np.unravel_index(int(np.argmin(d)), d.shape)
            if d[i, j] > max_offset_px:
                break
            found += 1
            d[i, :], d[:, j] = np.inf, np.inf
    return {"small_truth": truth, "small_found": found, "small_recall": found / max(truth, 1)}


# ---------------------------------------------------------------------------------------------
# Training data

#: JPEG quality of the frames (the simulated bag stores its images as JPEG of about this).
JPEG_QUALITY = 70


def render_frames(seed: int, n: int, duration: float = 60.0) -> list[Frame]:
    """`n` frames of the simulated harbour of `seed` (``usvfast.sim``), at evenly spread times
    over `duration` s with a seeded jitter, JPEG-compressed as in a recording; the classes are
    indices into ``usvfast.sim.TRUTH_KINDS``."""
    import cv2

    from usvfast.sim import TRUTH_KINDS, HarbourRenderer, make_world

    rng = np.random.default_rng([seed, 7])
    renderer = HarbourRenderer(make_world(seed, duration))
    times = (np.arange(n) + rng.uniform(0.0, 1.0, n)) * duration / n
    frames = []
    for t in times:
        image, truth = renderer.render(float(t))
        _, jpg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        image = cv2.imdecode(jpg, cv2.IMREAD_COLOR)
        assert image is not None  # decoding what imencode just wrote
        boxes = np.array([b.xyxy for b in truth], dtype=np.float64).reshape(-1, 4)
        classes = np.array([TRUTH_KINDS.index(b.kind) for b in truth], dtype=np.int64)
        frames.append(Frame(image, boxes, classes))
    return frames


@dataclass(frozen=True)
class Sample:
    """A training frame letterboxed to the network input: `image` (h, w, 3) uint8 RGB,
    `boxes` (k, 4) xyxy input px, `classes` (k,)."""

    image: np.ndarray
    boxes: np.ndarray
    classes: np.ndarray


def to_sample(frame: Frame, input_size: tuple[int, int]) -> Sample:
    """Letterbox a frame exactly as the detectors' preprocessing does (BGR -> RGB)."""
    img, info = letterbox(frame.image, input_size)
    return Sample(
        np.ascontiguousarray(img[..., ::-1]), info.to_letterbox(frame.boxes), frame.classes
    )


def random_crop(
    s: Sample,
    crop: tuple[int, int],
    rng: np.random.Generator,
    weights: np.ndarray | None = None,
    small_px: float = 0.0,
    small_weight: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A `crop` (w, h) window of a sample, centred near a random object 80 % of the time (drawn
    uniformly, or with per-class `weights` to favour e.g. the small floating objects, times
    `small_weight` for boxes whose shorter side is under `small_px` px), randomly flipped
    left-right and jittered in brightness/contrast; boxes clipped to the window, those left
    with < 40 % of their area dropped."""
    h, w = s.image.shape[:2]
    cw, ch = crop
    if len(s.boxes) and rng.random() < 0.8:
        if weights is None and small_weight == 1.0:
            b = s.boxes[rng.integers(len(s.boxes))]
        else:
            p = np.ones(len(s.boxes)) if weights is None else weights[s.classes].astype(float)
            side = np.min(s.boxes[:, 2:] - s.boxes[:, :2], axis=1)
            p = p * np.where(side < small_px, small_weight, 1.0)
            b = s.boxes[rng.choice(len(s.boxes), p=p / p.sum())]
        cx = (b[0] + b[2]) / 2 + rng.uniform(-0.4, 0.4) * cw
        cy = (b[1] + b[3]) / 2 + rng.uniform(-0.4, 0.4) * ch
        x0, y0 = int(np.clip(cx - cw / 2, 0, w - cw)), int(np.clip(cy - ch / 2, 0, h - ch))
    else:
        x0, y0 = int(rng.integers(0, w - cw + 1)), int(rng.integers(0, h - ch + 1))
    img = s.image[y0 : y0 + ch, x0 : x0 + cw].astype(np.float32)
    boxes = s.boxes - [x0, y0, x0, y0]
    clipped = np.clip(boxes, 0, [cw, ch, cw, ch])
    area = np.prod(np.clip(boxes[:, 2:] - boxes[:, :2], 1e-9, None), axis=1)
    kept = np.prod(np.clip(clipped[:, 2:] - clipped[:, :2], 0, None), axis=1) / area >= 0.4
    boxes, classes = clipped[kept], s.classes[kept]
    if rng.random() < 0.5:
        img = img[:, ::-1]
        boxes = np.stack([cw - boxes[:, 2], boxes[:, 1], cw - boxes[:, 0], boxes[:, 3]], 1)
    img = (img - 127.5) * rng.uniform(0.75, 1.25) + 127.5 + rng.uniform(-20, 20)
    return np.clip(img, 0, 255) / 255.0, boxes.reshape(-1, 4), classes


def cached(
    render: Callable[[int, int], list[Frame]], folder: Path
) -> Callable[[int, int], list[Frame]]:
    """`render` with its frames kept in `folder` (one `.npz` per seed and count), so that a
    second training run skips the rendering."""

    def wrapped(seed: int, n: int) -> list[Frame]:
        path = Path(folder) / f"frames-{seed}-{n}.npz"
        if path.is_file():
            z = np.load(path)
            return [
                Frame(z[f"image{i}"], z[f"boxes{i}"], z[f"classes{i}"]) for i in range(int(z["n"]))
            ]
        frames = render(seed, n)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays: dict[str, np.ndarray] = {"n": np.array(len(frames))}
        for i, f in enumerate(frames):
            arrays.update({f"image{i}": f.image, f"boxes{i}": f.boxes, f"classes{i}": f.classes})
        np.savez(path, **arrays)  # pyright: ignore[reportArgumentType]  # (arrays by name)
        return frames

    return wrapped


# ---------------------------------------------------------------------------------------------
# Training


def train(
    config: TrainConfig,
    train_frames: Sequence[Frame],
    log: Callable[[str], None] = print,
) -> object:
    """Train a :class:`usvfast.camera.harbour_net.HarbourNet` on `train_frames`; returns the
    network in eval mode."""
    from usvfast.camera.harbour_net import fit

    samples = [to_sample(f, config.input_size) for f in train_frames]
    # The first three classes are the small floating objects (usvfast.sim.FLOAT_KINDS). A
    # moving vessel renders like a moored boat (hull + cabin) and is several times rarer in
    # the frames, so `vessel_weight` centres more crops on vessels to balance the two.
    weights = None
    if config.trash_weight != 1.0 or config.vessel_weight != 1.0:
        weights = np.ones(len(config.classes))
        weights[:3] = config.trash_weight
        if "vessel" in config.classes:
            weights[list(config.classes).index("vessel")] = config.vessel_weight
    return fit(
        len(config.classes),
        config.input_size,
        config.crop_size,
        config.width,
        steps=config.steps,
        lr=config.lr,
        seed=config.seed,
        batch=lambda rng: [
            random_crop(
                samples[i], config.crop_size, rng, weights, config.small_px, config.small_weight
            )
            for i in rng.integers(len(samples), size=config.batch)
        ],
        log=log,
        log_every=50,
        tiny_px=config.tiny_px,
        balance=config.balance,
    )


# ---------------------------------------------------------------------------------------------
# Export and the command line


def export(net: object, out_dir: Path, card: dict, name: str = "harbour-demo") -> list[Path]:
    """Write `name`.pt (TorchScript), `name`.onnx and the `name`.json model card."""
    from usvfast.camera.export import export_onnx, export_torchscript

    out_dir.mkdir(parents=True, exist_ok=True)
    size = tuple(card["input_size"])
    pt = export_torchscript(net, out_dir / f"{name}.pt", size)
    onnx = export_onnx(net, out_dir / f"{name}.onnx", size)
    js = out_dir / f"{name}.json"
    js.write_text(json.dumps(card, indent=2) + "\n")
    return [pt, onnx, js]


def run(
    config: TrainConfig,
    render: Callable[[int, int], list[Frame]],
    out_dir: Path,
    log: Callable[[str], None] = print,
) -> dict:
    """Render, train, evaluate on held-out seeds, export; returns the model card."""
    import torch

    from usvfast.camera.yolo import YoloDetector

    torch.set_num_threads(config.threads)
    t0 = time.perf_counter()
    train_frames = [f for s in config.train_seeds for f in render(s, config.frames_per_seed)]
    held = [f for s in config.heldout_seeds for f in render(s, config.heldout_frames_per_seed)]
    t_render = time.perf_counter() - t0
    log(f"rendered {len(train_frames)} training + {len(held)} held-out frames in {t_render:.0f} s")
    t1 = time.perf_counter()
    net = train(config, train_frames, log)
    t_train = time.perf_counter() - t1
    det = YoloDetector(
        net, input_size=config.input_size, conf_threshold=config.conf_threshold, iou_threshold=0.5
    )
    metrics = evaluate(det, held, config.min_box_px)
    metrics.update(small_recall(det, held, config.min_box_px))
    log(f"held-out: {json.dumps(metrics)}")
    card = {
        "name": "harbour-demo",
        "about": (
            "Demo detector for the usvfast harbour simulator (rendered frames only); not a "
            "detector of real floating trash. Bring your own YOLO weights for real data."
        ),
        "layout": "v8",
        "input_size": list(config.input_size),
        "classes": list(config.classes),
        "conf_threshold": config.conf_threshold,
        "iou_threshold": 0.5,
        "parameters": int(sum(p.numel() for p in net.parameters())),  # pyright: ignore[reportAttributeAccessIssue]
        "train": {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(config).items()},
        "render_seconds": round(t_render, 1),
        "train_seconds": round(t_train, 1),
        "heldout": metrics,
        "command": "python -m usvfast.camera.train_demo --out python/usvfast/data/models",
    }
    for p in export(net, out_dir, card):
        log(f"wrote {p} ({p.stat().st_size / 1e3:.0f} kB)")
    return card


def main(argv: Sequence[str] | None = None) -> None:
    """Command line: `python -m usvfast.camera.train_demo [--out DIR] [--seed S] [--steps N]
    [--vessel-weight W] [--trash-weight W] [--small-weight W] [--tiny-px P] [--no-balance]
    [--train-seeds N] [--threads T] [--crop-size W H] [--cache DIR]`."""
    ap = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("python/usvfast/data/models"))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=TrainConfig.steps)
    ap.add_argument("--frames-per-seed", type=int, default=TrainConfig.frames_per_seed)
    ap.add_argument("--vessel-weight", type=float, default=TrainConfig.vessel_weight)
    ap.add_argument("--trash-weight", type=float, default=TrainConfig.trash_weight)
    ap.add_argument("--small-weight", type=float, default=TrainConfig.small_weight)
    ap.add_argument("--tiny-px", type=float, default=TrainConfig.tiny_px)
    ap.add_argument("--balance", action=argparse.BooleanOptionalAction, default=True)
    ap.add_argument(
        "--train-seeds", type=int, default=len(TRAIN_SEEDS), help="simulator seeds 1000, 1001, ..."
    )
    ap.add_argument("--threads", type=int, default=TrainConfig.threads)
    ap.add_argument(
        "--crop-size", type=int, nargs=2, default=TrainConfig.crop_size, help="W H input px"
    )
    ap.add_argument("--cache", type=Path, default=None, help="keep rendered frames here")
    args = ap.parse_args(argv)
    from usvfast.sim import TRUTH_KINDS

    config = TrainConfig(
        seed=args.seed,
        steps=args.steps,
        frames_per_seed=args.frames_per_seed,
        vessel_weight=args.vessel_weight,
        trash_weight=args.trash_weight,
        small_weight=args.small_weight,
        tiny_px=args.tiny_px,
        balance=args.balance,
        train_seeds=tuple(range(1000, 1000 + args.train_seeds)),
        threads=args.threads,
        crop_size=(int(args.crop_size[0]), int(args.crop_size[1])),
        classes=TRUTH_KINDS,
    )
    render = render_frames if args.cache is None else cached(render_frames, args.cache)
    run(config, render, args.out)


if __name__ == "__main__":
    main()
