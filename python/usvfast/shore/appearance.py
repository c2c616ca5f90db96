"""Appearance for re-identification: colour histograms of a box (hue–saturation, OpenCV's
calcHist) compared by the Bhattacharyya distance (OpenCV's compareHist). No re-identification
network weights are available here, so colour histograms stand in for a learned embedding."""

from __future__ import annotations

import cv2
import numpy as np

from usvfast._validate import as_float_array
from usvfast._validate import image as check_image

#: Hue and saturation bins.
BINS = (16, 8)


def box_histogram(image: np.ndarray, box: np.ndarray) -> np.ndarray | None:
    """Normalised (16 × 8) hue–saturation histogram (float32, sums to 1) of the pixels of box
    (x, y, w, h px) in a BGR frame; None when the box holds no pixel."""
    check_image("image", image)
    box = as_float_array("box", box).ravel()
    if box.shape != (4,):
        raise ValueError(f"box: expected (x, y, w, h), got shape {box.shape}")
    h, w = image.shape[:2]
    x0, y0 = max(int(box[0]), 0), max(int(box[1]), 0)
    x1, y1 = min(int(np.ceil(box[0] + box[2])), w), min(int(np.ceil(box[1] + box[3])), h)
    if x1 <= x0 or y1 <= y0:
        return None
    hsv = cv2.cvtColor(image[y0:y1, x0:x1], cv2.COLOR_BGR2HSV)
    hist = cv2.calcHist([hsv], [0, 1], None, list(BINS), [0, 180, 0, 256])
    total = float(hist.sum())
    return hist / total if total > 0 else None


def histogram_distance(a: np.ndarray | None, b: np.ndarray | None) -> float:
    """Bhattacharyya distance in [0, 1] (0: same colours); 1 when either is missing."""
    for name, h in (("a", a), ("b", b)):
        if h is not None and (not isinstance(h, np.ndarray) or h.dtype != np.float32):
            raise TypeError(
                f"{name}: expected a box_histogram (float32 array), got {type(h).__name__}"
            )
    if a is not None and b is not None and a.shape != b.shape:
        raise ValueError(f"a, b: histograms of different shapes {a.shape}, {b.shape}")
    if a is None or b is None:
        return 1.0
    return float(cv2.compareHist(a, b, cv2.HISTCMP_BHATTACHARYYA))
