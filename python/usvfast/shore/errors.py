"""Where a box detector's errors are: the false positives and false negatives of Bloisi et
al.'s scores (eqs. 4–5, one-to-one matching at IoU ≥ 0.5, :mod:`usvfast.shore.scores`) split
by cause, per frame and summed.

After the IoU ≥ 0.5 matching, the unmatched detections and unmatched annotated boxes are
matched again one-to-one at IoU ≥ `loc_iou` (0.1): each such pair is a **mislocalised** box
(the detector found the boat but drew the box badly; it counts as one FP and one FN). Of the
detections left, those overlapping (IoU ≥ `loc_iou`) an annotated box already claimed by
another detection are **duplicates**, the rest are **pure false** alarms. Of the annotated
boxes left, those overlapping a detection claimed by another box are **covered** (typically
two boats inside one merged box), the rest are **missed** (no detection near them).
Boxes x, y, w, h pixels.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from usvfast.shore.boxes import iou_matrix
from usvfast.shore.scores import assign_pairs


@dataclass
class ErrorBreakdown:
    """Counts summed over frames (module doc). `fp = fp_mislocalised + fp_duplicate +
    fp_false`, `fn = fn_mislocalised + fn_covered + fn_missed`, `fp_mislocalised ==
    fn_mislocalised`. `area_ratios`: detection area / annotated area of each mislocalised
    pair; `ious`: their IoU."""

    tp: int = 0
    fp_mislocalised: int = 0
    fp_duplicate: int = 0
    fp_false: int = 0
    fn_mislocalised: int = 0
    fn_covered: int = 0
    fn_missed: int = 0
    area_ratios: list[float] = field(default_factory=list)
    ious: list[float] = field(default_factory=list)

    @property
    def fp(self) -> int:
        """All false positives."""
        return self.fp_mislocalised + self.fp_duplicate + self.fp_false

    @property
    def fn(self) -> int:
        """All false negatives."""
        return self.fn_mislocalised + self.fn_covered + self.fn_missed

    def add(
        self,
        truth: np.ndarray,
        detected: np.ndarray,
        min_iou: float = 0.5,
        loc_iou: float = 0.1,
    ) -> None:
        """Count one frame: annotated boxes `truth` (g, 4), detections `detected` (d, 4)."""
        if not 0.0 < loc_iou < min_iou <= 1.0:
            raise ValueError(f"loc_iou: expected 0 < loc_iou < min_iou <= 1, got {loc_iou}")
        t = np.asarray(truth, dtype=float).reshape(-1, 4)
        d = np.asarray(detected, dtype=float).reshape(-1, 4)
        iou = iou_matrix(t, d)
        matched = assign_pairs(iou, min_iou)
        self.tp += len(matched)
        t_left = sorted(set(range(len(t))) - {r for r, _ in matched})
        d_left = sorted(set(range(len(d))) - {c for _, c in matched})
        sub = iou[np.ix_(t_left, d_left)] if t_left and d_left else np.zeros((0, 0))
        loc = [(t_left[r], d_left[c]) for r, c in assign_pairs(sub, loc_iou)]
        for r, c in loc:
            self.area_ratios.append(float(d[c, 2] * d[c, 3] / max(t[r, 2] * t[r, 3], 1e-9)))
            self.ious.append(float(iou[r, c]))
        self.fp_mislocalised += len(loc)
        self.fn_mislocalised += len(loc)
        t_loc, d_loc = {r for r, _ in loc}, {c for _, c in loc}
        t_rest = [r for r in t_left if r not in t_loc]
        d_rest = [c for c in d_left if c not in d_loc]
        for c in d_rest:
            if len(t) and iou[:, c].max() >= loc_iou:
                self.fp_duplicate += 1
            else:
                self.fp_false += 1
        for r in t_rest:
            if len(d) and iou[r].max() >= loc_iou:
                self.fn_covered += 1
            else:
                self.fn_missed += 1

    def summary(self) -> dict:
        """The counts (and the median area ratio and IoU of the mislocalised pairs; NaN
        without any) as a JSON-ready dict."""
        out = {
            f.name: getattr(self, f.name)
            for f in fields(self)
            if f.name not in ("area_ratios", "ious")
        }
        out["fp"] = self.fp
        out["fn"] = self.fn
        out["mislocalised_area_ratio"] = (
            float(np.median(self.area_ratios)) if self.area_ratios else float("nan")
        )
        out["mislocalised_iou"] = float(np.median(self.ious)) if self.ious else float("nan")
        return out
