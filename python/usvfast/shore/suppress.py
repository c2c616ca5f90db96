"""Non-maximum suppression across overlapping and nested boxes: a detector's boxes (or the
pooled boxes of several detectors) kept best score first, a box dropped when it overlaps a
kept one by IoU > `nms` or lies mostly inside it (or it inside the box): intersection over
the smaller box's area > `contain`.

Plain IoU suppression leaves the part-boxes a CNN draws on a long ship (bow, stern,
superstructure): each has a small IoU with the whole-ship box but lies inside it. With
`contain` > 1 the rule is plain greedy NMS (equal to OpenCV's `cv2.dnn.NMSBoxes` at the same
IoU threshold). Boxes x, y, w, h pixels.
"""

from __future__ import annotations

import numpy as np

from usvfast._validate import as_float_array, instance, real
from usvfast.shore.boxes import Detections, intersection_matrix, iou_matrix

#: Shipped suppression: IoU above which, and share of the smaller box inside the other above
#: which, the lower-scored box is dropped (the four leave-one-video-out folds of
#: :mod:`usvfast.shore.evaluate_det` picked 0.3–0.45 and 0.5–off on their training videos).
SUPPRESS_NMS = 0.3
SUPPRESS_CONTAIN = 0.7


def containment_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over the smaller area of every box of `a` (n, 4) with every box of `b`
    (m, 4), x, y, w, h px -> (n, m) in [0, 1] (0 where either box is empty)."""
    a = np.asarray(a, dtype=float).reshape(-1, 4)
    b = np.asarray(b, dtype=float).reshape(-1, 4)
    inter = intersection_matrix(a, b)
    small = np.minimum((a[:, 2] * a[:, 3])[:, None], (b[:, 2] * b[:, 3])[None])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(small > 0, inter / small, 0.0)


def suppress_indices(
    boxes: np.ndarray,
    scores: np.ndarray,
    nms: float = SUPPRESS_NMS,
    contain: float = SUPPRESS_CONTAIN,
) -> np.ndarray:
    """Indices of the boxes (k, 4) kept, best `scores` (k,) first (module doc); ties keep
    the earlier box."""
    b = as_float_array("boxes", boxes)
    if b.size % 4:
        raise ValueError(f"boxes: expected (k, 4) x, y, w, h, got shape {b.shape}")
    b = b.reshape(-1, 4)
    s = as_float_array("scores", scores, 1)
    if len(s) != len(b):
        raise ValueError(f"scores: expected {len(b)} scores, got {len(s)}")
    real("nms", nms)
    real("contain", contain)
    if len(b) == 0:
        return np.zeros(0, dtype=int)
    order = np.argsort(-s, kind="stable")
    drop = (iou_matrix(b, b) > nms) | (containment_matrix(b, b) > contain)
    keep: list[int] = []
    for i in order:
        if not any(drop[i, j] for j in keep):
            keep.append(int(i))
    return np.array(keep, dtype=int)


def suppress(
    detections: Detections, nms: float = SUPPRESS_NMS, contain: float = SUPPRESS_CONTAIN
) -> Detections:
    """The detections kept by :func:`suppress_indices`, best score first."""
    instance("detections", detections, Detections)
    k = suppress_indices(detections.boxes, detections.scores, nms, contain)
    return Detections(detections.boxes[k], detections.scores[k], detections.keypoints[k])
