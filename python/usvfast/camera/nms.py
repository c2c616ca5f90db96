"""Non-maximum suppression of detection boxes (Rust core), per class or class-agnostic."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from usvfast import _core
from usvfast._validate import as_float_array, as_index_array


def nms(
    boxes: ArrayLike,
    scores: ArrayLike,
    iou_threshold: float = 0.45,
    classes: ArrayLike | None = None,
) -> np.ndarray:
    """Indices of the boxes kept by greedy NMS, in descending score order (int64, (k,)).

    `boxes` (n, 4) `[x1, y1, x2, y2]` pixels with x2 >= x1, y2 >= y1; `scores` (n,);
    a box is dropped when its IoU with a kept higher-scoring box is strictly greater than
    `iou_threshold` (torchvision semantics; equal scores keep the lower index first). With
    `classes` (n,) integer ids, boxes of different classes never suppress each other
    (`torchvision.ops.batched_nms`). Raises DimensionError / NonFiniteError / ValueError.
    """
    b = as_float_array("boxes", boxes)
    if b.size == 0:
        b = b.reshape(0, 4)
    if b.ndim != 2:
        raise _core.DimensionError(f"boxes: expected a 2-D array (n, 4), got shape {b.shape}")
    s = as_float_array("scores", scores, ndim=1)
    if classes is not None and np.size(classes) == 0:
        classes = np.zeros(0, dtype=np.int64)  # [] is float64 to numpy
    c = None if classes is None else as_index_array("classes", classes, b.shape[0])
    return _core.nms_indices(b, s, float(iou_threshold), c)
