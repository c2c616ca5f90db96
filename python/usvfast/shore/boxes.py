"""Boxes in image pixels: (x, y, w, h) with (x, y) the top-left corner, origin at the image's
top-left, x right, y down (MOTChallenge's convention)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usvfast._validate import as_float_array, finite_result


@dataclass
class Detections:
    """Boxes of one frame: `boxes` (k, 4) x, y, w, h in pixels; `scores` (k,) confidences in
    [0, 1]; `keypoints` (k,) how many keypoints each box holds (−1 when not counted)."""

    boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    scores: np.ndarray = field(default_factory=lambda: np.zeros(0))
    keypoints: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __len__(self) -> int:
        return len(self.boxes)

    def subset(self, keep: np.ndarray) -> Detections:
        """The detections where the boolean mask `keep` (k,) is True."""
        return Detections(self.boxes[keep], self.scores[keep], self.keypoints[keep])


def intersection_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection area (px²) of every box of `a` (n, 4) with every box of `b` (m, 4), both
    x, y, w, h pixels -> (n, m). Raises ValueError (naming them) for non-finite boxes or
    areas beyond float64."""
    a = as_float_array("a", a).reshape(-1, 4)
    b = as_float_array("b", b).reshape(-1, 4)
    with np.errstate(over="ignore", invalid="ignore"):
        ax2, ay2 = a[:, 0] + a[:, 2], a[:, 1] + a[:, 3]
        bx2, by2 = b[:, 0] + b[:, 2], b[:, 1] + b[:, 3]
        iw = np.minimum(ax2[:, None], bx2[None]) - np.maximum(a[:, None, 0], b[None, :, 0])
        ih = np.minimum(ay2[:, None], by2[None]) - np.maximum(a[:, None, 1], b[None, :, 1])
        area = np.clip(iw, 0, None) * np.clip(ih, 0, None)
    return finite_result("the intersection area", area, "a, b")


def iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over union of every box of `a` (n, 4) with every box of `b` (m, 4),
    both x, y, w, h pixels -> (n, m) in [0, 1] (0 for empty boxes)."""
    a = np.asarray(a, dtype=float).reshape(-1, 4)
    b = np.asarray(b, dtype=float).reshape(-1, 4)
    inter = intersection_matrix(a, b)
    union = (a[:, 2] * a[:, 3])[:, None] + (b[:, 2] * b[:, 3])[None] - inter
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(union > 0, inter / union, 0.0)
    return out


def clip_boxes(boxes: np.ndarray, width: int, height: int) -> np.ndarray:
    """Boxes (k, 4) clipped to a width × height image (pixels)."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4).copy()
    x2 = np.clip(b[:, 0] + b[:, 2], 0, width)
    y2 = np.clip(b[:, 1] + b[:, 3], 0, height)
    b[:, 0] = np.clip(b[:, 0], 0, width)
    b[:, 1] = np.clip(b[:, 1], 0, height)
    b[:, 2] = x2 - b[:, 0]
    b[:, 3] = y2 - b[:, 1]
    return b
