"""Multi-target CLEAR MOT (Bernardin & Stiefelhagen 2008) and the ID measures (Ristani et al.
2016) over a `FrameSequence`, with py-motmetrics' matching rules so the figures are the same:

1. a truth object matched at an earlier frame keeps its last track if that track is present and
   within the gate;
2. the remaining objects and tracks are matched by an optimal assignment that first maximises
   the number of gated pairs and then minimises their total distance;
3. a match whose truth object was last matched to another track is an ID switch;
4. unmatched truth objects are misses, unmatched tracks false positives.

MOTA = 1 − (misses + false positives + switches) / truth objects; MOTP = mean distance of the
matches (metres, or 1 − IoU for boxes; `motp_iou` gives the mean box IoU); precision =
matched / (matched + FP); recall = matched / truth. IDF1 = 2 IDTP / (truth + tracks) with IDTP
the largest number of gated (truth, track) co-occurrences under a one-to-one map of truth ids to
track ids. `mota_log10` is MOTA with the switch cost log10(switches) instead of switches
(Bernardin & Stiefelhagen's c_s = log10, used by Bloisi et al.'s VTS evaluation, eq. 6).

Example::

    seq = FrameSequence.from_boxes(gf, gi, gbox, tf, ti, tbox, iou_threshold=0.5)
    m = mot_metrics(seq)
    m.mota, m.motp_iou, m.idf1, m.switches
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from usvfast.metrics.frames import FrameSequence


@dataclass(frozen=True)
class MotMetrics:
    """CLEAR MOT and ID figures of a run (module doc). Counts are summed over frames;
    mostly_tracked / partially_tracked / mostly_lost count truth ids matched in ≥ 80 %, 20–80 %,
    < 20 % of their frames. motp is in the sequence's distance unit (metres or 1 − IoU);
    motp_iou is the mean IoU of the matches (NaN for positions)."""

    mota: float
    mota_log10: float
    motp: float
    motp_iou: float
    precision: float
    recall: float
    idf1: float
    idp: float
    idr: float
    matches: int
    switches: int
    misses: int
    false_positives: int
    n_truth: int
    n_tracks: int
    idtp: int
    idfn: int
    idfp: int
    n_truth_ids: int
    n_track_ids: int
    mostly_tracked: int
    partially_tracked: int
    mostly_lost: int

    def as_dict(self) -> dict[str, float | int]:
        """The figures as a JSON-ready dict."""
        return {k: (float(v) if isinstance(v, float) else int(v)) for k, v in asdict(self).items()}


def _gated_assignment(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the assignment with the most finite entries, then least total cost;
    NaN/inf entries may not be chosen."""
    valid = np.isfinite(cost)
    if not valid.any():
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    # A forbidden pair costs more than any assignment of one fewer allowed pairs can save.
    big = 2 * min(cost.shape) * (np.abs(cost[valid]).max() + 1) + 1
    r, c = linear_sum_assignment(np.where(valid, cost, big))
    keep = valid[r, c]
    return r[keep], c[keep]


def _div(a: float, b: float) -> float:
    return float(a) / float(b) if b else float("nan")


def mot_metrics(seq: FrameSequence) -> MotMetrics:
    """CLEAR MOT, precision, recall and the ID measures of `seq` (module doc). Raises TypeError
    when `seq` is not a FrameSequence."""
    if not isinstance(seq, FrameSequence):
        raise TypeError(f"seq: expected a FrameSequence, got {type(seq).__name__}")
    # Dense ids so the per-frame bookkeeping is array indexing.
    all_g = np.unique(np.concatenate([np.zeros(0, np.int64), *seq.truth_ids]))
    all_t = np.unique(np.concatenate([np.zeros(0, np.int64), *seq.track_ids]))
    n_g, n_t = len(all_g), len(all_t)
    last = np.full(n_g, -1, np.int64)  # truth id -> its last matched track (dense)
    col_of = np.full(n_t, -1, np.int64)  # track (dense) -> column in the current frame
    present = np.zeros(n_g, np.int64)
    tracked = np.zeros(n_g, np.int64)
    co = np.zeros((n_g, n_t), np.int64)  # gated co-occurrences, for IDF1
    matches = switches = misses = fps = 0
    dist_sum = 0.0
    iou_sum = 0.0
    for gids, tids, dist in zip(seq.truth_ids, seq.track_ids, seq.distance, strict=True):
        g = np.searchsorted(all_g, gids)
        t = np.searchsorted(all_t, tids)
        present[g] += 1
        gate = np.isfinite(dist)
        gi, ti = np.nonzero(gate)
        co[g[gi], t[ti]] += 1
        if len(g) == 0 or len(t) == 0:
            misses += len(g)
            fps += len(t)
            continue
        col_of[t] = np.arange(len(t))
        # 1. keep established pairs that are still gated
        prev = last[g]
        cols = np.where(prev >= 0, col_of[np.maximum(prev, 0)], -1)
        # a previous track not in this frame has a stale col_of entry: check its id
        cols = np.where((cols >= 0) & (t[np.maximum(cols, 0)] == prev), cols, -1)
        keep = cols >= 0
        keep[keep] = gate[np.flatnonzero(keep), cols[keep]]
        rows_k, cols_k = np.flatnonzero(keep), cols[keep]
        # two objects whose last track is the same: the first in frame order keeps it
        _, first = np.unique(cols_k, return_index=True)
        first.sort()
        rows_k, cols_k = rows_k[first], cols_k[first]
        # 2. optimal assignment of the rest
        free = dist.copy()
        free[rows_k, :] = np.nan
        free[:, cols_k] = np.nan
        rows_a, cols_a = _gated_assignment(free)
        was = last[g[rows_a]]
        sw = (was >= 0) & (was != t[cols_a])
        switches += int(sw.sum())
        matches += len(rows_k) + int((~sw).sum())
        rows = np.concatenate([rows_k, rows_a])
        cols = np.concatenate([cols_k, cols_a])
        last[g[rows]] = t[cols]
        tracked[g[rows]] += 1
        dist_sum += float(dist[rows, cols].sum())
        if seq.kind == "box":
            iou_sum += float((1.0 - dist[rows, cols]).sum())
        misses += len(g) - len(rows)
        fps += len(t) - len(rows)
        col_of[t] = -1
    n_truth, n_tracks = seq.n_truth, seq.n_tracks
    detected = matches + switches
    # IDF1: one-to-one map of truth ids to track ids with the most co-occurrences.
    if co.size:
        r, c = linear_sum_assignment(-co)
        idtp = int(co[r, c].sum())
    else:
        idtp = 0
    ratio = np.divide(tracked, present, out=np.zeros(n_g), where=present > 0)
    mota_base = misses + fps
    return MotMetrics(
        mota=1.0 - _div(mota_base + switches, n_truth),
        mota_log10=1.0 - _div(mota_base + (np.log10(switches) if switches else 0.0), n_truth),
        motp=_div(dist_sum, detected),
        motp_iou=_div(iou_sum, detected) if seq.kind == "box" else float("nan"),
        precision=_div(detected, detected + fps),
        recall=_div(detected, n_truth),
        idf1=_div(2 * idtp, n_truth + n_tracks),
        idp=_div(idtp, n_tracks),
        idr=_div(idtp, n_truth),
        matches=matches,
        switches=switches,
        misses=misses,
        false_positives=fps,
        n_truth=n_truth,
        n_tracks=n_tracks,
        idtp=idtp,
        idfn=n_truth - idtp,
        idfp=n_tracks - idtp,
        n_truth_ids=n_g,
        n_track_ids=n_t,
        mostly_tracked=int(np.count_nonzero(ratio >= 0.8)),
        partially_tracked=int(np.count_nonzero((ratio >= 0.2) & (ratio < 0.8))),
        mostly_lost=int(np.count_nonzero(ratio < 0.2)),
    )
