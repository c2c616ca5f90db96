"""A training-free "object on the water" boat detector for shore cameras, built on the image
horizon of :mod:`usvfast.shore.horizon` (Bloisi et al., VTS camera surveillance, §IV).

Nothing is learnt, so it cannot overfit a video. Per frame (at a working width):

1. the horizon splits every row into its water part (under the line) and its sky or coast
   part (above it);
2. per row and per side, a robust colour model of the background: the median of each BGR
   channel and its spread, 1.4826 × the median absolute deviation (floored at `mad_floor`
   grey levels) — boats are a minority of every row, so they do not move the median;
3. a pixel's contrast is its largest channel deviation from its row's model in spreads (a
   robust z); pixels above `threshold` are candidate boat pixels;
4. an opening removes glitter specks, a closing (wider than tall) joins a boat's hull,
   superstructure and the rows at the line itself, where sky and water mix;
5. each connected component gives one box, kept when it is boat-shaped (width at least
   `min_width` of the frame and at least `min_aspect` × its height) and sits where boats
   are: across a water–sky line (a ship at the sea horizon is broken by it), or with its
   bottom under a water–coast line (boats float in the harbour, the quay does not).

The score of a box is the mean contrast of its component over 4 × `threshold`, clipped to
[0, 1]. Pixels: origin top-left, x right, y down; boxes x, y, w, h of the input frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from usvfast._validate import image as check_image
from usvfast._validate import instance, integer, real
from usvfast.shore.boxes import Detections
from usvfast.shore.horizon import HorizonConfig, HorizonLine, detect_horizon


@dataclass(frozen=True)
class ContrastConfig:
    """Parameters of :class:`ContrastDetector`.

    threshold: robust z (background spreads) from which a pixel differs from its row.
    work_width: frames wider than this are analysed at this width (px). blur: Gaussian kernel
    (odd, working px) before the row models. mad_floor: smallest spread (grey levels). open_px:
    opening kernel (working px; 1 = none). close: closing kernel (width, height) as fractions of
    the working width. min_width: smallest box width, fraction of the frame width. min_aspect:
    smallest width / height. straddle: a box at a water–sky line must reach within this fraction
    of the frame height of the line from above and from below. min_fill: smallest share of a
    box's pixels above the threshold before the closing (glitter is sparse, a hull solid). wet:
    a box at a water–coast line must end at least this fraction of the frame height under it.
    border_px: rows and columns at the frame's edge ignored (black bars, working px).
    model_step: every this many columns are sampled for the row models. horizon: the horizon
    detector's parameters.
    """

    threshold: float = 3.0
    work_width: int = 352
    blur: int = 5
    mad_floor: float = 3.0
    open_px: int = 3
    close: tuple[float, float] = (0.06, 0.03)
    min_width: float = 0.07
    min_aspect: float = 0.8
    straddle: float = 0.01
    wet: float = 0.05
    border_px: int = 3
    min_fill: float = 0.3
    model_step: int = 3
    horizon: HorizonConfig = field(default_factory=HorizonConfig)

    def __post_init__(self) -> None:
        real("threshold", self.threshold, positive=True)
        integer("work_width", self.work_width, low=16)
        blur = integer("blur", self.blur, low=1)
        if blur % 2 == 0:
            raise ValueError(f"blur: must be odd and >= 1, got {self.blur}")
        real("mad_floor", self.mad_floor, positive=True)
        integer("open_px", self.open_px, low=1)
        integer("border_px", self.border_px, low=0)
        integer("model_step", self.model_step, low=1)
        if not isinstance(self.close, tuple) or len(self.close) != 2:
            raise TypeError(f"close: expected a (width, height) tuple, got {self.close!r}")
        for name, value, high in (
            ("close", self.close[0], 1.0),
            ("close", self.close[1], 1.0),
            ("min_width", self.min_width, 1.0),
            ("min_fill", self.min_fill, 1.0),
            ("straddle", self.straddle, 1.0),
            ("wet", self.wet, 1.0),
        ):
            if not 0.0 <= real(name, value) < high:
                raise ValueError(f"{name}: expected a fraction in [0, 1), got {value}")
        real("min_aspect", self.min_aspect, low=0.0)
        instance("horizon", self.horizon, HorizonConfig)


def _row_models(plane: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row of one channel `plane` (h, w) float32, the median (h,) and 1.4826 × MAD (h,)
    of the pixels where `mask` (h, w) is True; NaN for rows with fewer than 30 % of w such
    pixels. Rows fully inside the mask by median, the partial ones by sorting (masked-out
    pixels sorted last), both for all rows at once."""
    h, w = mask.shape
    med = np.full(h, np.nan, np.float32)
    mad = np.full(h, np.nan, np.float32)
    count = mask.sum(axis=1)
    full = count == w
    if full.any():
        v = plane[full]
        m = np.median(v, axis=1)
        med[full] = m
        mad[full] = 1.4826 * np.median(np.abs(v - m[:, None]), axis=1)
    part = (count >= 0.3 * w) & ~full
    if part.any():
        n = count[part][:, None]
        lo, hi = (n - 1) // 2, n // 2

        def masked_median(v: np.ndarray) -> np.ndarray:
            v = np.sort(np.where(mask[part], v, np.inf), axis=1)
            return 0.5 * (np.take_along_axis(v, lo, 1) + np.take_along_axis(v, hi, 1))[:, 0]

        m = masked_median(plane[part])
        med[part] = m
        mad[part] = 1.4826 * masked_median(np.abs(plane[part] - m[:, None]))
    return med, mad


def _check_frame(image: np.ndarray, horizon: HorizonLine | None) -> None:
    check_image("image", image)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"image: expected (h, w, 3) uint8 BGR, got {image.shape} {image.dtype}")
    if horizon is not None:
        instance("horizon", horizon, HorizonLine)
        real("horizon.rho", horizon.rho)
        if not np.sin(real("horizon.theta", horizon.theta)) > 1e-3:
            raise ValueError(f"horizon: a near-vertical line (theta {horizon.theta}) is no horizon")


def contrast_map(
    image: np.ndarray, horizon: HorizonLine | None, config: ContrastConfig
) -> tuple[np.ndarray, np.ndarray, float]:
    """The robust contrast (z, background spreads) of every pixel of a BGR frame at the
    working size, the line's row per working column (all 0 without a line) and the scale
    working / input px. Pixels on the frame's border and in rows without a model get 0."""
    _check_frame(image, horizon)
    instance("config", config, ContrastConfig)
    h0, w0 = image.shape[:2]
    s = config.work_width / w0 if w0 > config.work_width else 1.0
    small = (
        cv2.resize(image, (round(w0 * s), max(1, round(h0 * s))), interpolation=cv2.INTER_AREA)
        if s < 1
        else image
    )
    h, w = small.shape[:2]
    k = config.blur
    sm = cv2.GaussianBlur(small, (k, k), 0) if k > 1 else small
    if horizon is None:
        line = np.zeros(w)
    else:
        line = horizon.y_at((np.arange(w) + 0.5) / s) * s
    below = np.arange(h)[:, None] >= line[None]
    above = ~below
    z = np.zeros((h, w), np.float32)
    step = config.model_step
    for plane in cv2.split(sm):
        plane = plane.astype(np.float32)
        mb, sb = _row_models(plane[:, ::step], below[:, ::step])
        ma, sa = _row_models(plane[:, ::step], above[:, ::step])
        med = np.where(below, np.nan_to_num(mb)[:, None], np.nan_to_num(ma)[:, None])
        spread = np.where(
            below, np.nan_to_num(sb, nan=np.inf)[:, None], np.nan_to_num(sa, nan=np.inf)[:, None]
        )
        np.maximum(z, np.abs(plane - med) / np.maximum(spread, config.mad_floor), out=z)
    b = config.border_px
    if b > 0:
        z[:b] = 0
        z[-b:] = 0
        z[:, :b] = 0
        z[:, -b:] = 0
    return z, line, s


class ContrastDetector:
    """Boats of a BGR frame as blobs that contrast with their row's water, sky or coast
    (module doc). `detect(image, horizon=None)` -> :class:`Detections` (x, y, w, h px of
    the input frame, scores in [0, 1], keypoints −1); the horizon is found when not given
    (pass the chain's own line to avoid finding it twice)."""

    def __init__(self, config: ContrastConfig | None = None) -> None:
        if config is not None:
            instance("config", config, ContrastConfig)
        self.config = config or ContrastConfig()

    def detect(self, image: np.ndarray, horizon: HorizonLine | None = None) -> Detections:
        """Boats of one BGR uint8 frame (h, w, 3) (module doc)."""
        _check_frame(image, horizon)
        if horizon is None:
            horizon = detect_horizon(image, config=self.config.horizon)
        cfg = self.config
        z, line, s = contrast_map(image, horizon, cfg)
        h, w = z.shape
        mask = (z > cfg.threshold).astype(np.uint8)
        if cfg.open_px > 1:
            mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((cfg.open_px,) * 2, np.uint8))
        kw, kh = (max(1, round(c * w)) for c in cfg.close)
        if kw > 1 or kh > 1:
            mask = cv2.morphologyEx(
                mask, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_RECT, (kw, kh))
            )
        raw = z > cfg.threshold
        n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        if n <= 1:
            return Detections()
        box = stats[1:, :4].astype(float)
        sums = np.bincount(labels.ravel(), weights=(z * mask).ravel(), minlength=n)[1:]
        mean_z = sums / np.maximum(stats[1:, 4], 1)
        fill = np.bincount(labels.ravel(), weights=raw.ravel(), minlength=n)[1:] / np.maximum(
            box[:, 2] * box[:, 3], 1
        )
        keep = (box[:, 2] >= cfg.min_width * w) & (box[:, 2] >= cfg.min_aspect * box[:, 3])
        keep &= fill >= cfg.min_fill
        if horizon is not None:
            cx = np.clip((box[:, 0] + box[:, 2] / 2).astype(int), 0, w - 1)
            ly = line[cx]
            top, bottom = box[:, 1], box[:, 1] + box[:, 3]
            if horizon.kind == "water-sky":
                keep &= (top <= ly + cfg.straddle * h) & (bottom >= ly - cfg.straddle * h)
            else:
                keep &= bottom >= ly + cfg.wet * h
        box, mean_z = box[keep] / s, mean_z[keep]
        scores = np.clip(mean_z / (4 * cfg.threshold), 0.0, 1.0)
        return Detections(box, scores, np.full(len(box), -1, dtype=np.int64))
