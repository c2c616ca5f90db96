"""GOSPA (Rahmathullah, García-Fernández & Svensson 2017, α = 2) and OSPA (Schuhmacher, Vo &
Vo 2008) per frame between the track and truth point sets of a `FrameSequence`.

With cut-off c (metres) and order p, d_c = min(d, c):

- GOSPA = (min over assignments of Σ d_c^p + c^p/2 · (missed + false))^(1/p); its parts
  `localisation` (Σ d^p of assigned pairs closer than c), `missed` and `false`
  (c^p/2 per unassigned truth or track), as Stone Soup's GOSPAMetric reports them.
- OSPA = ((1/n)(min Σ d_c^p + c^p |n − m|))^(1/p), n = max(|X|, |Y|), 0 when both are empty.

Example::

    g = gospa_metrics(seq, cutoff=5.0, order=2)
    g.mean_distance, g.distance  # (F,) per frame
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from usvfast.metrics.frames import FrameSequence


@dataclass(frozen=True)
class Gospa:
    """Per-frame GOSPA (F,) arrays at `frames`: distance, localisation, missed, false (all in
    metres^p except distance, metres); OSPA distance (F,) metres; means over frames."""

    frames: np.ndarray
    distance: np.ndarray
    localisation: np.ndarray
    missed: np.ndarray
    false: np.ndarray
    ospa: np.ndarray
    mean_distance: float
    mean_ospa: float

    def as_dict(self) -> dict[str, float]:
        """Means over frames as a JSON-ready dict."""
        return {
            "gospa": self.mean_distance,
            "gospa_localisation": float(self.localisation.mean()) if len(self.frames) else 0.0,
            "gospa_missed": float(self.missed.mean()) if len(self.frames) else 0.0,
            "gospa_false": float(self.false.mean()) if len(self.frames) else 0.0,
            "ospa": self.mean_ospa,
        }


def gospa_metrics(seq: FrameSequence, *, cutoff: float, order: float = 2.0) -> Gospa:
    """GOSPA (α = 2) and OSPA of every frame of `seq` (module doc). cutoff: c, metres (> 0);
    order: p ≥ 1. The points are the sequence's values (positions; box sequences use the
    boxes' (x, y, w, h) as 4-vectors, rarely what you want). Raises ValueError on a bad
    cutoff/order, TypeError when `seq` is not a FrameSequence."""
    if not isinstance(seq, FrameSequence):
        raise TypeError(f"seq: expected a FrameSequence, got {type(seq).__name__}")
    if not cutoff > 0:
        raise ValueError(f"cutoff: must be positive, got {cutoff}")
    if not (order >= 1 and np.isfinite(order)):
        raise ValueError(f"order: must be finite and >= 1, got {order}")
    c, p = float(cutoff), float(order)
    nf = len(seq.frames)
    dist, loc, miss, false, ospa = (np.zeros(nf) for _ in range(5))
    cp = c**p
    for k, (x, y) in enumerate(zip(seq.truth_values, seq.track_values, strict=True)):
        m, n = len(x), len(y)
        if m and n:
            d = np.linalg.norm(x[:, None, :] - y[None, :, :], axis=2)
            cost = np.minimum(d, c) ** p
            r, col = linear_sum_assignment(cost)
            real = d[r, col] < c
            pairs = int(real.sum())
            loc[k] = float((d[r, col][real] ** p).sum())
            best = float(cost[r, col].sum())
        else:
            pairs, best = 0, 0.0
        miss[k] = (m - pairs) * cp / 2
        false[k] = (n - pairs) * cp / 2
        dist[k] = (loc[k] + miss[k] + false[k]) ** (1 / p)
        big = max(m, n)
        ospa[k] = ((best + cp * abs(m - n)) / big) ** (1 / p) if big else 0.0
    return Gospa(
        frames=seq.frames,
        distance=dist,
        localisation=loc,
        missed=miss,
        false=false,
        ospa=ospa,
        mean_distance=float(dist.mean()) if nf else 0.0,
        mean_ospa=float(ospa.mean()) if nf else 0.0,
    )
