"""Global image motion between two frames of a fixed or slowly panning shore camera, so that
a neighbouring frame can be warped onto the current one before a per-pixel background is
built (:mod:`usvfast.shore.change`).

Two OpenCV estimators:

1. ORB keypoints (`cv2.ORB_create`), brute-force Hamming matching with cross-check, and a
   RANSAC similarity (rotation, uniform scale, translation; `cv2.estimateAffinePartial2D`):
   robust to large pans and zooms and to boats moving through the scene (their matches are
   outliers);
2. enhanced correlation (`cv2.findTransformECC`) over the whole frame, from the identity
   (rotation + translation) and from the ORB similarity (affine when it zooms); the start
   whose result correlates best is kept — the frame's area, not its keypoints, decides, so
   a big textured boat that holds most keypoints cannot pull the warp onto itself. ECC
   failing from both, the ORB similarity alone.

When all fail the pair is reported as not registered (the caller skips that neighbour).
Warps are 2 × 3 float32 affine matrices mapping pixel (x, y) of the *moving* frame to the
*reference* frame (origin top-left, x right, y down), in input pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from usvfast._validate import image as check_image
from usvfast._validate import integer, real

#: How a warp was found: ECC from the identity, ECC from the ORB similarity, the ORB
#: similarity alone (ECC did not converge), or not at all.
METHODS = ("ecc", "orb", "orb-only", "none")


@dataclass(frozen=True)
class RegisterConfig:
    """Parameters of :func:`register`.

    work_width: frames wider than this are registered at this width (px; the warp is scaled
    back to input pixels). orb_features: ORB keypoints per frame. min_inliers: RANSAC inliers
    needed to accept the ORB similarity. ransac_px: RANSAC reprojection threshold (working
    px). max_scale: the similarity's scale must lie within [1/max_scale, max_scale]. zoom:
    from a similarity whose scale differs from 1 by more than this, ECC refines an affine warp
    (else rotation + translation). ecc_iters,
    ecc_eps: ECC's iteration limit and convergence threshold. min_ecc: smallest ECC
    correlation accepted (in [0, 1]).
    """

    work_width: int = 352
    orb_features: int = 500
    min_inliers: int = 12
    ransac_px: float = 2.0
    max_scale: float = 1.6
    zoom: float = 0.05
    ecc_iters: int = 60
    ecc_eps: float = 1e-4
    min_ecc: float = 0.8

    def __post_init__(self) -> None:
        integer("work_width", self.work_width, low=16)
        integer("orb_features", self.orb_features, low=10)
        integer("min_inliers", self.min_inliers, low=3)
        real("ransac_px", self.ransac_px, positive=True)
        real("max_scale", self.max_scale, low=1.0)
        real("zoom", self.zoom, low=0.0)
        integer("ecc_iters", self.ecc_iters, low=1)
        real("ecc_eps", self.ecc_eps, positive=True)
        if not 0.0 <= real("min_ecc", self.min_ecc) <= 1.0:
            raise ValueError(f"min_ecc: expected a value in [0, 1], got {self.min_ecc}")


def _grey(image: np.ndarray, name: str) -> np.ndarray:
    check_image(name, image)
    if image.dtype != np.uint8 or image.ndim not in (2, 3):
        raise ValueError(
            f"{name}: expected (h, w) or (h, w, 3) uint8, got {image.shape} {image.dtype}"
        )
    if image.ndim == 3:
        if image.shape[2] != 3:
            raise ValueError(f"{name}: expected 3 channels (BGR), got {image.shape}")
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    return image


def _orb(ref: np.ndarray, mov: np.ndarray, cfg: RegisterConfig) -> np.ndarray | None:
    orb = cv2.ORB_create(nfeatures=cfg.orb_features)  # pyright: ignore[reportAttributeAccessIssue]
    k1, d1 = orb.detectAndCompute(ref, None)
    k2, d2 = orb.detectAndCompute(mov, None)
    if d1 is None or d2 is None or len(k1) < cfg.min_inliers or len(k2) < cfg.min_inliers:
        return None
    matches = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True).match(d2, d1)
    if len(matches) < cfg.min_inliers:
        return None
    src = np.array([k2[m.queryIdx].pt for m in matches], dtype=np.float32)
    dst = np.array([k1[m.trainIdx].pt for m in matches], dtype=np.float32)
    warp, inliers = cv2.estimateAffinePartial2D(
        src, dst, method=cv2.RANSAC, ransacReprojThreshold=cfg.ransac_px
    )
    if warp is None or inliers is None or int(inliers.sum()) < cfg.min_inliers:
        return None
    scale = float(np.hypot(warp[0, 0], warp[1, 0]))
    if not 1.0 / cfg.max_scale <= scale <= cfg.max_scale:
        return None
    return warp.astype(np.float32)


def _ecc(
    ref: np.ndarray, mov: np.ndarray, start: np.ndarray, motion: int, cfg: RegisterConfig
) -> tuple[np.ndarray, float] | None:
    """ECC refinement (OpenCV `motion` type) of the warp `start` (moving -> reference) and
    its correlation; None when ECC does not converge or correlates below `min_ecc`."""
    # ECC's warp maps template (reference) pixels to input (moving) pixels.
    init = cv2.invertAffineTransform(start).astype(np.float32)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, cfg.ecc_iters, cfg.ecc_eps)
    try:
        rho, warp = cv2.findTransformECC(ref, mov, init, motion, criteria, None, 5)  # pyright: ignore[reportCallIssue, reportArgumentType]
    except cv2.error:
        return None
    if not np.isfinite(rho) or rho < cfg.min_ecc or not np.all(np.isfinite(warp)):
        return None
    return cv2.invertAffineTransform(warp).astype(np.float32), float(rho)


def register(
    reference: np.ndarray, moving: np.ndarray, config: RegisterConfig | None = None
) -> tuple[np.ndarray, str]:
    """The warp (2, 3) float32 taking pixel (x, y) of `moving` to `reference` (input px; both
    uint8 BGR or grey of the same size) and how it was found, one of :data:`METHODS`
    (module doc). With "none" the warp is the identity and should not be trusted."""
    cfg = config or RegisterConfig()
    if not isinstance(cfg, RegisterConfig):
        raise TypeError(f"config: expected RegisterConfig, got {type(cfg).__name__}")
    ref, mov = _grey(reference, "reference"), _grey(moving, "moving")
    if ref.shape != mov.shape:
        raise ValueError(f"moving: size {mov.shape} differs from reference's {ref.shape}")
    h, w = ref.shape
    s = cfg.work_width / w if w > cfg.work_width else 1.0
    if s < 1.0:
        size = (round(w * s), max(1, round(h * s)))
        ref = cv2.resize(ref, size, interpolation=cv2.INTER_AREA)
        mov = cv2.resize(mov, size, interpolation=cv2.INTER_AREA)
    orb = _orb(ref, mov, cfg)
    best: tuple[np.ndarray, float, str] | None = None
    # from the identity: rotation + translation (a pan); from ORB's similarity: affine (a
    # pan with a zoom)
    starts = [("ecc", np.eye(2, 3, dtype=np.float32), cv2.MOTION_EUCLIDEAN)]
    if orb is not None:
        scale = float(np.hypot(orb[0, 0], orb[1, 0]))
        if abs(scale - 1.0) > cfg.zoom:
            starts.append(("orb", orb, cv2.MOTION_AFFINE))
        else:  # no zoom: the similarity's rotation and translation only
            rigid = orb.copy()
            rigid[:, :2] /= scale
            starts.append(("orb", rigid, cv2.MOTION_EUCLIDEAN))
    for name, start, motion in starts:
        found = _ecc(ref, mov, start, motion, cfg)
        if found is not None and (best is None or found[1] > best[1]):
            best = (found[0], found[1], name)
    if best is not None:
        warp, name = best[0], best[2]
    elif orb is not None:
        warp, name = orb, "orb-only"
    else:
        return np.eye(2, 3, dtype=np.float32), "none"
    warp = warp.copy()
    warp[:, 2] /= s  # working -> input px (the linear part is scale-free)
    return warp, name


def warp_to(
    image: np.ndarray, warp: np.ndarray, size: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """`image` warped by `warp` (2, 3; image px -> output px) onto an output of `size`
    (width, height), and the mask (h, w) bool of output pixels that came from inside it."""
    w = np.asarray(warp, dtype=np.float32)
    if w.shape != (2, 3) or not np.all(np.isfinite(w)):
        raise ValueError(f"warp: expected a finite (2, 3) affine matrix, got shape {w.shape}")
    out = cv2.warpAffine(image, w, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    inside = cv2.warpAffine(
        np.full(image.shape[:2], 255, np.uint8), w, size, flags=cv2.INTER_NEAREST, borderValue=0
    )
    return out, inside > 0
