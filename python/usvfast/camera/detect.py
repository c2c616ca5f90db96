"""What every grid detector backend shares: letterbox, decoding of the YOLO output layouts, the
Rust NMS and the mapping back to original pixels.

Layouts: YOLOv5/v7 `[N, A, 5 + nc]` (cx, cy, w, h, objectness, class scores) and YOLOv8+
`[N, 4 + nc, A]` (cx, cy, w, h, class scores), boxes in letterboxed input pixels.
:class:`GridDetector` is the common front and back end; a backend only runs the network
(:class:`usvfast.camera.yolo.YoloDetector` through torch, :class:`usvfast.camera.dnn.OnnxDetector`
through OpenCV's DNN module), so both give the same boxes for the same network.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from usvfast._validate import as_float_array
from usvfast.camera.nms import nms


@dataclass(frozen=True)
class Letterbox:
    """How an image was letterboxed: `scale` (sx, sy) resized/original, `pad` (left, top) px,
    `original_size` (width, height). `to_original` inverts the mapping exactly."""

    scale: tuple[float, float]
    pad: tuple[int, int]
    original_size: tuple[int, int]

    def to_original(self, boxes: np.ndarray) -> np.ndarray:
        """Boxes (k, 4) xyxy in letterboxed pixels -> original pixels, clipped to the image."""
        b = np.array(boxes, dtype=np.float64, copy=True).reshape(-1, 4)
        b[:, [0, 2]] = (b[:, [0, 2]] - self.pad[0]) / self.scale[0]
        b[:, [1, 3]] = (b[:, [1, 3]] - self.pad[1]) / self.scale[1]
        w, h = self.original_size
        b[:, [0, 2]] = b[:, [0, 2]].clip(0, w)
        b[:, [1, 3]] = b[:, [1, 3]].clip(0, h)
        return b

    def to_letterbox(self, boxes: np.ndarray) -> np.ndarray:
        """Boxes (k, 4) xyxy in original pixels -> letterboxed pixels."""
        b = np.array(boxes, dtype=np.float64, copy=True).reshape(-1, 4)
        b[:, [0, 2]] = b[:, [0, 2]] * self.scale[0] + self.pad[0]
        b[:, [1, 3]] = b[:, [1, 3]] * self.scale[1] + self.pad[1]
        return b


def letterbox_geometry(
    image_size: tuple[int, int], size: tuple[int, int] = (640, 640)
) -> tuple[tuple[int, int], Letterbox]:
    """Where :func:`letterbox` puts an image of `image_size` (width, height) in `size`:
    ((resized width, height), the :class:`Letterbox`)."""
    w, h = image_size
    tw, th = size
    r = min(tw / w, th / h)
    nw, nh = max(1, round(w * r)), max(1, round(h * r))
    left, top = (tw - nw) // 2, (th - nh) // 2
    return (nw, nh), Letterbox((nw / w, nh / h), (left, top), (w, h))


def letterbox(
    image: np.ndarray, size: tuple[int, int] = (640, 640), color: int = 114
) -> tuple[np.ndarray, Letterbox]:
    """Resize keeping the aspect ratio and pad to `size` = (width, height) with `color`.

    Returns the new image and the :class:`Letterbox` needed to map boxes back. The per-axis
    scale is the exact ratio of the integer resized size to the original, so the inverse
    mapping has no systematic error (the thesis's resize-and-rescale had ±2 px).
    """
    h, w = image.shape[:2]
    tw, th = size
    (nw, nh), info = letterbox_geometry((w, h), size)
    left, top = info.pad
    out = np.full((th, tw, *image.shape[2:]), color, dtype=image.dtype)
    out[top : top + nh, left : left + nw] = _resized(image, nw, nh)
    return out, info


def _resized(image: np.ndarray, nw: int, nh: int) -> np.ndarray:
    """`image` resized to (nw, nh) (bilinear); the image itself when it has that size (a
    bilinear resize to the same size is the identity)."""
    if image.shape[1] == nw and image.shape[0] == nh:
        return image
    return cv2.resize(image, (nw, nh), interpolation=cv2.INTER_LINEAR)


@dataclass(frozen=True)
class Detections:
    """Boxes of one frame: `boxes` (k, 4) xyxy original pixels, `scores` (k,), `classes` (k,)
    int64, sorted by descending score."""

    boxes: np.ndarray
    scores: np.ndarray
    classes: np.ndarray

    @staticmethod
    def empty() -> Detections:
        """No detections: boxes (0, 4), scores (0,), class ids (0,) int64."""
        return Detections(np.zeros((0, 4)), np.zeros(0), np.zeros(0, dtype=np.int64))


def decode(
    output: np.ndarray,
    layout: str = "auto",
    conf_threshold: float = 0.25,
    classes: Sequence[int] | None = None,
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Decode a raw YOLO output batch into per-image (boxes xyxy, scores, classes) before NMS.

    `output` is `[N, A, 5 + nc]` (`layout="v5"`, YOLOv5/v7, score = objectness x class score)
    or `[N, 4 + nc, A]` (`layout="v8"`, YOLOv8 and later); `"auto"` takes the smaller of the two
    last axes as the channel axis. Candidates below `conf_threshold` or whose class is not in
    `classes` are dropped.
    """
    out = np.asarray(output, dtype=np.float64)
    if out.ndim != 3:
        raise ValueError(f"output: expected a 3-D [N, A, C] or [N, C, A] array, got {out.shape}")
    if layout == "auto":
        layout = "v8" if out.shape[1] < out.shape[2] else "v5"
    if layout == "v8":
        out = out.transpose(0, 2, 1)
        if out.shape[2] < 5:
            raise ValueError(f"output: v8 layout needs 4 + nc >= 5 channels, got {out.shape[2]}")
        cls_scores = out[:, :, 4:]
    elif layout == "v5":
        if out.shape[2] < 6:
            raise ValueError(f"output: v5 layout needs 5 + nc >= 6 channels, got {out.shape[2]}")
        cls_scores = out[:, :, 5:] * out[:, :, 4:5]
    else:
        raise ValueError(f"layout: expected 'auto', 'v5' or 'v8', got {layout!r}")
    result = []
    for i in range(out.shape[0]):
        cls = np.argmax(cls_scores[i], axis=1)
        score = np.take_along_axis(cls_scores[i], cls[:, None], axis=1)[:, 0]
        keep = score >= conf_threshold
        if classes is not None:
            keep &= np.isin(cls, np.asarray(classes))
        c = out[i, keep, :4]
        boxes = np.stack(
            [
                c[:, 0] - c[:, 2] / 2,
                c[:, 1] - c[:, 3] / 2,
                c[:, 0] + c[:, 2] / 2,
                c[:, 1] + c[:, 3] / 2,
            ],
            axis=1,
        )
        result.append((boxes, score[keep], cls[keep].astype(np.int64)))
    return result


def as_detections(result: Any) -> Detections:
    """Accept Detections or a (boxes, scores[, classes]) tuple from any detector callable."""
    if isinstance(result, Detections):
        return result
    boxes, scores, *rest = result
    b = as_float_array("boxes", boxes).reshape(-1, 4)
    s = as_float_array("scores", scores).reshape(-1)
    c = np.asarray(rest[0], dtype=np.int64).reshape(-1) if rest else np.zeros(len(b), np.int64)
    return Detections(b, s, c)


def _check_size(name: str, size: Any) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in size)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: expected (width, height) integers, got {size!r}") from None
    if w <= 0 or h <= 0:
        raise ValueError(f"{name}: expected positive (width, height), got {size!r}")
    return w, h


class GridDetector:
    """Front and back end shared by the backends: a list of images (H, W, 3 uint8, BGR as
    OpenCV reads them) -> letterbox to `input_size` (width, height) px -> RGB float32 NCHW in
    [0, 1] -> :meth:`forward` (the backend) -> :func:`decode` (`layout`, `conf_threshold`,
    `classes`) -> Rust NMS (`iou_threshold`, per class unless `agnostic`, at most `max_det`)
    -> :class:`Detections` in original pixels, one per image.

    `bgr=False` when the images are already RGB. Subclasses implement :meth:`forward`.
    """

    def __init__(
        self,
        *,
        input_size: tuple[int, int] = (640, 640),
        layout: str = "auto",
        conf_threshold: float = 0.25,
        iou_threshold: float = 0.45,
        classes: Sequence[int] | None = None,
        agnostic: bool = False,
        max_det: int = 300,
        bgr: bool = True,
    ) -> None:
        if layout not in ("auto", "v5", "v8"):
            raise ValueError(f"layout: expected 'auto', 'v5' or 'v8', got {layout!r}")
        self.input_size = _check_size("input_size", input_size)
        self.layout = layout
        self.conf_threshold = float(conf_threshold)
        self.iou_threshold = float(iou_threshold)
        for name in ("conf_threshold", "iou_threshold"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"{name}: expected a value in [0, 1], got {v}")
        self.classes = None if classes is None else [int(c) for c in classes]
        self.agnostic = bool(agnostic)
        self.max_det = int(max_det)
        self.bgr = bool(bgr)

    def preprocess(self, images: Sequence[np.ndarray]) -> tuple[np.ndarray, list[Letterbox]]:
        """Images -> (batch (N, 3, h, w) float32 RGB in [0, 1], letterboxes): the
        :func:`letterbox` of each image (grey 114 padding), channels reversed when `bgr`,
        divided by 255 in float32 — written in one pass into the batch."""
        w, h = self.input_size
        batch = np.empty((len(images), 3, h, w), np.float32)
        infos = []
        pad = np.float32(114.0) / np.float32(255.0)
        for i, im in enumerate(images):
            im = np.asarray(im)
            if im.ndim != 3 or im.shape[2] != 3:
                raise ValueError(f"images: expected (H, W, 3) arrays, got shape {im.shape}")
            if im.dtype != np.uint8:
                raise TypeError(f"images: expected uint8 pixels, got {im.dtype}")
            (nw, nh), info = letterbox_geometry((im.shape[1], im.shape[0]), self.input_size)
            left, top = info.pad
            out = batch[i]
            out[:, :top] = pad
            out[:, top + nh :] = pad
            out[:, top : top + nh, :left] = pad
            out[:, top : top + nh, left + nw :] = pad
            src = _resized(im, nw, nh)
            chw = (src[..., ::-1] if self.bgr else src).transpose(2, 0, 1)
            np.divide(chw, np.float32(255.0), out=out[:, top : top + nh, left : left + nw])
            infos.append(info)
        return batch, infos

    def forward(self, batch: np.ndarray) -> np.ndarray:
        """Run the network on a preprocessed batch; the raw output as a float32 numpy array."""
        raise NotImplementedError

    def raw(self, images: Sequence[np.ndarray]) -> tuple[np.ndarray, list[Letterbox]]:
        """Letterbox, run the network once on the batch; returns (raw output, letterboxes)."""
        batch, infos = self.preprocess(images)
        return self.forward(batch), infos

    def postprocess(self, raw: np.ndarray, infos: Sequence[Letterbox]) -> list[Detections]:
        """Raw network output of a batch -> per-image :class:`Detections` (original pixels)."""
        out = []
        decoded = decode(raw, self.layout, self.conf_threshold, self.classes)
        if len(decoded) != len(infos):
            raise ValueError(
                f"output: the network returned {len(decoded)} images for a batch of {len(infos)}"
            )
        for (boxes, scores, cls), info in zip(decoded, infos, strict=True):
            keep = nms(boxes, scores, self.iou_threshold, None if self.agnostic else cls)
            keep = keep[: self.max_det]
            out.append(Detections(info.to_original(boxes[keep]), scores[keep], cls[keep]))
        return out

    def __call__(self, images: np.ndarray | Sequence[np.ndarray]) -> list[Detections]:
        """Detect on one image (H, W, 3) or a list of images; one :class:`Detections` each."""
        if isinstance(images, np.ndarray) and images.ndim == 3:
            images = [images]
        images = list(images)
        if not images:
            return []
        return self.postprocess(*self.raw(images))
