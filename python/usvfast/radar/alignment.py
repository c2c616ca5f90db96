"""Radar alignment calibration against a reference track: the radar's bearing bias (its heading
alignment), measured once per installation from plots of a target whose true positions are
known (its GNSS log or AIS reports), and removed before tracking with the tracker config's
`bearing_correction_deg = -bias` (`usvfast.trackcmd.corrected_plots`).

A tracker cannot estimate this angle from the plots alone: a track turned about the own ship
is as likely under its motion models as the true one, so the bias has to come from outside.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["bearing_bias_deg"]


def _points(name: str, v: ArrayLike) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.ndim != 2 or a.shape[1] != 2:
        raise ValueError(f"{name}: an (n, 2) array of north/east metres, got shape {a.shape}")
    return a


def bearing_bias_deg(
    plots: ArrayLike,
    scan_index: ArrayLike,
    origins: ArrayLike,
    reference: ArrayLike,
    *,
    scans: ArrayLike | None = None,
    gate_m: float = 60.0,
    min_pairs: int = 10,
) -> float:
    """The radar's bearing bias (degrees, plot bearing minus true bearing, compass sense:
    clockwise from north) fitted against a reference track.

    plots (d, 2): north/east (m) of every plot, in a local plane; scan_index (d,): the scan
    (0-based) of each plot; origins (d, 2): north/east (m) of the radar when it took each plot;
    reference (s, 2): the reference target's true north/east (m) at each scan, NaN where it is
    not known; scans: the scans to calibrate on (indices into reference, e.g. `range(0, 119)`;
    default all). In each of those scans the plot nearest the reference position, if within
    `gate_m` metres, is paired with it.

    The angle θ is the least-squares rotation about the radar: it minimises
    Σ |p_i − R(θ) t_i|² over the pairs, with p_i, t_i the plot and the reference relative to
    the radar and R(θ) the turn that adds θ to a compass bearing,
    (n, e) → (n cos θ − e sin θ, n sin θ + e cos θ). Its closed form (the two-dimensional case of
    Wahba's problem, Wahba, SIAM Review 7(3), 1965) is θ = atan2(Σ t_i × p_i, Σ t_i · p_i)
    with t × p = t_n p_e − t_e p_n; it is the maximum-likelihood bias for isotropic Gaussian
    plot noise. Pass `bearing_correction_deg = -θ` to the tracker to remove it.

    Raises ValueError naming the argument for shapes that do not match, non-finite plots or
    origins, scan indices outside reference, a gate that is not positive and finite, fewer
    than `min_pairs` pairs (a calibration needs the reference seen in enough scans) and
    positions so large that the sums overflow; TypeError for scan numbers that are not
    integers.
    """
    p = _points("plots", plots)
    o = _points("origins", origins)
    ref = _points("reference", reference)
    si = np.asarray(scan_index)
    if si.shape != (len(p),):
        raise ValueError(f"scan_index: shape ({len(p)},) like plots, got {si.shape}")
    if len(p) and not np.issubdtype(si.dtype, np.integer):
        raise TypeError(f"scan_index: integer scan numbers, got dtype {si.dtype}")
    if o.shape != p.shape:
        raise ValueError(f"origins: shape {p.shape} like plots, got {o.shape}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(o))):
        raise ValueError("plots / origins: every value must be finite")
    if len(si) and (si.min() < 0 or si.max() >= len(ref)):
        raise ValueError(
            f"scan_index: scans in [0, {len(ref)}) (rows of reference), got {si.min()}..{si.max()}"
        )
    if isinstance(gate_m, bool) or not (isinstance(gate_m, int | float) and 0 < gate_m < np.inf):
        raise ValueError(f"gate_m: a positive finite distance in metres, got {gate_m!r}")
    if isinstance(min_pairs, bool) or not isinstance(min_pairs, int) or min_pairs < 1:
        raise ValueError(f"min_pairs: an integer >= 1, got {min_pairs!r}")
    use = np.arange(len(ref)) if scans is None else np.asarray(scans)
    if use.ndim != 1 or (len(use) and not np.issubdtype(use.dtype, np.integer)):
        raise TypeError(
            f"scans: a 1-D sequence of integer scan indices, got {use.dtype} {use.shape}"
        )
    if len(use) and (use.min() < 0 or use.max() >= len(ref)):
        raise ValueError(
            f"scans: indices in [0, {len(ref)}) (rows of reference), got {use.min()}..{use.max()}"
        )
    order = np.argsort(si, kind="stable")
    starts = np.searchsorted(si[order], np.arange(len(ref) + 1))
    t_rel, p_rel = [], []
    for k in np.unique(use):
        if not np.all(np.isfinite(ref[k])):
            continue
        rows = order[starts[k] : starts[k + 1]]
        if not len(rows):
            continue
        d = np.hypot(*(p[rows] - ref[k]).T)
        j = rows[int(np.argmin(d))]
        if d.min() <= gate_m:
            t_rel.append(ref[k] - o[j])
            p_rel.append(p[j] - o[j])
    if len(t_rel) < min_pairs:
        raise ValueError(
            f"reference: {len(t_rel)} scans with a plot within gate_m={gate_m} m of it, "
            f"need min_pairs={min_pairs}"
        )
    t, q = np.array(t_rel), np.array(p_rel)
    with np.errstate(over="ignore", invalid="ignore"):
        cross = np.sum(t[:, 0] * q[:, 1] - t[:, 1] * q[:, 0])
        dot = np.sum(t * q)
    if not (np.isfinite(cross) and np.isfinite(dot)):
        raise ValueError("plots / reference: positions too large for the sums (overflow)")
    return float(np.degrees(np.arctan2(cross, dot)))
