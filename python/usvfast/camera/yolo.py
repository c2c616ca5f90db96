"""YOLO detection through torch: letterbox, decoding of both output layouts, Rust NMS, and the
camera pipeline (detector -> filters -> georeferencing) that any box-returning callable plugs
into.

Layouts: YOLOv5/v7 `[N, A, 5 + nc]` (cx, cy, w, h, objectness, class scores) and YOLOv8+
`[N, 4 + nc, A]` (cx, cy, w, h, class scores), boxes in letterboxed input pixels. torch is an
optional dependency (`pip install usvfast[yolo]`); it is imported only when a torch model is used.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from usvfast._validate import as_float_array
from usvfast.camera.georef import (
    LOW_CONFIDENCE,
    OK,
    OWN_VESSEL,
    Camera,
    box_contact_points,
    georeference,
)
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
    r = min(tw / w, th / h)
    nw, nh = max(1, round(w * r)), max(1, round(h * r))
    left, top = (tw - nw) // 2, (th - nh) // 2
    out = np.full((th, tw, *image.shape[2:]), color, dtype=image.dtype)
    resized = cv2.resize(image, (nw, nh), interpolation=cv2.INTER_LINEAR)
    out[top : top + nh, left : left + nw] = resized
    return out, Letterbox((nw / w, nh / h), (left, top), (w, h))


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


class YoloDetector:
    """A YOLO model as a callable: list of images (H, W, 3 uint8, BGR as OpenCV reads them) ->
    list of :class:`Detections` in original pixels.

    `model`: a TorchScript file path (or a `torch.export` `.pt2` file), a `torch.nn.Module`,
    or an Ultralytics `YOLO` object (its own pre/post-processing is used, with our thresholds).
    `input_size` (width, height) of
    the network; `layout` "auto" | "v5" | "v8"; `conf_threshold`, `iou_threshold`, `classes`
    (keep only these ids), `agnostic` (class-agnostic NMS), `max_det` per image; `device`
    "cpu", "cuda", "cuda:0", ...; `half` runs the network in float16 (CUDA only).
    """

    def __init__(
        self,
        model: Any,
        *,
        input_size: tuple[int, int] = (640, 640),
        layout: str = "auto",
        conf_threshold: float = 0.25,
        iou_threshold: float = 0.45,
        classes: Sequence[int] | None = None,
        agnostic: bool = False,
        max_det: int = 300,
        device: str = "cpu",
        half: bool = False,
        bgr: bool = True,
    ) -> None:
        import torch

        self._torch = torch
        self.device = torch.device(device)
        self.input_size = (int(input_size[0]), int(input_size[1]))
        self.layout = layout
        self.conf_threshold = float(conf_threshold)
        self.iou_threshold = float(iou_threshold)
        self.classes = None if classes is None else list(classes)
        self.agnostic = agnostic
        self.max_det = int(max_det)
        self.half = half
        self.bgr = bgr
        self._ultralytics = type(model).__module__.startswith("ultralytics")
        if isinstance(model, str | Path):
            if str(model).endswith(".pt2"):
                model = torch.export.load(str(model)).module()
            else:
                # TorchScript is deprecated upstream (FutureWarning) but is what most exported
                # YOLO weights are; load it quietly.
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", FutureWarning)
                    model = torch.jit.load(str(model), map_location=self.device)
        elif not self._ultralytics and not isinstance(model, torch.nn.Module):
            raise TypeError(
                "model: expected a TorchScript path, a torch.nn.Module or an Ultralytics model, "
                f"got {type(model).__name__}"
            )
        if not self._ultralytics and isinstance(model, torch.nn.Module):
            model = model.to(self.device)
            if hasattr(model, "eval"):
                model = model.eval()
            if half:
                model = model.half()
        self.model = model

    def _ultralytics_call(self, images: list[np.ndarray]) -> list[Detections]:
        results = self.model(
            images if self.bgr else [im[..., ::-1] for im in images],
            imgsz=max(self.input_size),
            conf=self.conf_threshold,
            iou=self.iou_threshold,
            classes=self.classes,
            agnostic_nms=self.agnostic,
            max_det=self.max_det,
            device=str(self.device),
            verbose=False,
        )
        out = []
        for r in results:
            b = r.boxes
            out.append(
                Detections(
                    b.xyxy.cpu().numpy().astype(np.float64),
                    b.conf.cpu().numpy().astype(np.float64),
                    b.cls.cpu().numpy().astype(np.int64),
                )
            )
        return out

    def raw(self, images: Sequence[np.ndarray]) -> tuple[np.ndarray, list[Letterbox]]:
        """Letterbox, run the network once on the batch; returns (raw output, letterboxes)."""
        torch = self._torch
        boxed, infos = [], []
        for im in images:
            if im.ndim != 3 or im.shape[2] != 3:
                raise ValueError(f"images: expected (H, W, 3) arrays, got shape {im.shape}")
            lb, info = letterbox(im, self.input_size)
            boxed.append(lb[..., ::-1] if self.bgr else lb)
            infos.append(info)
        batch = np.ascontiguousarray(np.stack(boxed).transpose(0, 3, 1, 2))
        x = torch.from_numpy(batch).to(self.device)
        x = (x.half() if self.half else x.float()) / 255.0
        with torch.inference_mode():
            y = self.model(x)
        if isinstance(y, list | tuple):
            y = y[0]
        return y.float().cpu().numpy(), infos

    def __call__(self, images: np.ndarray | Sequence[np.ndarray]) -> list[Detections]:
        if isinstance(images, np.ndarray) and images.ndim == 3:
            images = [images]
        images = list(images)
        if not images:
            return []
        if self._ultralytics:
            return self._ultralytics_call(images)
        raw, infos = self.raw(images)
        out = []
        decoded = decode(raw, self.layout, self.conf_threshold, self.classes)
        for (boxes, scores, cls), info in zip(decoded, infos, strict=True):
            keep = nms(boxes, scores, self.iou_threshold, None if self.agnostic else cls)
            keep = keep[: self.max_det]
            out.append(Detections(info.to_original(boxes[keep]), scores[keep], cls[keep]))
        return out


def _as_detections(result: Any) -> Detections:
    """Accept Detections or a (boxes, scores[, classes]) tuple from any detector callable."""
    if isinstance(result, Detections):
        return result
    boxes, scores, *rest = result
    b = as_float_array("boxes", boxes).reshape(-1, 4)
    s = as_float_array("scores", scores).reshape(-1)
    c = np.asarray(rest[0], dtype=np.int64).reshape(-1) if rest else np.zeros(len(b), np.int64)
    return Detections(b, s, c)


@dataclass(frozen=True)
class CameraDetections:
    """One frame through the pipeline: every detector box with its contact pixel (k, 2),
    water position (k, 2), covariance (k, 2, 2) and `reason` (k,) code into
    :data:`usvfast.camera.REASONS` (0 = ok; filtered boxes keep their reason and NaN positions)."""

    detections: Detections
    pixels: np.ndarray
    positions: np.ndarray
    covariances: np.ndarray
    reason: np.ndarray
    frame: str

    @property
    def valid(self) -> np.ndarray:
        """(k,) bool: boxes that passed every filter and were georeferenced."""
        return self.reason == OK


@dataclass
class CameraPipeline:
    """detector -> filters (confidence, own-vessel polygon, horizon line) -> georeferencing
    (horizon from attitude, max range) for each frame.

    `detector`: :class:`YoloDetector` or any callable taking a list of images and returning,
    per image, :class:`Detections` or `(boxes (k, 4) xyxy, scores (k,)[, classes (k,)])`.
    `own_vessel_polygon` (m, 2) pixels: boxes whose contact point lies inside are dropped.
    `horizon_line` (a, b): contact points with v <= a·u + b are above the horizon (a given
    image line, or :func:`usvfast.camera.horizon_line` from the attitude).
    Other keywords are those of :func:`usvfast.camera.georeference`.
    """

    detector: Callable[[list[np.ndarray]], Sequence[Any]]
    camera: Camera
    height: float
    min_confidence: float = 0.0
    own_vessel_polygon: np.ndarray | None = None
    horizon_line: tuple[float, float] | None = None
    georef_options: dict[str, Any] | None = None

    def filter(self, det: Detections) -> np.ndarray:
        """(k,) reason codes of the image-space filters for one frame's detections."""
        from usvfast.camera.georef import ABOVE_HORIZON

        px = box_contact_points(det.boxes) if len(det.boxes) else np.zeros((0, 2))
        reason = np.zeros(len(px), dtype=np.int64)
        reason[det.scores < self.min_confidence] = LOW_CONFIDENCE
        if self.own_vessel_polygon is not None and len(px):
            poly = np.asarray(self.own_vessel_polygon, dtype=np.float32).reshape(-1, 1, 2)
            inside = np.array(
                [cv2.pointPolygonTest(poly, (float(u), float(v)), False) >= 0 for u, v in px],
                dtype=bool,
            )
            reason[(reason == OK) & inside] = OWN_VESSEL
        if self.horizon_line is not None and len(px):
            a, b = self.horizon_line
            reason[(reason == OK) & (px[:, 1] <= a * px[:, 0] + b)] = ABOVE_HORIZON
        return reason

    def __call__(self, images: Sequence[np.ndarray], **pose: Any) -> list[CameraDetections]:
        """Run on a batch of frames; `pose` keywords (roll, pitch, heading, vessel_ne) apply to
        every frame of the batch."""
        results = self.detector(list(images))
        out = []
        opts = dict(self.georef_options or {})
        opts.update(pose)
        for r in results:
            det = _as_detections(r)
            px = box_contact_points(det.boxes) if len(det.boxes) else np.zeros((0, 2))
            reason = self.filter(det)
            positions = np.full((len(px), 2), np.nan)
            covs = np.full((len(px), 2, 2), np.nan)
            frame = "ned" if opts.get("heading") is not None else "level"
            ok = reason == OK
            if ok.any():
                g = georeference(px[ok], self.camera, height=self.height, **opts)
                positions[ok], covs[ok] = g.positions, g.covariances
                reason[ok] = g.reason
                frame = g.frame
            out.append(CameraDetections(det, px, positions, covs, reason, frame))
        return out
