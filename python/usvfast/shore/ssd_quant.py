"""Post-training static int8 quantisation of an exported SSD (:func:`usvfast.shore.pretrained.
export_onnx`) with NNCF (Apache 2.0; `pip install usvfast[quantize]`), for OpenVINO's int8
kernels (AVX512-VNNI / AMX where the CPU has them; :mod:`usvfast.shore.ssd_runtime`).

    python -m usvfast.shore.ssd_quant MODEL.onnx [--data ANNOTATIONS_DIR] [--out OUT.onnx]

Calibration (Jacob et al., CVPR 2018, §3: per-tensor activation ranges from representative
inputs; NNCF's "mixed" preset: symmetric int8 weights per output channel, asymmetric
activations, then bias correction layer by layer (Nagel et al., ICCV 2019, §4.2); the 12 box
and class head convolutions stay float: of the recipes tried, the one that lost least
held-out TPR — README) runs on the frames of the videos the model was trained on,
as its card lists them (`videos`), letterboxed as at inference; never on any other video, so
a leave-one-video-out model stays blind to its held-out video. Writes `NAME-int8.onnx`
(quantize/dequantize pairs; OpenVINO runs it, OpenCV DNN 5.1 does not) beside the model and
its card `NAME-int8.json` (the model's card plus `int8`: calibration videos, frame count,
NNCF version, recipe).

NNCF sends anonymous usage telemetry (openvino-telemetry) unless the user has opted out
(`opt_in_out --opt_out`, which writes ~/intel/openvino_telemetry); it never does under pytest
or with CI=true."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import numpy as np

from usvfast._extras import require
from usvfast.shore.mardct import AnnotatedFrame, load_mardct
from usvfast.shore.pretrained import preprocess

#: Suffix of the int8 model's name (`NAME-int8.onnx`).
INT8_SUFFIX = "-int8"


def int8_path(model: Path | str) -> Path:
    """Where :func:`quantize_int8` writes the int8 model of `model` (`NAME-int8.onnx`)."""
    model = Path(model)
    return model.with_name(model.stem + INT8_SUFFIX + ".onnx")


def video_frames(data: Path | str, videos: Sequence[str]) -> list[AnnotatedFrame]:
    """The annotated frames of `videos` (at least one) in the MarDCT folder `data`, video by
    video. Raises ValueError when a video is not there."""
    found = load_mardct(data)
    missing = sorted(set(videos) - set(found))
    if missing or not videos:
        raise ValueError(f"videos: {missing or 'none'} not in {data} (has {sorted(found)})")
    return [f for v in videos for f in found[v]]


def calibration_images(data: Path | str, videos: Sequence[str]) -> list[np.ndarray]:
    """Every annotated frame (BGR uint8) of `videos` in the MarDCT folder `data`. Raises
    ValueError when a video is not there or a frame cannot be read."""
    out = []
    for f in video_frames(data, videos):
        image = cv2.imread(str(f.path), cv2.IMREAD_COLOR)
        if image is None:
            raise ValueError(f"data: cannot read {f.path}")
        out.append(image)
    return out


def quantize_int8(
    model: Path | str,
    images: Sequence[np.ndarray],
    out: Path | str | None = None,
    card_extra: dict | None = None,
) -> Path:
    """Quantise the SSD at `model` (.onnx, with its card) to int8, calibrated on `images`
    (BGR uint8 frames, each letterboxed to the card's input size); write `out` (default
    :func:`int8_path`) and its card. Raises ValueError without images or card."""
    nncf = require("nncf", "quantize", "int8 quantisation of the SSD")
    import onnx

    model = Path(model)
    card_path = model.with_suffix(".json")
    if not model.is_file() or not card_path.is_file():
        raise ValueError(f"model: expected an .onnx file with its card beside it, got {model}")
    if not images:
        raise ValueError("images: at least one calibration frame is needed")
    card = json.loads(card_path.read_text(encoding="utf-8"))
    size = tuple(int(v) for v in card["input_size"])
    letterbox = bool(card.get("letterbox", False))
    blobs = [preprocess(im, size, letterbox)[0] for im in images]  # pyright: ignore[reportArgumentType]
    dataset = nncf.Dataset(blobs, lambda x: {"images": x})
    network = onnx.load(str(model))
    heads = [n.name for n in network.graph.node if n.op_type == "Conv" and "_heads." in n.name]
    quantized = nncf.quantize(
        network,
        dataset,
        preset=nncf.QuantizationPreset.MIXED,
        subset_size=len(blobs),
        ignored_scope=nncf.IgnoredScope(names=heads),
        fast_bias_correction=False,
    )
    out = Path(out) if out is not None else int8_path(model)
    onnx.save(quantized, str(out))
    int8 = {
        "frames": len(blobs),
        "nncf": nncf.__version__,
        "preset": "mixed",
        "bias_correction": "full",
        "float_layers": heads,
        **(card_extra or {}),
    }
    card = {**card, "name": out.stem, "int8": int8}
    out.with_suffix(".json").write_text(json.dumps(card, indent=2), encoding="utf-8")
    return out


def quantize_on_training_videos(
    model: Path | str, data: Path | str, out: Path | str | None = None
) -> Path:
    """:func:`quantize_int8` calibrated on every frame of the videos the model's card lists
    as its training videos (`videos`) in the MarDCT folder `data`."""
    model = Path(model)
    card_path = model.with_suffix(".json")
    if not card_path.is_file():
        raise ValueError(f"model: no card {card_path} naming the training videos")
    videos = list(json.loads(card_path.read_text(encoding="utf-8")).get("videos") or [])
    images = calibration_images(data, videos)
    return quantize_int8(model, images, out, {"calibration_videos": videos})


def int8_model(model: Path | str, data: Path | str, log: Callable = print) -> Path:
    """The int8 model of `model` (:func:`int8_path`), quantised on its training videos when
    absent or older than the model."""
    model = Path(model)
    path = int8_path(model)
    if not path.is_file() or path.stat().st_mtime < model.stat().st_mtime:
        log(f"int8: quantising {model.name} on its training videos")
        quantize_on_training_videos(model, data, path)
    return path


def main(argv: Sequence[str] | None = None) -> None:
    """Command-line entry point (module doc)."""
    from usvfast.shore.evaluate import default_data

    p = argparse.ArgumentParser(
        prog="python -m usvfast.shore.ssd_quant", description=(__doc__ or "").split("\n")[0]
    )
    p.add_argument("model", type=Path, help="The SSD .onnx (its card beside it)")
    p.add_argument("--data", type=Path, default=None, help="MarDCT training/annotations folder")
    p.add_argument("--out", type=Path, default=None, help="Where to write (default NAME-int8)")
    a = p.parse_args(argv)
    path = quantize_on_training_videos(a.model, a.data or default_data(), a.out)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
