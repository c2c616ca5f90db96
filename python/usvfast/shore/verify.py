"""A second-stage box verifier for shore-camera boat detectors: every detector's candidate
boxes, each also re-fitted to the boat by the frame's own contrast, are pooled and rescored by
a boosted regressor of the box's IoU with a boat, then non-maximum suppression across
detectors keeps the best-fitting box of each boat.

Proposals come from the CNN (:mod:`usvfast.shore.cnn`, a low confidence floor) and the
training-free contrast detector (:mod:`usvfast.shore.contrast`). **Box refinement**: the
robust contrast map of :func:`usvfast.shore.contrast.contrast_map` is thresholded inside the
candidate enlarged by `grow` on every side; the connected components (after a closing) that
touch the candidate's central half give the re-fitted box (their union's extent). Candidates
whose refit moves little are not duplicated.

**Features** of a box (:func:`box_features`, all scale-free): which detector proposed it and
whether it is a refit; the CNN's best confidence among its boxes overlapping it (IoU ≥ 0.5)
and that confidence over the frame's best; the contrast share and mean contrast inside the
box, in a ring around it and in thin strips just inside and just outside each of its four
edges (a tight box has contrast inside its edges and none outside); edge density (Canny)
inside and in the ring; grey mean and spread inside and in the ring; size and aspect; its top
and bottom against the horizon line (and the line's kind); its overlap with the contrast
detector's best box.

The regressor (scikit-learn's `HistGradientBoostingRegressor`, squared error, seeded) learns
each candidate's largest IoU with an annotated box; videos weigh equally. Pixels: origin
top-left, x right, y down; boxes x, y, w, h of the input frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from usvfast._validate import as_float_array, real
from usvfast.shore.boxes import Detections, clip_boxes, iou_matrix
from usvfast.shore.contrast import ContrastConfig, ContrastDetector, contrast_map
from usvfast.shore.horizon import HorizonLine

#: Proposal sources, in the order of the features' one-hot columns.
SOURCES: tuple[str, ...] = ("cnn", "contrast")


@dataclass(frozen=True)
class Candidates:
    """One frame's pooled candidate boxes: `boxes` (k, 4) x, y, w, h px, `source` (k,) index
    into :data:`SOURCES`, `refit` (k,) bool, `features` (k, f) from :func:`box_features`."""

    boxes: np.ndarray
    source: np.ndarray
    refit: np.ndarray
    features: np.ndarray


def _strip_share(ii: np.ndarray, x0, y0, x1, y1) -> np.ndarray:
    """Mean of the 0/1 map behind integral image `ii` over boxes [x0, x1) × [y0, y1)
    (integer working px, clipped); 0 for an empty box."""
    h, w = ii.shape[0] - 1, ii.shape[1] - 1
    x0, x1 = np.clip(x0, 0, w), np.clip(x1, 0, w)
    y0, y1 = np.clip(y0, 0, h), np.clip(y1, 0, h)
    area = (x1 - x0) * (y1 - y0)
    s = ii[y1, x1] - ii[y0, x1] - ii[y1, x0] + ii[y0, x0]
    return np.where(area > 0, s / np.maximum(area, 1), 0.0)


def _integral(a: np.ndarray) -> np.ndarray:
    """OpenCV's integral image of `a` (h, w) -> (h + 1, w + 1) float64, first row/column 0."""
    return cv2.integral(np.ascontiguousarray(a, dtype=np.float64), sdepth=cv2.CV_64F)


def refit_boxes(
    z: np.ndarray, scale: float, boxes: np.ndarray, threshold: float, grow: float = 0.5
) -> np.ndarray:
    """Boxes (k, 4) x, y, w, h input px re-fitted to the contrast map `z` (working px,
    `scale` working / input px) above `threshold`: the extent of the contrasting components
    inside each box enlarged by `grow` × its size per side that touch its central half (the
    box itself when none does)."""
    b = as_float_array("boxes", boxes).reshape(-1, 4)
    real("grow", grow)
    out = b.copy()
    h, w = z.shape
    for i, (x, y, bw, bh) in enumerate(b * scale):
        x0, y0 = max(int(x - grow * bw), 0), max(int(y - grow * bh), 0)
        x1, y1 = (
            min(int(np.ceil(x + bw * (1 + grow))), w),
            min(int(np.ceil(y + bh * (1 + grow))), h),
        )
        if x1 - x0 < 2 or y1 - y0 < 2:
            continue
        m = (z[y0:y1, x0:x1] > threshold).astype(np.uint8)
        # odd kernel sizes: an even one shifts the closed mask by a pixel
        k = (2 * round(bw * 0.075) + 1, 2 * round(bh * 0.075) + 1)
        m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_RECT, k))
        n, labels, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
        if n <= 1:
            continue
        cx0, cy0 = int(x + bw / 4) - x0, int(y + bh / 4) - y0
        cx1, cy1 = int(np.ceil(x + 3 * bw / 4)) - x0, int(np.ceil(y + 3 * bh / 4)) - y0
        core = labels[max(cy0, 0) : max(cy1, cy0 + 1), max(cx0, 0) : max(cx1, cx0 + 1)]
        ids = np.unique(core[core > 0]).astype(np.intp)
        if len(ids) == 0:
            continue
        st = np.asarray(stats)[ids]
        ex0, ey0 = st[:, 0].min(), st[:, 1].min()
        ex1, ey1 = (st[:, 0] + st[:, 2]).max(), (st[:, 1] + st[:, 3]).max()
        out[i] = np.array([x0 + ex0, y0 + ey0, ex1 - ex0, ey1 - ey0], float) / scale
    return out


def box_features(
    image: np.ndarray,
    horizon: HorizonLine | None,
    z: np.ndarray,
    scale: float,
    boxes: np.ndarray,
    source: np.ndarray,
    refit: np.ndarray,
    cnn: Detections,
    contrast: Detections,
    threshold: float,
) -> np.ndarray:
    """Feature matrix (k, f) of candidate `boxes` (k, 4) of one frame (module doc)."""
    b = np.asarray(boxes, float).reshape(-1, 4)
    k = len(b)
    H, W = image.shape[:2]
    if k == 0:
        return np.zeros((0, n_features()))
    cols: list[np.ndarray] = [source == i for i, _ in enumerate(SOURCES)]
    cols.append(refit.astype(float))
    iou_c = iou_matrix(b, cnn.boxes)
    conf = np.where(iou_c >= 0.5, cnn.scores[None], 0.0).max(axis=1) if len(cnn) else np.zeros(k)
    best = cnn.scores.max() if len(cnn) else 1.0
    cols += [conf, conf / max(best, 1e-6), iou_c.max(axis=1) if len(cnn) else np.zeros(k)]
    iou_k = iou_matrix(b, contrast.boxes)
    cols.append(iou_k.max(axis=1) if len(contrast) else np.zeros(k))
    # contrast inside, in a ring and in thin strips at each edge (working px)
    zz = z > threshold
    ii, iz = _integral(zz.astype(float)), _integral(np.minimum(z, 4 * threshold) / (4 * threshold))
    s = b * scale
    x0, y0 = np.floor(s[:, 0]).astype(int), np.floor(s[:, 1]).astype(int)
    x1 = np.ceil(s[:, 0] + s[:, 2]).astype(int)
    y1 = np.ceil(s[:, 1] + s[:, 3]).astype(int)
    dw = np.maximum(np.round(s[:, 2] * 0.15), 1).astype(int)
    dh = np.maximum(np.round(s[:, 3] * 0.15), 1).astype(int)
    rw = np.maximum(np.round(s[:, 2] * 0.5), 2).astype(int)
    rh = np.maximum(np.round(s[:, 3] * 0.5), 2).astype(int)

    def ring(m: np.ndarray) -> np.ndarray:
        outer = _strip_share(m, x0 - rw, y0 - rh, x1 + rw, y1 + rh)
        ao = (np.clip(x1 + rw, 0, z.shape[1]) - np.clip(x0 - rw, 0, z.shape[1])) * (
            np.clip(y1 + rh, 0, z.shape[0]) - np.clip(y0 - rh, 0, z.shape[0])
        )
        inner = _strip_share(m, x0, y0, x1, y1)
        ai = (np.clip(x1, 0, z.shape[1]) - np.clip(x0, 0, z.shape[1])) * (
            np.clip(y1, 0, z.shape[0]) - np.clip(y0, 0, z.shape[0])
        )
        return np.where(ao > ai, (outer * ao - inner * ai) / np.maximum(ao - ai, 1), 0.0)

    inside = _strip_share(ii, x0, y0, x1, y1)
    around = ring(ii)
    cols += [inside, _strip_share(iz, x0, y0, x1, y1), around, ring(iz), inside - around]
    for a0, b0, a1, b1, c0, d0, c1, d1 in (
        (x0, y0, x0 + dw, y1, x0 - dw, y0, x0, y1),  # left: inside, outside
        (x1 - dw, y0, x1, y1, x1, y0, x1 + dw, y1),  # right
        (x0, y0, x1, y0 + dh, x0, y0 - dh, x1, y0),  # top
        (x0, y1 - dh, x1, y1, x0, y1, x1, y1 + dh),  # bottom
    ):
        si, so = _strip_share(ii, a0, b0, a1, b1), _strip_share(ii, c0, d0, c1, d1)
        cols += [si, so, si - so]
    # edges and grey level at the input size
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    edges = (cv2.Canny(grey, 60, 150) > 0).astype(float)
    ie = _integral(edges)
    g = grey.astype(float) / 255.0
    ig, ig2 = _integral(g), _integral(g * g)
    f0, g0 = np.floor(b[:, 0]).astype(int), np.floor(b[:, 1]).astype(int)
    f1 = np.ceil(b[:, 0] + b[:, 2]).astype(int)
    g1 = np.ceil(b[:, 1] + b[:, 3]).astype(int)
    pw, ph = np.maximum((b[:, 2] * 0.5).astype(int), 2), np.maximum((b[:, 3] * 0.5).astype(int), 2)
    e_in = _strip_share(ie, f0, g0, f1, g1)
    e_out = _strip_share(ie, f0 - pw, g0 - ph, f1 + pw, g1 + ph)
    m_in, m2_in = _strip_share(ig, f0, g0, f1, g1), _strip_share(ig2, f0, g0, f1, g1)
    m_out = _strip_share(ig, f0 - pw, g0 - ph, f1 + pw, g1 + ph)
    m2_out = _strip_share(ig2, f0 - pw, g0 - ph, f1 + pw, g1 + ph)
    sd_in = np.sqrt(np.maximum(m2_in - m_in**2, 0))
    sd_out = np.sqrt(np.maximum(m2_out - m_out**2, 0))
    cols += [e_in, e_out, e_in - e_out, m_in, sd_in, m_in - m_out, sd_in - sd_out]
    # geometry and the horizon
    cols += [
        b[:, 2] / W,
        b[:, 3] / H,
        np.log(np.maximum(b[:, 2], 1) / np.maximum(b[:, 3], 1)),
        (b[:, 0] + b[:, 2] / 2) / W,
        ((b[:, 0] <= 1) | (b[:, 0] + b[:, 2] >= W - 1)).astype(float),
    ]
    if horizon is None:
        ly = np.zeros(k)
        kind = np.full(k, -1.0)
    else:
        ly = horizon.y_at(b[:, 0] + b[:, 2] / 2)
        kind = np.full(k, 1.0 if horizon.kind == "water-sky" else 0.0)
    cols += [(b[:, 1] - ly) / H, (b[:, 1] + b[:, 3] - ly) / H, kind, np.full(k, len(b))]
    return np.column_stack([np.asarray(c, float) for c in cols])


def n_features() -> int:
    """Number of columns :func:`box_features` returns."""
    return len(SOURCES) + 1 + 3 + 1 + 5 + 12 + 7 + 5 + 4


def _dedupe(boxes: np.ndarray, same: float) -> np.ndarray:
    """Indices of `boxes` kept when later boxes with IoU > `same` to a kept one are dropped."""
    keep: list[int] = []
    iou = iou_matrix(boxes, boxes)
    for i in range(len(boxes)):
        if all(iou[i, j] <= same for j in keep):
            keep.append(i)
    return np.array(keep, dtype=int)


def candidates(
    image: np.ndarray,
    horizon: HorizonLine | None,
    cnn: Detections | None,
    config: ContrastConfig | None = None,
    refine: bool = True,
    same: float = 0.9,
) -> Candidates:
    """One frame's pooled candidates (module doc): the CNN's boxes `cnn` (None: the CNN is
    not used), the contrast detector's, each re-fitted when `refine`; near-copies (IoU >
    `same`) dropped."""
    cfg = config or ContrastConfig()
    H, W = image.shape[:2]
    z, _, s = contrast_map(image, horizon, cfg)
    cd = ContrastDetector(cfg).detect(image, horizon)
    cn = cnn if cnn is not None else Detections()
    parts = [(cn.boxes, 0), (cd.boxes, 1)]
    boxes, source, refit = [], [], []
    for bx, src in parts:
        if len(bx) == 0:
            continue
        boxes.append(bx)
        source.append(np.full(len(bx), src))
        refit.append(np.zeros(len(bx), bool))
        if refine:
            boxes.append(refit_boxes(z, s, bx, cfg.threshold))
            source.append(np.full(len(bx), src))
            refit.append(np.ones(len(bx), bool))
    if not boxes:
        return Candidates(
            np.zeros((0, 4)), np.zeros(0, int), np.zeros(0, bool), np.zeros((0, n_features()))
        )
    b = clip_boxes(np.concatenate(boxes), W, H)
    src, rf = np.concatenate(source), np.concatenate(refit)
    ok = (b[:, 2] >= 2) & (b[:, 3] >= 2)
    b, src, rf = b[ok], src[ok], rf[ok]
    keep = _dedupe(b, same)
    b, src, rf = b[keep], src[keep], rf[keep]
    f = box_features(image, horizon, z, s, b, src, rf, cn, cd, cfg.threshold)
    return Candidates(b, src, rf, f)


def best_iou(truth: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Each box's largest IoU with an annotated box (0 when the frame has none)."""
    iou = iou_matrix(truth, boxes)
    return iou.max(axis=0) if iou.shape[0] else np.zeros(len(np.asarray(boxes).reshape(-1, 4)))


class BoxVerifier:
    """The boosted regressor of a candidate's IoU with a boat (module doc). `fit(features,
    targets, groups)`: rows of :func:`box_features`, their best IoU, and each row's video
    (videos weigh equally). `predict(features)` -> (k,) scores in [0, 1]."""

    def __init__(self, seed: int = 0, max_iter: int = 200) -> None:
        from sklearn.ensemble import HistGradientBoostingRegressor

        self.model = HistGradientBoostingRegressor(
            max_iter=max_iter,
            learning_rate=0.05,
            max_leaf_nodes=15,
            min_samples_leaf=10,
            l2_regularization=1.0,
            random_state=seed,
        )

    def fit(self, features: np.ndarray, targets: np.ndarray, groups: Sequence[str]) -> BoxVerifier:
        """Fit on rows `features` (n, f), targets (n,) in [0, 1], `groups` (n,) video names."""
        g = np.asarray(groups)
        weight = np.zeros(len(g))
        for v in np.unique(g):
            weight[g == v] = 1.0 / np.sum(g == v)
        self.model.fit(features, targets, sample_weight=weight * len(g))
        return self

    def predict(self, features: np.ndarray) -> np.ndarray:
        """Predicted IoU (k,) of rows `features` (k, f), clipped to [0, 1]."""
        if len(features) == 0:
            return np.zeros(0)
        return np.clip(self.model.predict(features), 0.0, 1.0)


def select(
    boxes: np.ndarray, scores: np.ndarray, threshold: float, relative: float, nms: float
) -> np.ndarray:
    """Indices of one frame's boxes kept: score ≥ `threshold` and ≥ `relative` × the frame's
    best, then greedy non-maximum suppression at IoU > `nms` (best score first)."""
    s = np.asarray(scores, float)
    if len(s) == 0:
        return np.zeros(0, dtype=int)
    ok = np.flatnonzero((s >= threshold) & (s >= relative * s.max()))
    order = ok[np.argsort(-s[ok], kind="stable")]
    iou = iou_matrix(boxes, boxes)
    keep: list[int] = []
    for i in order:
        if all(iou[i, j] <= nms for j in keep):
            keep.append(int(i))
    return np.array(keep, dtype=int)
