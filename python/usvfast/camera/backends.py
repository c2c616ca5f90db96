"""Choose a detector backend by name, as a pipeline config does (`[detector]` table):
`"onnx"` (OpenCV DNN, no torch), `"torch"` (TorchScript / `torch.export` through torch), and
the bundled demo weights.

The bundled `harbour-demo` network was trained on frames of the harbour simulator
(`python -m usvfast.camera.train_demo`); it is a demo model for simulated recordings, not a
detector of real floating trash: bring your own YOLO weights (`weights = "..."`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from usvfast.camera.detect import GridDetector

#: Folder of the bundled detector weights.
MODELS_DIR = Path(__file__).resolve().parent.parent / "data" / "models"
#: Backend name -> weights file suffix.
SUFFIXES = {"onnx": ".onnx", "torch": ".pt"}


def resolve_weights(weights: str | Path, base: str | Path | None = None) -> Path:
    """The weights file for `weights`: an absolute path, a path relative to `base` (e.g. the
    config file's folder), or the name of a bundled file in :data:`MODELS_DIR`
    (`"harbour-demo.onnx"`). Raises FileNotFoundError listing the places looked in."""
    p = Path(weights)
    if p.is_absolute():
        tried = [p]
    else:
        tried = [Path(base) / p if base is not None else p, MODELS_DIR / p.name]
    for cand in tried:
        if cand.is_file():
            return cand
    raise FileNotFoundError(
        f"weights: no such file {str(weights)!r} (looked in {', '.join(map(str, tried))})"
    )


def demo_weights(backend: str = "onnx") -> Path:
    """Path of the bundled harbour demo network for `backend` ("onnx" or "torch")."""
    if backend not in SUFFIXES:
        raise ValueError(f"backend: expected one of {sorted(SUFFIXES)}, got {backend!r}")
    return resolve_weights(f"harbour-demo{SUFFIXES[backend]}")


def model_card(weights: str | Path) -> dict[str, Any]:
    """The JSON card beside a weights file (`name.json`: input_size, layout, class names,
    training figures), or {} when there is none."""
    card = Path(weights).with_suffix(".json")
    return json.loads(card.read_text()) if card.is_file() else {}


def load_detector(
    backend: str,
    weights: str | Path,
    *,
    base: str | Path | None = None,
    **options: Any,
) -> GridDetector:
    """A detector callable for `backend` ("onnx" -> :class:`usvfast.camera.dnn.OnnxDetector`,
    "torch" -> :class:`usvfast.camera.yolo.YoloDetector`) on `weights` (see
    :func:`resolve_weights`; `base` is the folder relative paths start from).

    `options` are the detector keywords (conf_threshold, iou_threshold, classes, agnostic,
    max_det, input_size, layout; device and half for torch). `input_size` and `layout` default
    to the weights' model card (:func:`model_card`) when it has them.
    Raises ValueError for an unknown backend, FileNotFoundError for missing weights.
    """
    if backend not in SUFFIXES:
        raise ValueError(f"backend: expected one of {sorted(SUFFIXES)}, got {backend!r}")
    path = resolve_weights(weights, base)
    card = model_card(path)
    for key in ("input_size", "layout"):
        if key in card and options.get(key) is None:
            options[key] = tuple(card[key]) if key == "input_size" else card[key]
    options = {k: v for k, v in options.items() if v is not None}
    if backend == "onnx":
        from usvfast.camera.dnn import OnnxDetector

        return OnnxDetector(path, **options)
    from usvfast.camera.yolo import YoloDetector

    return YoloDetector(path, **options)
