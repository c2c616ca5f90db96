"""A fused boat score: the CNN's boxes (:mod:`usvfast.shore.cnn`) rescored by the
training-free contrast cue of :mod:`usvfast.shore.contrast`.

The network proposes well-placed boxes but also fires on quays, buildings and glitter; a boat
is an object that stands out from its row's water or sky. A box's support is the share of its
pixels whose robust contrast exceeds the contrast threshold; the fused score is the geometric
mean √(CNN confidence × support). A box is kept when its fused score is at least `threshold`
and at least `relative` × the best fused score of its frame: network confidences shift from
one scene to another (a held-out video scores lower than the training ones), while the ranking
within a frame carries over better. Pixels: origin top-left, x right, y down; boxes x, y, w,
h of the input frame.
"""

from __future__ import annotations

import cv2
import numpy as np

from usvfast._validate import as_float_array, instance, real
from usvfast.shore.boxes import Detections
from usvfast.shore.contrast import ContrastConfig, _check_frame, contrast_map
from usvfast.shore.horizon import HorizonLine, detect_horizon

#: Default fused-score threshold (chosen by inner validation on the training videos; see
#: :mod:`usvfast.shore.evaluate_det`).
FUSED_THRESHOLD = 0.2
#: Default share of the frame's best fused score a box needs (inner validation, as above).
FUSED_RELATIVE = 0.8
#: The CNN's own confidence floor under the fused score (boxes below are never proposed).
FUSED_CNN_FLOOR = 0.1


def box_support(z: np.ndarray, boxes: np.ndarray, scale: float, threshold: float) -> np.ndarray:
    """Share (k,) of the pixels of each box (k, 4) x, y, w, h input px whose contrast `z`
    (h, w, at `scale` working / input px) exceeds `threshold` (0 for an empty box)."""
    z = as_float_array("z", z, 2, finite=False)
    b = as_float_array("boxes", boxes)
    if b.size % 4 or (b.ndim != 2 and b.size):
        raise ValueError(f"boxes: expected (k, 4) x, y, w, h, got shape {b.shape}")
    b = b.reshape(-1, 4)
    real("scale", scale, positive=True)
    real("threshold", threshold)
    if len(b) == 0 or z.size == 0:
        return np.zeros(0)
    h, w = z.shape
    ii = cv2.integral((z > threshold).astype(np.uint8), sdepth=cv2.CV_64F)
    x0 = np.clip(np.floor(b[:, 0] * scale), 0, w).astype(int)
    y0 = np.clip(np.floor(b[:, 1] * scale), 0, h).astype(int)
    x1 = np.clip(np.ceil((b[:, 0] + b[:, 2]) * scale), 0, w).astype(int)
    y1 = np.clip(np.ceil((b[:, 1] + b[:, 3]) * scale), 0, h).astype(int)
    inside = ii[y1, x1] - ii[y0, x1] - ii[y1, x0] + ii[y0, x0]
    area = (x1 - x0) * (y1 - y0)
    return np.where(area > 0, inside / np.maximum(area, 1), 0.0)


class FusedDetector:
    """CNN boxes rescored by the contrast cue (module doc). `cnn`: any object with
    `detect(image) -> Detections` (a :class:`usvfast.shore.cnn.CnnDetector` built with a low
    confidence floor); `config`: the contrast map's parameters; `threshold`: the fused score
    kept; `relative`: the share of the frame's best fused score kept (0: off).
    `detect(image, horizon=None)` -> :class:`Detections` whose scores are fused."""

    def __init__(
        self,
        cnn,
        config: ContrastConfig | None = None,
        threshold: float = FUSED_THRESHOLD,
        relative: float = FUSED_RELATIVE,
    ) -> None:
        if config is not None:
            instance("config", config, ContrastConfig)
        if not callable(getattr(cnn, "detect", None)):
            raise TypeError("cnn: expected an object with a detect(image) method")
        if not 0.0 <= real("threshold", threshold) <= 1.0:
            raise ValueError(f"threshold: expected a value in [0, 1], got {threshold}")
        if not 0.0 <= real("relative", relative) <= 1.0:
            raise ValueError(f"relative: expected a value in [0, 1], got {relative}")
        self.relative = float(relative)
        self.cnn = cnn
        self.config = config or ContrastConfig()
        self.threshold = float(threshold)

    def score(self, image: np.ndarray, horizon: HorizonLine | None = None) -> Detections:
        """Every CNN box with its fused score (none dropped)."""
        _check_frame(image, horizon)
        d = self.cnn.detect(image)
        if not isinstance(d, Detections):
            raise TypeError(f"cnn: detect() must return Detections, got {type(d).__name__}")
        if len(d) == 0:
            return d
        if horizon is None:
            horizon = detect_horizon(image, config=self.config.horizon)
        z, _, s = contrast_map(image, horizon, self.config)
        support = box_support(z, d.boxes, s, self.config.threshold)
        return Detections(d.boxes, np.sqrt(np.clip(d.scores, 0, 1) * support), d.keypoints)

    def detect(self, image: np.ndarray, horizon: HorizonLine | None = None) -> Detections:
        """The CNN boxes kept by the fused score (class doc)."""
        d = self.score(image, horizon)
        return d.subset(fused_keep(d.scores, self.threshold, self.relative))


def fused_keep(scores: np.ndarray, threshold: float, relative: float) -> np.ndarray:
    """Mask (k,) of one frame's fused `scores` (k,) at least `threshold` and at least
    `relative` × their maximum."""
    s = as_float_array("scores", scores, 1)
    real("threshold", threshold)
    real("relative", relative)
    if len(s) == 0:
        return np.zeros(0, dtype=bool)
    return (s >= threshold) & (s >= relative * s.max())
