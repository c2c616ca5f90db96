"""The camera chain of the thesis (Code 5.5): detector -> image-space filters (confidence,
own-vessel polygon, horizon line) -> georeferencing onto the water plane with covariance.

Any detector backend plugs in: :class:`usvfast.camera.yolo.YoloDetector` (torch),
:class:`usvfast.camera.dnn.OnnxDetector` (OpenCV DNN), or any callable returning boxes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from usvfast.camera.detect import Detections, as_detections
from usvfast.camera.georef import (
    ABOVE_HORIZON,
    LOW_CONFIDENCE,
    OK,
    OWN_VESSEL,
    Camera,
    box_contact_points,
    georeference,
)


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

    `detector`: :class:`usvfast.camera.yolo.YoloDetector` (torch),
    :class:`usvfast.camera.dnn.OnnxDetector` (OpenCV DNN), or any callable taking a list of
    images and returning,
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
            det = as_detections(r)
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
