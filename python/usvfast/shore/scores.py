"""Detection scores of Bloisi et al. (VTS camera surveillance, eqs. 4–5): per frame, the
detections are matched one-to-one to the annotated boxes by optimal assignment on IoU
(pairs with IoU ≥ 0.5 count); TPR = TP / (TP + FN), FAR = FP / (TP + FP)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from usvfast.shore.boxes import iou_matrix


@dataclass
class DetectionCounts:
    """True positives, false positives and false negatives summed over frames."""

    tp: int = 0
    fp: int = 0
    fn: int = 0

    def add(self, truth: np.ndarray, detected: np.ndarray, min_iou: float = 0.5) -> None:
        """Count one frame: truth (g, 4) and detected (d, 4) boxes, x, y, w, h px."""
        tp = matched_pairs(truth, detected, min_iou)
        self.tp += tp
        self.fn += len(truth) - tp
        self.fp += len(detected) - tp

    @property
    def tpr(self) -> float:
        """TP / (TP + FN) (eq. 4); NaN without any annotated box."""
        n = self.tp + self.fn
        return self.tp / n if n else float("nan")

    @property
    def far(self) -> float:
        """FP / (TP + FP) (eq. 5); 0 without any detection."""
        n = self.tp + self.fp
        return self.fp / n if n else 0.0


def assign_pairs(iou: np.ndarray, min_iou: float) -> list[tuple[int, int]]:
    """The one-to-one (row, col) pairs of an IoU matrix with IoU ≥ min_iou, by the assignment
    that maximises the number of such pairs (ties broken by IoU). Raises ValueError naming
    `iou` unless it is a finite 2-D array."""
    iou = np.asarray(iou, dtype=float)
    if iou.ndim != 2 or not np.all(np.isfinite(iou)):
        raise ValueError(f"iou: expected a finite 2-D array, got shape {iou.shape}")
    if iou.size == 0:
        return []
    ok = iou >= min_iou
    rows, cols = linear_sum_assignment(-(ok + 1e-3 * iou))
    return [(int(r), int(c)) for r, c in zip(rows, cols, strict=True) if ok[r, c]]


def matched_pairs(truth: np.ndarray, detected: np.ndarray, min_iou: float = 0.5) -> int:
    """How many one-to-one (truth, detection) pairs with IoU ≥ min_iou the assignment that
    maximises the number of such pairs finds."""
    return len(assign_pairs(iou_matrix(truth, detected), min_iou))
