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


def matched_pairs(truth: np.ndarray, detected: np.ndarray, min_iou: float = 0.5) -> int:
    """How many one-to-one (truth, detection) pairs with IoU ≥ min_iou the assignment that
    maximises the number of such pairs finds."""
    iou = iou_matrix(truth, detected)
    if iou.size == 0:
        return 0
    ok = iou >= min_iou
    # maximise the number of valid pairs (ties broken by IoU)
    rows, cols = linear_sum_assignment(-(ok + 1e-3 * iou))
    return int(ok[rows, cols].sum())
