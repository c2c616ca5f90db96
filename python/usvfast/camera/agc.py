"""Automatic gain control: a 16-bit or floating-point frame (a thermal camera's raw counts,
`mono16` / `16UC1` / `32FC1` images) to the 8-bit frame the detectors take.

A linear stretch between two percentiles of the frame's own values, as a thermal camera's
linear AGC does: the `low` percentile becomes 0, the `high` one 255, values beyond are clipped,
so a few hot or dead pixels do not set the scale. A flat frame becomes zeros; in a
floating-point frame, non-finite values are left out of the percentiles, NaN becomes 0 and
±inf 255 / 0.

    from usvfast.camera.agc import to_uint8
    frame8 = to_uint8(frame16, (1.0, 99.0))
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["to_uint8"]


def to_uint8(image: np.ndarray, percentiles: Sequence[float] = (1.0, 99.0)) -> np.ndarray:
    """`image` (H, W) or (H, W, C) of any integer or float dtype stretched linearly so that
    its `percentiles` (low, high; 0–100, over all channels) become 0 and 255; uint8 of the
    same shape (a uint8 frame is returned as it is). Percentiles are numpy's "linear" ones.
    Raises TypeError for a non-numeric or complex array, ValueError for percentiles that are
    not 0 <= low < high <= 100."""
    if not isinstance(image, np.ndarray) or image.dtype.kind not in "uif":
        kind = image.dtype if isinstance(image, np.ndarray) else type(image).__name__
        raise TypeError(f"image: expected an integer or float array, got {kind}")
    if len(percentiles) != 2:
        raise ValueError(f"percentiles: expected (low, high), got {percentiles!r}")
    low, high = (float(p) for p in percentiles)
    if not 0.0 <= low < high <= 100.0:
        raise ValueError(f"percentiles: expected 0 <= low < high <= 100, got {percentiles!r}")
    if image.dtype == np.uint8:
        return image
    if image.dtype.kind == "u" and image.dtype.itemsize <= 2:
        lo, hi = _histogram_percentiles(image, low, high)
    else:
        values = image[np.isfinite(image)] if image.dtype.kind == "f" else image
        if values.size == 0:
            return np.zeros(image.shape, np.uint8)
        lo, hi = np.percentile(values, [low, high])
    if not hi > lo:
        return np.zeros(image.shape, np.uint8)
    scaled = image.astype(np.float64)
    scaled -= lo
    scaled *= 255.0 / (hi - lo)
    np.clip(scaled, 0.0, 255.0, out=scaled)
    if image.dtype.kind == "f":
        scaled[np.isnan(scaled)] = 0.0
    return np.rint(scaled, out=scaled).astype(np.uint8)


def _histogram_percentiles(image: np.ndarray, low: float, high: float) -> tuple[float, float]:
    """numpy's linear percentiles of an unsigned ≤ 16-bit frame from its histogram (one
    counting pass instead of a partition: 0.7 ms against 4 ms for 640 × 512)."""
    counts = np.bincount(image.ravel(), minlength=1)
    below = np.cumsum(counts)  # below[v] = number of pixels <= v
    n = int(below[-1])
    out = []
    for p in (low, high):
        rank = p / 100.0 * (n - 1)
        k = int(np.floor(rank))
        a, b = np.searchsorted(below, [k + 1, min(k + 2, n)])  # k-th and (k+1)-th smallest
        out.append(float(a) + (float(b) - float(a)) * (rank - k))
    return out[0], out[1]
