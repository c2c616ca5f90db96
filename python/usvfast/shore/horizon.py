"""The horizon line from the image, after Bloisi et al. (VTS camera surveillance, §IV):
edges -> Hough line candidates -> validation by paired sample points above and under each
candidate (valid when more than 90 % of the pairs differ in intensity) -> water–sky or
water–coast. IR frames are min–max normalised first (their Fig. 8). Detections lying well
above a water–coast (or water–sky) line are dropped.

Pixels, origin top-left, y down. A line is kept as Hough's (rho, theta):
x·cos θ + y·sin θ = rho, θ near π/2 for a near-horizontal line.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

from usvfast._validate import image as check_image
from usvfast._validate import instance
from usvfast.shore.boxes import Detections

HorizonKind = Literal["water-sky", "water-coast"]


@dataclass(frozen=True)
class HorizonConfig:
    """Parameters of the horizon detector (pixels and 8-bit grey levels).

    canny_low, canny_high: Canny thresholds (the paper's 50 and 70). median_kernel: median
    filter size before the edges (odd). hough_votes: minimum Hough accumulator votes as a
    fraction of the image width. max_tilt_deg: candidates steeper than this are ignored.
    samples: sample-point pairs along a candidate. offset_px: distance of each sample point
    above/under the line. intensity_tolerance: two grey levels "differ" when they are more than
    this apart. valid_fraction: the share of differing pairs that validates a line (the paper's
    90 %). coast_edge_density: edge-pixel share in the band above the line from which the line
    is water–coast. drop_margin: a detection is dropped when its bottom lies more than this
    fraction of the image height above the line. max_candidates: Hough lines examined.
    max_width: frames wider than this are searched at this width (px; 0: always full size)
    and the line scaled back: the pixel parameters above hold at that working size.
    """

    canny_low: float = 50.0
    canny_high: float = 70.0
    median_kernel: int = 5
    hough_votes: float = 0.15
    max_tilt_deg: float = 15.0
    samples: int = 60
    offset_px: int = 10
    intensity_tolerance: float = 2.0
    valid_fraction: float = 0.9
    coast_edge_density: float = 0.04
    drop_margin: float = 0.05
    max_candidates: int = 40
    max_width: int = 360

    def __post_init__(self) -> None:
        if self.median_kernel < 1 or self.median_kernel % 2 == 0:
            raise ValueError(f"median_kernel: must be odd and >= 1, got {self.median_kernel}")
        if not 0.0 < self.valid_fraction <= 1.0:
            raise ValueError(f"valid_fraction: must be in (0, 1], got {self.valid_fraction}")
        if self.samples < 2 or self.offset_px < 1:
            raise ValueError("samples: must be >= 2 and offset_px >= 1")


@dataclass(frozen=True)
class HorizonLine:
    """A validated horizon: Hough (rho px, theta rad), `kind` water–sky or water–coast,
    `differing` the share of sample pairs that differ, `edge_density` above the line."""

    rho: float
    theta: float
    kind: HorizonKind
    differing: float
    edge_density: float

    def y_at(self, x: np.ndarray | float) -> np.ndarray:
        """Row (px) of the line at column(s) x (px)."""
        return (self.rho - np.asarray(x, dtype=float) * np.cos(self.theta)) / np.sin(self.theta)

    def endpoints(self, width: int) -> tuple[tuple[int, int], tuple[int, int]]:
        """The line's points at x = 0 and x = width − 1 (px, rounded), for drawing."""
        y0, y1 = self.y_at(np.array([0.0, width - 1.0]))
        return (0, int(np.rint(y0))), (width - 1, int(np.rint(y1)))


def normalise_ir(gray: np.ndarray) -> np.ndarray:
    """Scale and shift an IR frame to the full 0–255 range (min–max normalisation)."""
    check_image("gray", gray)
    return cv2.normalize(gray, None, 0, 255, cv2.NORM_MINMAX)  # pyright: ignore[reportCallIssue, reportArgumentType]


def _pairs_differ(
    gray: np.ndarray, rho: float, theta: float, cfg: HorizonConfig
) -> tuple[float, int]:
    """Share of sample pairs (above, under the line, along its normal) whose grey levels
    differ by more than the tolerance, and the number of pairs inside the image."""
    share, n = _pairs_differ_many(gray, np.array([rho]), np.array([theta]), cfg)
    return float(share[0]), int(n[0])


def _pairs_differ_many(
    gray: np.ndarray, rho: np.ndarray, theta: np.ndarray, cfg: HorizonConfig
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_pairs_differ` of k candidate lines at once: (share (k,), pairs inside (k,));
    the share is 0 for a line with fewer than half its pairs inside the image."""
    h, w = gray.shape
    xs = np.linspace(0.02 * w, 0.98 * w, cfg.samples)[None]  # (1, S)
    cos, sin = np.cos(theta)[:, None], np.sin(theta)[:, None]  # unit normal, down at ≈ π/2
    ys = (rho[:, None] - xs * cos) / sin  # (k, S)
    ax, ay = xs - cfg.offset_px * cos, ys - cfg.offset_px * sin
    bx, by = xs + cfg.offset_px * cos, ys + cfg.offset_px * sin
    inside = (ay >= 0) & (by < h - 1) & (ax >= 0) & (bx < w - 1) & (ax < w) & (bx >= 0)
    n = inside.sum(axis=1)

    def level(y: np.ndarray, x: np.ndarray) -> np.ndarray:
        r = np.clip(np.round(y), 0, h - 1).astype(np.intp)
        c = np.clip(np.round(x), 0, w - 1).astype(np.intp)
        return gray[r, c].astype(float)

    differ = (np.abs(level(ay, ax) - level(by, bx)) > cfg.intensity_tolerance) & inside
    share = np.where(n >= cfg.samples // 2, differ.sum(axis=1) / np.maximum(n, 1), 0.0)
    return share, n


def _edge_density_above(edges: np.ndarray, line: tuple[float, float], band: int) -> float:
    h, w = edges.shape
    rho, theta = line
    ys = (rho - np.arange(w) * np.cos(theta)) / np.sin(theta)
    # only the rows the band can reach (the mask is empty elsewhere)
    r0 = int(np.clip(np.floor(ys.min()) - band - 1, 0, h))
    r1 = int(np.clip(np.ceil(ys.max()), r0, h))
    rows = np.arange(r0, r1)[:, None]
    mask = (rows < ys[None] - 2) & (rows >= ys[None] - band)
    n = int(mask.sum())
    return float(edges[r0:r1][mask].astype(bool).sum() / n) if n else 0.0


def detect_horizon(
    image: np.ndarray, *, infrared: bool = False, config: HorizonConfig | None = None
) -> HorizonLine | None:
    """The horizon of a BGR or grey uint8 frame, or None when no candidate validates.

    infrared: normalise first (IR frames). Among the validated candidates the one with the
    largest share of differing pairs wins (ties: the strongest Hough line). The band above it
    is examined for texture: water–coast when its edge density exceeds `coast_edge_density`.
    """
    check_image("image", image)
    if config is not None:
        instance("config", config, HorizonConfig)
    cfg = config or HorizonConfig()
    if image.ndim == 3:
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    elif image.ndim == 2:
        gray = image
    else:
        raise ValueError(f"image: expected (h, w) or (h, w, 3), got shape {image.shape}")
    if gray.dtype != np.uint8:
        raise TypeError(f"image: expected uint8, got {gray.dtype}")
    if infrared:
        gray = normalise_ir(gray)
    scale = 1.0
    if 0 < cfg.max_width < gray.shape[1]:
        scale = cfg.max_width / gray.shape[1]
        size = (cfg.max_width, max(1, round(gray.shape[0] * scale)))
        gray = cv2.resize(gray, size, interpolation=cv2.INTER_LINEAR)
    smooth = cv2.medianBlur(gray, cfg.median_kernel) if cfg.median_kernel > 1 else gray
    edges = cv2.Canny(smooth, cfg.canny_low, cfg.canny_high)
    h, w = gray.shape
    lines = cv2.HoughLines(
        edges,
        1,
        np.pi / 360,
        max(10, int(cfg.hough_votes * w)),
        min_theta=np.pi / 2 - np.radians(cfg.max_tilt_deg),
        max_theta=np.pi / 2 + np.radians(cfg.max_tilt_deg),
    )
    if lines is None:
        return None
    # lines hugging the top or bottom border (black bars of the frame) are no horizon
    mid_y = (lines[:, 0, 0] - (w / 2) * np.cos(lines[:, 0, 1])) / np.sin(lines[:, 0, 1])
    lines = lines[(mid_y > cfg.offset_px + 2) & (mid_y < h - cfg.offset_px - 2)]
    cand = lines[: cfg.max_candidates, 0].astype(float)
    if len(cand) == 0:
        return None
    shares, _ = _pairs_differ_many(smooth, cand[:, 0], cand[:, 1], cfg)
    valid = shares > cfg.valid_fraction
    if not valid.any():
        return None
    # the largest share wins; ties: the first (strongest) Hough line
    i = int(np.argmax(np.where(valid, shares, -1.0)))
    rho, theta, share = float(cand[i, 0]), float(cand[i, 1]), float(shares[i])
    density = _edge_density_above(edges, (rho, theta), band=max(8, h // 6))
    kind: HorizonKind = "water-coast" if density > cfg.coast_edge_density else "water-sky"
    return HorizonLine(rho / scale, theta, kind, share, density)


def horizon_keep(
    detections: Detections, horizon: HorizonLine | None, height: int, config: HorizonConfig
) -> np.ndarray:
    """Boolean mask (k,) of the detections to keep: those whose bottom edge is not more than
    `drop_margin` × height above the line at the box centre (all kept without a line)."""
    instance("detections", detections, Detections)
    if horizon is not None:
        instance("horizon", horizon, HorizonLine)
    instance("config", config, HorizonConfig)
    if horizon is None or len(detections) == 0:
        return np.ones(len(detections), dtype=bool)
    b = detections.boxes
    line_y = horizon.y_at(b[:, 0] + b[:, 2] / 2)
    return b[:, 1] + b[:, 3] >= line_y - config.drop_margin * height
