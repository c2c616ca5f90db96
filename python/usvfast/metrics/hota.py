"""HOTA, Higher Order Tracking Accuracy (Luiten et al., IJCV 2021, eqs. 1–11), over a
`FrameSequence`, computed as TrackEval does so the figures are the same.

For each localisation threshold α in 0.05, 0.10, …, 0.95:
DetA_α = |TP| / (|TP| + |FN| + |FP|), AssA_α = (1/|TP|) Σ_c A(c) with
A(c) = |TPA(c)| / (|TPA(c)| + |FNA(c)| + |FPA(c)|), HOTA_α = √(DetA_α · AssA_α); matches per
frame maximise the similarity weighted by the pair's global alignment score. The reported
HOTA, DetA, AssA, LocA, … are the means over α. Similarity: the sequence's (IoU for boxes,
max(0, 1 − d / zero_distance) for positions).

Example::

    h = hota_metrics(FrameSequence.from_boxes(gf, gi, gbox, tf, ti, tbox))
    h.hota, h.deta, h.assa
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from usvfast.metrics.frames import FrameSequence

#: The localisation thresholds α of HOTA.
ALPHAS = np.arange(0.05, 0.99, 0.05)
_EPS = np.finfo(float).eps


@dataclass(frozen=True)
class HotaMetrics:
    """HOTA figures (module doc): the scalars are means over `alphas`; the `*_alpha` arrays hold
    the value per α. hota_0 / loca_0: HOTA and LocA at the smallest α."""

    hota: float
    deta: float
    assa: float
    detre: float
    detpr: float
    assre: float
    asspr: float
    loca: float
    owta: float
    hota_0: float
    loca_0: float
    alphas: np.ndarray
    hota_alpha: np.ndarray
    deta_alpha: np.ndarray
    assa_alpha: np.ndarray
    tp_alpha: np.ndarray
    fn_alpha: np.ndarray
    fp_alpha: np.ndarray

    def as_dict(self) -> dict[str, float]:
        """The scalar figures as a JSON-ready dict."""
        names = ("hota", "deta", "assa", "detre", "detpr", "assre", "asspr", "loca", "owta")
        return {n: float(getattr(self, n)) for n in (*names, "hota_0", "loca_0")}


def _final(tp, fn, fp, assa, assre, asspr, loca) -> HotaMetrics:
    detre = tp / np.maximum(1, tp + fn)
    detpr = tp / np.maximum(1, tp + fp)
    deta = tp / np.maximum(1, tp + fn + fp)
    hota = np.sqrt(deta * assa)
    owta = np.sqrt(detre * assa)
    return HotaMetrics(
        hota=float(hota.mean()),
        deta=float(deta.mean()),
        assa=float(assa.mean()),
        detre=float(detre.mean()),
        detpr=float(detpr.mean()),
        assre=float(assre.mean()),
        asspr=float(asspr.mean()),
        loca=float(loca.mean()),
        owta=float(owta.mean()),
        hota_0=float(hota[0]),
        loca_0=float(loca[0]),
        alphas=ALPHAS.copy(),
        hota_alpha=hota,
        deta_alpha=deta,
        assa_alpha=assa,
        tp_alpha=tp,
        fn_alpha=fn,
        fp_alpha=fp,
    )


def hota_metrics(seq: FrameSequence) -> HotaMetrics:
    """HOTA and its parts for `seq` (module doc). Raises TypeError when `seq` is not a
    FrameSequence."""
    if not isinstance(seq, FrameSequence):
        raise TypeError(f"seq: expected a FrameSequence, got {type(seq).__name__}")
    na = len(ALPHAS)
    zeros = np.zeros(na)
    n_truth, n_tracks = seq.n_truth, seq.n_tracks
    if n_tracks == 0 or n_truth == 0:
        fn = np.full(na, float(n_truth)) if n_tracks == 0 else zeros
        fp = np.full(na, float(n_tracks)) if n_tracks else zeros
        return _final(zeros, fn, fp, zeros, zeros, zeros, np.ones(na))
    all_g = np.unique(np.concatenate(seq.truth_ids))
    all_t = np.unique(np.concatenate(seq.track_ids))
    g_idx = [np.searchsorted(all_g, g) for g in seq.truth_ids]
    t_idx = [np.searchsorted(all_t, t) for t in seq.track_ids]
    # Global alignment: similarity-weighted potential matches of every id pair (eq. 9 of the
    # paper's "A(c)" estimated before matching).
    potential = np.zeros((len(all_g), len(all_t)))
    g_count = np.zeros((len(all_g), 1))
    t_count = np.zeros((1, len(all_t)))
    for g, t, s in zip(g_idx, t_idx, seq.similarity, strict=True):
        denom = s.sum(0)[None, :] + s.sum(1)[:, None] - s
        jac = np.divide(s, denom, out=np.zeros_like(s), where=denom > _EPS)
        potential[np.ix_(g, t)] += jac
        g_count[g] += 1
        t_count[0, t] += 1
    alignment = potential / (g_count + t_count - potential)
    tp = np.zeros(na)
    fn = np.zeros(na)
    fp = np.zeros(na)
    loc = np.zeros(na)
    counts = np.zeros((na, len(all_g), len(all_t)))
    for g, t, s in zip(g_idx, t_idx, seq.similarity, strict=True):
        if len(g) == 0 or len(t) == 0:
            fn += len(g)
            fp += len(t)
            continue
        r, c = linear_sum_assignment(-(alignment[np.ix_(g, t)] * s))
        sim = s[r, c]
        ok = sim[None, :] >= ALPHAS[:, None] - _EPS  # (na, n_match)
        k = ok.sum(1)
        tp += k
        fn += len(g) - k
        fp += len(t) - k
        loc += (ok * sim[None, :]).sum(1)
        a_i, m_i = np.nonzero(ok)
        np.add.at(counts, (a_i, g[r[m_i]], t[c[m_i]]), 1.0)
    tp_div = np.maximum(1, tp)
    ass_a = counts / np.maximum(1, (g_count + t_count)[None] - counts)
    assa = (counts * ass_a).sum((1, 2)) / tp_div
    assre = (counts * (counts / np.maximum(1, g_count)[None])).sum((1, 2)) / tp_div
    asspr = (counts * (counts / np.maximum(1, t_count)[None])).sum((1, 2)) / tp_div
    loca = np.maximum(1e-10, loc) / np.maximum(1e-10, tp)
    return _final(tp, fn, fp, assa, assre, asspr, loca)
