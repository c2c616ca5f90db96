"""The vessel detector of Kim, Chung and Lee (§III): the day/night class picks a binary
threshold (23 for EO, 203 for IR, eq. 4), erosion then dilation with a 3×3 window, twice each
(eqs. 5–8), keypoints on the cleaned image, and the vessel's box from the keypoints' extent
(their pseudo-code steps 3–7; a keypoint counts with its region, centre ± half its size).

Keypoints: the paper uses STAR (OpenCV's CenSurE variant, scale-space extrema of box-filter
Laplacians on integral images). STAR is in opencv-contrib, which opencv-python-headless does
not ship; the closest available detector is SIFT (scale-space extrema of a difference of
Gaussians, itself an approximation of the Laplacian), used by default; 'star' runs the paper's
detector where an opencv-contrib build is installed; ORB and FAST are offered for speed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import cv2
import numpy as np
from scipy.cluster.hierarchy import fcluster, linkage

from usvfast._validate import instance
from usvfast.shore.boxes import Detections
from usvfast.shore.daynight import DayNightClassifier, FrameClass

KeypointDetector = Literal["sift", "star", "orb", "fast"]
Grouping = Literal["extent", "clusters"]
ThresholdMode = Literal["paper", "otsu"]


def make_keypoint_detector(kind: KeypointDetector, max_keypoints: int = 500) -> cv2.Feature2D:
    """An OpenCV keypoint detector: 'sift' (closest to STAR/CenSurE), 'star' (the paper's,
    only with an opencv-contrib build: ValueError otherwise), 'orb' or 'fast'."""
    if kind == "star":
        xf = getattr(cv2, "xfeatures2d", None)
        if xf is None or not hasattr(xf, "StarDetector_create"):
            raise ValueError("keypoints: 'star' needs opencv-contrib (cv2.xfeatures2d); use 'sift'")
        return xf.StarDetector_create()
    if kind == "sift":
        return cv2.SIFT_create(nfeatures=max_keypoints)  # pyright: ignore[reportAttributeAccessIssue]
    if kind == "orb":
        return cv2.ORB_create(nfeatures=max_keypoints)  # pyright: ignore[reportAttributeAccessIssue]
    if kind == "fast":
        return cv2.FastFeatureDetector_create()  # pyright: ignore[reportAttributeAccessIssue]
    raise ValueError(f"keypoints: expected 'sift', 'star', 'orb' or 'fast', got {kind!r}")


@dataclass(frozen=True)
class BayesDetectorConfig:
    """Parameters (8-bit levels, pixels). thresholds: binary threshold per frame class (the
    paper's 23 for EO and 203 for IR, eq. 4); max_value: the value above it (255);
    morph_kernel: the square window of erosion and dilation (3); morph_iterations: how many
    times each is applied (2); keypoints: the detector; min_keypoints: fewer keypoints than
    this give no detection; border_px: keypoints this close to the image border are ignored
    (the threshold's frame edge); grouping: 'extent' (the paper: one box around all
    keypoints, one vessel per frame) or 'clusters' (ours, for several vessels: keypoints
    grouped by single linkage within cluster_px, one box per group of min_keypoints or more);
    threshold_mode: 'paper' (the fixed `thresholds` of eq. 4) or 'otsu' (data-driven, per
    frame: Otsu's level that best splits the grey histogram in two, for footage on which the
    fixed levels find nothing).
    """

    thresholds: dict[str, float] = field(default_factory=lambda: {"eo": 23.0, "ir": 203.0})
    max_value: float = 255.0
    morph_kernel: int = 3
    morph_iterations: int = 2
    keypoints: KeypointDetector = "sift"
    min_keypoints: int = 3
    border_px: int = 4
    grouping: Grouping = "extent"
    threshold_mode: ThresholdMode = "paper"
    cluster_px: float = 15.0

    def __post_init__(self) -> None:
        if self.threshold_mode not in ("paper", "otsu"):
            raise ValueError(
                f"threshold_mode: expected 'paper' or 'otsu', got {self.threshold_mode!r}"
            )


class BayesDetector:
    """One box per frame, the extent of the keypoints of the thresholded, cleaned frame.

    `detect(image)` -> Detections (score 1.0, keypoint count kept): 0 or 1 box with the
    paper's 'extent' grouping, one per keypoint cluster with 'clusters';
    `last_class` and `last_binary` hold the frame class and the cleaned binary image.
    """

    def __init__(
        self,
        config: BayesDetectorConfig | None = None,
        classifier: DayNightClassifier | None = None,
    ) -> None:
        if config is not None:
            instance("config", config, BayesDetectorConfig)
        if classifier is not None:
            instance("classifier", classifier, DayNightClassifier)
        self.config = config or BayesDetectorConfig()
        self.classifier = classifier or DayNightClassifier.default()
        self.kernel = np.ones((self.config.morph_kernel,) * 2, np.uint8)
        self.keypoint_detector = make_keypoint_detector(self.config.keypoints)
        self.last_class: FrameClass = "eo"
        self.last_binary: np.ndarray | None = None

    def binary(self, image: np.ndarray, frame_class: FrameClass) -> np.ndarray:
        """The thresholded (eq. 4) and cleaned (eqs. 5–8) uint8 image of a BGR frame."""
        cfg = self.config
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
        # s = max_value if r > threshold else 0  (eq. 4)
        if cfg.threshold_mode == "otsu":
            _, b = cv2.threshold(gray, 0, cfg.max_value, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
        else:
            level = cfg.thresholds[frame_class]
            _, b = cv2.threshold(gray, level, cfg.max_value, cv2.THRESH_BINARY)
        # erode(f, g) = θ(f * g, S), dilate(f, g) = θ(f * g, 1) with g the 3×3 window (eq. 8)
        b = cv2.erode(b, self.kernel, iterations=cfg.morph_iterations)
        return cv2.dilate(b, self.kernel, iterations=cfg.morph_iterations)

    def detect(self, image: np.ndarray) -> Detections:
        """The box(es) (x, y, w, h px) spanned by the keypoints of the cleaned frame."""
        cfg = self.config
        self.last_class = self.classifier.classify(image)
        b = self.binary(image, self.last_class)
        self.last_binary = b
        kps = self.keypoint_detector.detect(b, None)
        h, w = b.shape
        # each keypoint: centre (x, y) and radius (half its size, px)
        pts = np.array([(*k.pt, k.size / 2) for k in kps], dtype=float).reshape(-1, 3)
        inside = (
            (pts[:, 0] >= cfg.border_px)
            & (pts[:, 0] < w - cfg.border_px)
            & (pts[:, 1] >= cfg.border_px)
            & (pts[:, 1] < h - cfg.border_px)
        )
        pts = pts[inside]
        if len(pts) < cfg.min_keypoints:
            return Detections()
        if cfg.grouping == "extent":
            groups = [pts]
        else:
            labels = fcluster(
                linkage(pts[:, :2], method="single"), cfg.cluster_px, criterion="distance"
            )
            groups = [pts[labels == k] for k in np.unique(labels)]
            groups = [g for g in groups if len(g) >= cfg.min_keypoints]
        if not groups:
            return Detections()
        boxes = []
        for g in groups:
            # steps 5–7: lowest and highest coordinates -> the box around the vessel
            x0, y0 = (g[:, :2] - g[:, 2:]).min(axis=0)
            x1, y1 = (g[:, :2] + g[:, 2:]).max(axis=0)
            boxes.append([x0, y0, max(x1 - x0, 1.0), max(y1 - y0, 1.0)])
        counts = np.array([len(g) for g in groups])
        return Detections(np.array(boxes), np.ones(len(groups)), counts)
