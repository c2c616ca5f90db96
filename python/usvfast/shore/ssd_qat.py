"""Quantisation-aware fine-tuning (QAT) of a fine-tuned SSD for OpenVINO's int8 kernels
(Jacob et al., CVPR 2018, §3: training with simulated quantisation; NNCF's torch back-end,
`pip install usvfast[quantize]` with torch).

    python -m usvfast.shore.ssd_qat MODEL.onnx [--data ANNOTATIONS_DIR] [--steps 120]

The float model's weights are read back from its ONNX file into the torch network. NNCF then
puts int8 fake quantisation on every convolution (the "mixed" preset: symmetric weights per
output channel, asymmetric activations per tensor, the head convolutions included),
calibrated on the frames of the model's training videos (its card's `videos`; never on any
other video, so a leave-one-video-out model stays blind to its held-out video). The layers the
float fine-tune trained (:mod:`usvfast.shore.ssd_train`: from the stride-16 block on, the
extras and the heads) and the quantisers' ranges are then trained through the fake
quantisation with the same SSD loss on augmented views of the same frames, at a tenth of
the float learning rate, so that the weights settle on the int8 grid. Writes `NAME-int8.onnx`
(its FakeQuantize nodes are OpenVINO's; OpenCV DNN cannot run it) and its card `NAME-int8.json`,
where :mod:`usvfast.shore.ssd_quant` writes its post-training int8 model: the run-times take
either (`SsdRuntime(path, "openvino")`, `evaluate_det --ssd-runtime openvino-int8`).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from usvfast._extras import require
from usvfast.shore.ssd_quant import int8_path, video_frames
from usvfast.shore.ssd_train import (
    SsdTrainConfig,
    augmented_views,
    match_anchors,
    train_steps,
)

__all__ = ["QAT_CONFIG", "float_network", "quantization_aware_fine_tune"]

#: The QAT set-up: 120 steps of 8 views drawn from 480, at a tenth of the float rate.
QAT_CONFIG = SsdTrainConfig(views=480, steps=120, lr=3e-5, warmup=10, threads=2)


def float_network(model: Path | str, input_size: tuple[int, int]):
    """The torch :class:`usvfast.shore.ssd.SsdMobileNetV2` whose export is the ONNX file
    `model` (:func:`usvfast.shore.pretrained.export_onnx` at `input_size` (W, H)): its
    weights read back by name. Raises ValueError when the file is not such an export."""
    import onnx
    import torch
    from onnx import numpy_helper

    from usvfast.shore.pretrained import coco_network
    from usvfast.shore.ssd import SsdExport

    net = coco_network()
    w, h = input_size
    export = SsdExport(net.eval(), h, w)
    weights = {
        i.name: torch.from_numpy(numpy_helper.to_array(i).copy())
        for i in onnx.load(str(model)).graph.initializer
    }
    try:
        export.load_state_dict(weights)
    except RuntimeError as exc:
        raise ValueError(f"model: {model} is not an SSD export of this network: {exc}") from exc
    return net.eval()


def quantization_aware_fine_tune(
    model: Path | str,
    data: Path | str,
    config: SsdTrainConfig = QAT_CONFIG,
    out: Path | str | None = None,
    log: Callable[[str], None] = print,
) -> Path:
    """Quantisation-aware fine-tuning of the SSD `model` (.onnx with its card) on the frames
    of its card's training videos in the MarDCT folder `data` (module doc); writes `out`
    (default :func:`usvfast.shore.ssd_quant.int8_path`) and its card; returns its path.
    Raises ValueError without a card naming the videos."""
    nncf = require("nncf", "quantize", "quantisation-aware training of the SSD")
    import cv2
    import torch

    from usvfast.shore.cnn_train import load_frames
    from usvfast.shore.pretrained import export_onnx, preprocess
    from usvfast.shore.ssd import ssd_anchors

    model = Path(model)
    card_path = model.with_suffix(".json")
    if not model.is_file() or not card_path.is_file():
        raise ValueError(f"model: expected an .onnx file with its card beside it, got {model}")
    card = json.loads(card_path.read_text(encoding="utf-8"))
    videos = list(card.get("videos") or [])
    size = (int(card["input_size"][0]), int(card["input_size"][1]))
    cfg = replace(config, input_size=size)
    annotated = video_frames(data, videos)
    threads = (torch.get_num_threads(), cv2.getNumThreads())
    torch.set_num_threads(cfg.threads)
    cv2.setNumThreads(1)
    # NNCF's fake quantisers are torch.compile'd per tensor shape; every convolution has
    # another, so compiling only costs time (and a compile-worker pool) here: run eagerly.
    try:
        with torch._dynamo.config.patch(disable=True):
            torch.manual_seed(cfg.seed)
            rng = np.random.default_rng(cfg.seed)
            t0 = time.perf_counter()
            net = float_network(model, size)
            letterbox = bool(card.get("letterbox", True))
            frames = load_frames(annotated)
            blobs = [torch.from_numpy(preprocess(f.image, size, letterbox)[0]) for f in frames]
            qnet = nncf.quantize(
                net,
                nncf.Dataset(blobs),
                preset=nncf.QuantizationPreset.MIXED,
                subset_size=len(blobs),
            )
            log(
                f"calibrated on {len(blobs)} frames of {videos} in {time.perf_counter() - t0:.0f} s"
            )
            xs, boxes = augmented_views(frames, cfg, rng)
            anchors = ssd_anchors(net.feature_sizes(size[1], size[0]))
            at = torch.from_numpy(anchors)
            match = [match_anchors(anchors, b, cfg.match_iou) for b in boxes]
            frozen = {id(p) for i in range(net.tap) for p in net.blocks[i].parameters()}
            train = [p for p in qnet.parameters() if p.is_floating_point() and id(p) not in frozen]
            for p in qnet.parameters():
                p.requires_grad_(False)
            qnet.train()
            train_steps(
                lambda idx: qnet(torch.from_numpy(xs[idx])),
                train, len(xs), match, boxes, at, cfg, rng, log, t0,
            )  # fmt: skip
            seconds = time.perf_counter() - t0
            path = Path(out) if out is not None else int8_path(model)
            export_onnx(qnet.eval(), path, size)
    finally:
        torch.set_num_threads(threads[0])
        cv2.setNumThreads(threads[1])
    int8 = {
        "method": "quantisation-aware fine-tuning (usvfast.shore.ssd_qat)",
        "calibration_videos": videos,
        "frames": len(blobs),
        "nncf": nncf.__version__,
        "preset": "mixed",
        "train": {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(cfg).items()},
        "train_seconds": round(seconds, 1),
    }
    out_card = {**card, "name": path.stem, "int8": int8}
    path.with_suffix(".json").write_text(json.dumps(out_card, indent=2), encoding="utf-8")
    log(f"wrote {path} in {seconds:.0f} s")
    return path


def main(argv: Sequence[str] | None = None) -> None:
    """Command-line entry point (module doc)."""
    from usvfast.shore.evaluate import default_data

    p = argparse.ArgumentParser(
        prog="python -m usvfast.shore.ssd_qat", description=(__doc__ or "").split("\n")[0]
    )
    p.add_argument("model", type=Path, help="Fine-tuned SSD (.onnx with its card)")
    p.add_argument("--data", type=Path, default=None, help="MarDCT training/annotations")
    p.add_argument("--steps", type=int, default=QAT_CONFIG.steps, help="Training steps")
    p.add_argument("--out", type=Path, default=None, help="Output .onnx (NAME-int8.onnx)")
    a = p.parse_args(argv)
    cfg = replace(QAT_CONFIG, steps=a.steps)
    quantization_aware_fine_tune(a.model, a.data or default_data(), cfg, a.out)


if __name__ == "__main__":
    main()
