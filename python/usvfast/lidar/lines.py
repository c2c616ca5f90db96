"""Line extraction for the LiDAR pipeline: raster image, OpenCV LSD, and the line memory.

Segments are (m, 4) float64 arrays of rows [x1, y1, x2, y2] in metres in the sensor frame
(x forward, y left). The raster covers [-radius, radius)² with square pixels; pixel (row,
col) holds the points with floor((y + radius)/pixel) = row and floor((x + radius)/pixel) =
col.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from usvfast._core import DimensionError
from usvfast._validate import as_float_array, integer, real


def _grid(radius: float, pixel: float) -> int:
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"radius: expected a positive number of metres, got {radius}")
    if not (np.isfinite(pixel) and 0 < pixel <= radius):
        raise ValueError(f"pixel: expected 0 < pixel <= radius, got {pixel}")
    if 2 * radius / pixel > 100_000:
        raise ValueError(f"pixel: {pixel} m makes a raster wider than 100000 pixels")
    return int(np.ceil(2 * radius / pixel))


def rasterize(points: np.ndarray, *, radius: float = 10.0, pixel: float = 0.2) -> np.ndarray:
    """Binary image (uint8, 255 where at least one point falls) of (n, 2) points in metres.

    The image is square, ceil(2·radius/pixel) pixels wide; points outside the square are
    ignored. Raises DimensionError / NonFiniteError on bad points.
    """
    size = _grid(radius, pixel)
    xy = as_float_array("points", points, ndim=2).reshape(-1, 2)
    col = np.floor((xy[:, 0] + radius) / pixel).astype(np.int64)
    row = np.floor((xy[:, 1] + radius) / pixel).astype(np.int64)
    inside = (col >= 0) & (col < size) & (row >= 0) & (row < size)
    image = np.zeros((size, size), dtype=np.uint8)
    image[row[inside], col[inside]] = 255
    return image


def blur(image: np.ndarray) -> np.ndarray:
    """3×3 Gaussian blur (OpenCV, sigma from the kernel size) that joins near pixels.
    `image`: a 2-D uint8 array (as `rasterize` makes); anything else is a TypeError."""
    if not isinstance(image, np.ndarray) or image.ndim != 2 or image.dtype != np.uint8:
        raise TypeError(f"image: expected a 2-D uint8 array, got {_describe(image)}")
    return cv2.GaussianBlur(image, (3, 3), 0)


def _describe(value) -> str:
    if isinstance(value, np.ndarray):
        return f"{value.dtype} array of shape {value.shape}"
    return type(value).__name__


def _rows(name: str, value, width: int) -> np.ndarray:
    """(m, width) finite float64 rows from `value` (any array of m·width numbers)."""
    a = as_float_array(name, value)
    if a.size % width or (a.ndim >= 2 and a.shape[-1] != width) or a.ndim > 2:
        raise DimensionError(f"{name}: expected shape (m, {width}), got {a.shape}")
    return a.reshape(-1, width)


_LSD = None


def _lsd():
    global _LSD
    if _LSD is None:
        _LSD = cv2.createLineSegmentDetector()
    return _LSD


def detect_segments(
    image: np.ndarray,
    *,
    radius: float = 10.0,
    pixel: float = 0.2,
    min_length: float = 1.0,
) -> np.ndarray:
    """Run OpenCV's Line Segment Detector on a raster and return (m, 4) segments in metres.

    LSD coordinates have pixel centres on integers; they map back to metres as
    (coordinate + 0.5)·pixel − radius. Segments shorter than `min_length` metres are dropped
    (small floating objects must not be taken for walls). A one-pixel-wide line gives two
    segments, one along each of its edges.
    """
    _grid(radius, pixel)
    if not isinstance(image, np.ndarray) or image.ndim != 2 or image.dtype != np.uint8:
        raise TypeError(f"image: expected a 2-D uint8 image, got {_describe(image)}")
    lines = _lsd().detect(image)[0]
    if lines is None:
        return np.zeros((0, 4))
    seg = (lines.reshape(-1, 4).astype(np.float64) + 0.5) * pixel - radius
    length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    return seg[length >= min_length]


def point_segment_distance(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """(n, m) Euclidean distance from each point (n, 2) to each segment (m, 4), metres."""
    p = _rows("points", points, 2)
    s = _rows("segments", segments, 4)
    scale = max(np.abs(p).max(initial=0.0), np.abs(s).max(initial=0.0))
    if scale > 1e150:  # the squares would overflow: the same in units of `scale`
        return point_segment_distance(p / scale, s / scale) * scale
    px, py = p[:, 0:1], p[:, 1:2]
    ax, ay = s[None, :, 0], s[None, :, 1]
    dx, dy = s[None, :, 2] - ax, s[None, :, 3] - ay
    len2 = dx * dx + dy * dy
    rx, ry = px - ax, py - ay
    t = np.clip((rx * dx + ry * dy) / np.where(len2 > 0, len2, 1.0), 0.0, 1.0)
    ex, ey = rx - t * dx, ry - t * dy
    return np.sqrt(ex * ex + ey * ey)


def covered_mask(segments: np.ndarray, tolerance: float = 0.2) -> np.ndarray:
    """(m,) bool: True for segments lying entirely within `tolerance` of another, longer one.

    A segment is covered when both its endpoints are within `tolerance` (m) of one other
    segment at least as long; of two equal segments covering each other the earlier is kept.
    """
    seg = _rows("segments", segments, 4)
    tolerance = real("tolerance", tolerance, low=0.0)
    m = seg.shape[0]
    if m < 2:
        return np.zeros(m, dtype=bool)
    length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    lo = np.minimum(seg[:, :2], seg[:, 2:])
    hi = np.maximum(seg[:, :2], seg[:, 2:])
    idx = np.arange(m)
    # candidates: j at least as long as i (ties: the earlier wins) and i's bounding box
    # inside j's grown by the tolerance; then the exact endpoint distances on those pairs
    cand = (length[None, :] > length[:, None]) | (
        (length[None, :] == length[:, None]) & (idx[None, :] < idx[:, None])
    )
    for k in (0, 1):
        cand &= lo[:, None, k] >= lo[None, :, k] - tolerance
        cand &= hi[:, None, k] <= hi[None, :, k] + tolerance
    i, j = np.nonzero(cand)
    covered = np.zeros(m, dtype=bool)
    if i.size:
        a, d = seg[j, :2], seg[j, 2:] - seg[j, :2]
        len2 = (d * d).sum(axis=1)
        ok = np.ones(i.size, dtype=bool)
        for end in (seg[i, :2], seg[i, 2:]):
            r = end - a
            t = np.clip((r * d).sum(axis=1) / np.where(len2 > 0, len2, 1.0), 0.0, 1.0)
            e = r - t[:, None] * d
            ok &= (e * e).sum(axis=1) <= tolerance * tolerance
        covered[i[ok]] = True
    return covered


def drop_covered(segments: np.ndarray, tolerance: float = 0.2) -> np.ndarray:
    """Segments (m, 4) without those covered by another (`covered_mask`), order kept."""
    seg = _rows("segments", segments, 4)
    return seg[~covered_mask(seg, real("tolerance", tolerance, low=0.0))]


def move_segments(segments: np.ndarray, motion: tuple[float, float, float]) -> np.ndarray:
    """Express segments of the previous sensor frame in the current one.

    `motion` = (dx, dy, dyaw): the sensor's displacement (m, previous sensor frame, x
    forward / y left) and its rotation (rad, counter-clockwise seen from above) between the
    two frames. A world-fixed point p becomes R(−dyaw)·(p − d).
    """
    m = as_float_array("motion", motion)
    if m.shape != (3,):
        raise DimensionError(f"motion: expected (dx, dy, dyaw), got shape {m.shape}")
    dx, dy, dyaw = (float(v) for v in m)
    c, s = np.cos(dyaw), np.sin(dyaw)
    seg = _rows("segments", segments, 4)
    out = np.empty_like(seg)
    for k in (0, 2):
        px, py = seg[:, k] - dx, seg[:, k + 1] - dy
        out[:, k] = c * px + s * py
        out[:, k + 1] = -s * px + c * py
    return out


@dataclass
class LineMemory:
    """Segments that persist for `frames` frames, moved with the vessel between frames.

    `update(new, motion)` moves the remembered segments by `motion` (see `move_segments`),
    adds the new ones, forgets those older than `frames` frames and drops covered ones
    (`drop_covered` with `cover_tolerance`); it returns the active (m, 4) segments in the
    current sensor frame. Thesis 5.3.5: LSD sometimes splits one wall into pieces with gaps;
    remembering the last frames closes them.
    """

    frames: int = 3
    cover_tolerance: float = 0.2
    _segments: np.ndarray = field(init=False, repr=False, default_factory=lambda: np.zeros((0, 4)))
    _age: np.ndarray = field(
        init=False, repr=False, default_factory=lambda: np.zeros(0, dtype=np.int64)
    )

    def __post_init__(self) -> None:
        if isinstance(self.frames, float) and self.frames.is_integer():
            self.frames = int(self.frames)
        self.frames = integer("frames", self.frames, low=1, high=10**6)
        self.cover_tolerance = real("cover_tolerance", self.cover_tolerance, low=0.0)

    def update(
        self, new_segments: np.ndarray, motion: tuple[float, float, float] = (0.0, 0.0, 0.0)
    ) -> np.ndarray:
        """Advance one frame; return the active segments (m, 4) in the current sensor frame."""
        new = as_float_array("new_segments", new_segments).reshape(-1, 4)
        old = move_segments(self._segments, motion)
        age = self._age + 1
        keep = age < self.frames
        seg = np.vstack([new, old[keep]])
        ages = np.concatenate([np.zeros(new.shape[0], dtype=np.int64), age[keep]])
        length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
        seg, ages = seg[length > 0], ages[length > 0]
        mask = ~covered_mask(seg, self.cover_tolerance)
        self._segments, self._age = seg[mask], ages[mask]
        return self._segments.copy()

    @property
    def segments(self) -> np.ndarray:
        """Active segments (m, 4) in the sensor frame of the last update."""
        return self._segments.copy()

    def reset(self) -> None:
        """Forget every segment."""
        self._segments = np.zeros((0, 4))
        self._age = np.zeros(0, dtype=np.int64)


def extend_segments(segments: np.ndarray, distance: float) -> np.ndarray:
    """Lengthen each segment (m, 4) by `distance` metres at both ends (zero-length ones stay).

    LSD stops about half a pixel short of a line's ends and leaves corners open; extending
    by a pixel or two closes them before the line-of-sight filter.
    """
    seg = _rows("segments", segments, 4)
    distance = real("distance", distance)
    d = seg[:, 2:] - seg[:, :2]
    length = np.hypot(d[:, 0], d[:, 1])
    unit = d / np.where(length > 0, length, 1.0)[:, None]
    return np.hstack([seg[:, :2] - distance * unit, seg[:, 2:] + distance * unit])
