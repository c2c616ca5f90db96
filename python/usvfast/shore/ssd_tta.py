"""Test-time augmentation of an SSD boat detector (:class:`usvfast.shore.pretrained.
SsdDetector`): the frame, its left–right mirror and, with `zoom` > 1, overlapping tiles of the
frame enlarged `zoom` times beyond the network's letterbox scale, each run through the network;
their candidate boxes (every anchor scoring at least the threshold) are pooled and one greedy
NMS keeps the best (the detector's IoU threshold).

Why: the network sees a frame at most `input_size` large (320 × 240 for the fine-tuned
models), so a boat a few pixels long in a small frame falls below the smallest anchors; a tile
of the enlarged frame shows it `zoom` times larger, a scale the training views (scale 0.6–1.5)
also covered. A tile's box that touches the tile's inner edge (one that is not the frame's
border) is dropped: it is a boat cut by the tile, which the whole-frame pass or the next tile
sees whole. Boxes x, y, w, h px.
"""

from __future__ import annotations

import math

import numpy as np

from usvfast._validate import instance, real
from usvfast.shore.boxes import Detections
from usvfast.shore.pretrained import SsdDetector, suppressed

#: Share of a tile that overlaps the next one (along each axis).
TILE_OVERLAP = 0.25
#: A tile box within this many px of an inner tile edge is dropped.
EDGE_PX = 2.0


def tile_origins(length: float, tile: float, overlap: float = TILE_OVERLAP) -> list[float]:
    """Start coordinates of tiles of size `tile` covering [0, `length`) with at least
    `overlap` of a tile shared by neighbours; the last tile ends at `length` (one tile at 0
    when `tile` ≥ `length`)."""
    if tile >= length:
        return [0.0]
    n = math.ceil((length - tile) / (tile * (1.0 - overlap))) + 1
    return [float(v) for v in np.linspace(0.0, length - tile, n)]


class SsdTta:
    """Boats of a BGR frame from an :class:`usvfast.shore.pretrained.SsdDetector` with
    test-time augmentation (module doc). `flip`: also run the mirrored frame; `zoom` ≥ 1:
    also run tiles of the frame enlarged `zoom` times (1: no tiles). Its threshold, NMS IoU
    and `top_k` are the detector's. `detect(image)` -> :class:`usvfast.shore.boxes.Detections`."""

    def __init__(self, detector, *, flip: bool = True, zoom: float = 1.0) -> None:
        instance("detector", detector, SsdDetector)
        if not isinstance(flip, bool | np.bool_):
            raise TypeError(f"flip: expected a bool, got {type(flip).__name__}")
        self.zoom = real("zoom", zoom, low=1.0)
        if self.zoom > 4.0:
            raise ValueError(f"zoom: expected 1..4, got {self.zoom}")
        self.detector = detector
        self.flip = bool(flip)

    @property
    def conf_threshold(self) -> float:
        """The detector's confidence threshold."""
        return self.detector.conf_threshold

    def views(self, image: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Candidate boxes (n, 4) x1, y1, x2, y2 frame px and scores (n,) of each view:
        "frame", "mirror" (with `flip`) and "tiles" (with `zoom` > 1, every tile's boxes)."""
        det = self.detector
        h, w = image.shape[:2]
        out = {"frame": det.candidates(image)}
        if self.flip:
            b, s = det.candidates(np.ascontiguousarray(image[:, ::-1]))
            out["mirror"] = (np.stack([w - b[:, 2], b[:, 1], w - b[:, 0], b[:, 3]], 1), s)
        if self.zoom > 1.0:
            iw, ih = det.input_size
            scale = min(iw / w, ih / h) * self.zoom
            tw, th = min(iw / scale, w), min(ih / scale, h)
            parts_b, parts_s = [np.zeros((0, 4))], [np.zeros(0)]
            for y0 in tile_origins(h, th):
                for x0 in tile_origins(w, tw):
                    x, y = round(x0), round(y0)
                    crop = image[y : y + round(th), x : x + round(tw)]
                    b, s = det.candidates(np.ascontiguousarray(crop))
                    ch, cw = crop.shape[:2]
                    inner = np.zeros(len(b), bool)
                    if x > 0:
                        inner |= b[:, 0] <= EDGE_PX
                    if y > 0:
                        inner |= b[:, 1] <= EDGE_PX
                    if x + cw < w:
                        inner |= b[:, 2] >= cw - EDGE_PX
                    if y + ch < h:
                        inner |= b[:, 3] >= ch - EDGE_PX
                    parts_b.append(b[~inner] + [x, y, x, y])
                    parts_s.append(s[~inner])
            out["tiles"] = (np.concatenate(parts_b), np.concatenate(parts_s))
        return out

    def candidates(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pooled candidate boxes (n, 4) x1, y1, x2, y2 px and scores (n,) of every view."""
        v = list(self.views(image).values())
        return np.concatenate([b for b, _ in v]).reshape(-1, 4), np.concatenate([s for _, s in v])

    def detect(self, image: np.ndarray) -> Detections:
        """Boats of one BGR uint8 frame (h, w, 3): x, y, w, h px, scores, keypoints −1."""
        det = self.detector
        return suppressed(*self.candidates(image), det.iou_threshold, det.top_k)
