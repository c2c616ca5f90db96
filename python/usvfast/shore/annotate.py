"""Drawing of the annotated output video: detections (thin grey), tracks (coloured by id, with
the id), the horizon line (green water–sky, orange water–coast) and the frame class."""

from __future__ import annotations

import cv2
import numpy as np

from usvfast._validate import image as check_image
from usvfast.shore.horizon import HorizonLine


def id_colour(track_id: int) -> tuple[int, int, int]:
    """A stable BGR colour of a track id."""
    rng = np.random.default_rng(track_id * 7919 + 13)
    b, g, r = (int(v) for v in rng.integers(64, 256, 3))
    return b, g, r


def draw_frame(
    image: np.ndarray,
    detections: np.ndarray,
    ids: np.ndarray,
    tracks: np.ndarray,
    horizon: HorizonLine | None,
    label: str,
) -> np.ndarray:
    """A copy of `image` (BGR) with detections (k, 4), tracks (ids (t,), boxes (t, 4)),
    the horizon and a text label in the top-left corner."""
    check_image("image", image)
    if not isinstance(label, str):
        raise TypeError(f"label: expected str, got {type(label).__name__}")
    out = image.copy()
    w = out.shape[1]
    if horizon is not None:
        colour = (0, 200, 0) if horizon.kind == "water-sky" else (0, 140, 255)
        p0, p1 = horizon.endpoints(w)
        cv2.line(out, p0, p1, colour, 1, cv2.LINE_AA)
    for b in np.asarray(detections).reshape(-1, 4):
        x, y, bw, bh = (int(np.rint(v)) for v in b)
        cv2.rectangle(out, (x, y), (x + bw, y + bh), (160, 160, 160), 1)
    for tid, b in zip(ids, np.asarray(tracks).reshape(-1, 4), strict=True):
        x, y, bw, bh = (int(np.rint(v)) for v in b)
        c = id_colour(int(tid))
        cv2.rectangle(out, (x, y), (x + bw, y + bh), c, 2)
        cv2.putText(out, str(int(tid)), (x, max(y - 3, 10)), cv2.FONT_HERSHEY_SIMPLEX, 0.4, c, 1)
    cv2.putText(out, label, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1)
    return out
