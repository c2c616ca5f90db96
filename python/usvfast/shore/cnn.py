"""The CNN boat detector of the shore chain: a YOLO-layout network (our HarbourNet trained by
:mod:`usvfast.shore.cnn_train`, or the user's own YOLO weights) run through OpenCV DNN (ONNX,
no torch) or torch, with the letterbox, decoding and Rust NMS of :mod:`usvfast.camera.detect`;
boxes converted to the shore chain's x, y, w, h pixels.

Which weights `usvfast shore` uses by default (:func:`default_model`): the file named by
$USVFAST_SHORE_MODEL, else `shore-cnn.onnx` in the user's model folder
(:func:`user_model_dir`, where `usvfast shore-train --detector cnn` writes the model trained
on MarDCT), else None (the chain falls back to the Bayes detector). No MarDCT-trained weights
are shipped in the package: MarDCT is GPL v3 and usvfast is MIT; weights fitted to those
frames are kept out of the MIT package and produced locally in minutes instead.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from usvfast.camera.backends import load_detector
from usvfast.shore.boxes import Detections

#: The default model's file stem (see :func:`default_model`).
MODEL_FILE = "shore-cnn.onnx"


def user_model_dir() -> Path:
    """Folder of locally trained models: $USVFAST_MODELS, else $XDG_DATA_HOME/usvfast/models,
    else ~/.local/share/usvfast/models."""
    env = os.environ.get("USVFAST_MODELS")
    if env:
        return Path(env)
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "usvfast" / "models"


def user_model(env: str, name: str) -> Path | None:
    """A model file: the path in environment variable `env` (must exist: ValueError
    otherwise), else `name` in :func:`user_model_dir` when it is there, else None."""
    value = os.environ.get(env)
    if value:
        p = Path(value)
        if not p.is_file():
            raise ValueError(f"{env}: no such model file {p}")
        return p
    p = user_model_dir() / name
    return p if p.is_file() else None


def default_model() -> Path | None:
    """The CNN weights `usvfast shore` uses when none are given: $USVFAST_SHORE_MODEL (must
    exist: ValueError otherwise), else `shore-cnn.onnx` in :func:`user_model_dir`, else None."""
    return user_model("USVFAST_SHORE_MODEL", MODEL_FILE)


class CnnDetector:
    """Boats of a BGR frame from a YOLO-layout network.

    `weights`: an `.onnx` file (OpenCV DNN) or TorchScript `.pt` file (torch), or an
    in-memory `torch.nn.Module` (torch backend; `input_size` then required). `backend`
    "onnx" | "torch" (default: from the file suffix). `conf_threshold`, `iou_threshold`
    (NMS), `input_size` (width, height) and `classes` (keep only these class ids; a user's
    COCO model: `classes=[8]` for "boat") default to the model card beside the file.
    `detect(image)` -> :class:`usvfast.shore.boxes.Detections` (x, y, w, h px, scores).
    """

    def __init__(
        self,
        weights,
        *,
        backend: str | None = None,
        conf_threshold: float | None = None,
        iou_threshold: float | None = None,
        input_size: tuple[int, int] | None = None,
        classes: Sequence[int] | None = None,
    ) -> None:
        if isinstance(weights, str | Path):
            path = Path(weights)
            if not path.is_file():
                raise ValueError(f"weights: no such model file {path}")
            backend = backend or ("torch" if path.suffix in (".pt", ".pt2") else "onnx")
            from usvfast.camera.backends import model_card

            card = model_card(path)
            if conf_threshold is None:
                conf_threshold = card.get("conf_threshold", 0.5)
            if iou_threshold is None:
                iou_threshold = card.get("iou_threshold", 0.45)
            self.grid = load_detector(
                backend,
                path.resolve(),
                conf_threshold=conf_threshold,
                iou_threshold=iou_threshold,
                input_size=input_size,
                classes=classes,
                agnostic=True,
            )
        else:
            from usvfast.camera.yolo import YoloDetector

            if input_size is None:
                input_size = getattr(weights, "input_size", None)
            if input_size is None:
                raise ValueError("input_size: needed for an in-memory network")
            self.grid = YoloDetector(
                weights,
                input_size=input_size,
                conf_threshold=0.5 if conf_threshold is None else conf_threshold,
                iou_threshold=0.45 if iou_threshold is None else iou_threshold,
                classes=classes,
                agnostic=True,
            )

    def detect(self, image: np.ndarray) -> Detections:
        """Boats of one BGR uint8 frame (h, w, 3): x, y, w, h px, scores, keypoints −1."""
        (d,) = self.grid([image])
        b = d.boxes.reshape(-1, 4)
        boxes = np.concatenate([b[:, :2], b[:, 2:] - b[:, :2]], axis=1)
        return Detections(boxes, d.scores.astype(float), np.full(len(b), -1, dtype=np.int64))
