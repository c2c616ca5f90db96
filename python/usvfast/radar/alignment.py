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


def scan_numbers(scan_index: ArrayLike, n_plots: int) -> np.ndarray:
    """`scan_index` checked: shape (n_plots,), integers (TypeError otherwise)."""
    si = np.asarray(scan_index)
    if si.shape != (n_plots,):
        raise ValueError(f"scan_index: shape ({n_plots},) like plots, got {si.shape}")
    if n_plots and not np.issubdtype(si.dtype, np.integer):
        raise TypeError(f"scan_index: integer scan numbers, got dtype {si.dtype}")
    return si


def in_reference(si: np.ndarray, n_ref: int) -> None:
    """ValueError unless every scan number of `si` is a row of a reference of n_ref rows."""
    if len(si) and (si.min() < 0 or si.max() >= n_ref):
        raise ValueError(
            f"scan_index: scans in [0, {n_ref}) (rows of reference), got {si.min()}..{si.max()}"
        )


def chosen_scans(scans: ArrayLike | None, n_ref: int) -> np.ndarray:
    """The unique scan indices of `scans` (default all n_ref), checked: 1-D integers
    (TypeError otherwise) in [0, n_ref)."""
    use = np.arange(n_ref) if scans is None else np.asarray(scans)
    if use.ndim != 1 or (len(use) and not np.issubdtype(use.dtype, np.integer)):
        raise TypeError(
            f"scans: a 1-D sequence of integer scan indices, got {use.dtype} {use.shape}"
        )
    if len(use) and (use.min() < 0 or use.max() >= n_ref):
        raise ValueError(
            f"scans: indices in [0, {n_ref}) (rows of reference), got {use.min()}..{use.max()}"
        )
    return np.unique(use).astype(np.int64)


def scan_slices(scan_index: np.ndarray, n_scans: int) -> tuple[np.ndarray, np.ndarray]:
    """(order, starts): the plot rows of scan k are `order[starts[k]:starts[k + 1]]`."""
    order = np.argsort(scan_index, kind="stable")
    return order, np.searchsorted(scan_index[order], np.arange(n_scans + 1))


def nearest_pairs(
    plots: np.ndarray, scan_index: np.ndarray, reference: np.ndarray, scans, gate_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """(scans, rows): in each of `scans` (unique, in [0, len(reference))) whose reference is
    finite, the row of the plot nearest the reference position if it is within `gate_m`
    metres (ties: the first row). Inputs already checked."""
    order, starts = scan_slices(scan_index, len(reference))
    ks, js = [], []
    for k in scans:
        if not np.all(np.isfinite(reference[k])):
            continue
        rows = order[starts[k] : starts[k + 1]]
        if not len(rows):
            continue
        d = np.hypot(*(plots[rows] - reference[k]).T)
        i = int(np.argmin(d))
        if d[i] <= gate_m:
            ks.append(int(k))
            js.append(int(rows[i]))
    return np.array(ks, dtype=np.int64), np.array(js, dtype=np.int64)


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
    si = scan_numbers(scan_index, len(p))
    if o.shape != p.shape:
        raise ValueError(f"origins: shape {p.shape} like plots, got {o.shape}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(o))):
        raise ValueError("plots / origins: every value must be finite")
    in_reference(si, len(ref))
    if isinstance(gate_m, bool) or not (isinstance(gate_m, int | float) and 0 < gate_m < np.inf):
        raise ValueError(f"gate_m: a positive finite distance in metres, got {gate_m!r}")
    if isinstance(min_pairs, bool) or not isinstance(min_pairs, int) or min_pairs < 1:
        raise ValueError(f"min_pairs: an integer >= 1, got {min_pairs!r}")
    use = chosen_scans(scans, len(ref))
    k, rows = nearest_pairs(p, si, ref, use, gate_m)
    t, q = ref[k] - o[rows], p[rows] - o[rows]
    if len(t) < min_pairs:
        raise ValueError(
            f"reference: {len(t)} scans with a plot within gate_m={gate_m} m of it, "
            f"need min_pairs={min_pairs}"
        )
    with np.errstate(over="ignore", invalid="ignore"):
        cross = np.sum(t[:, 0] * q[:, 1] - t[:, 1] * q[:, 0])
        dot = np.sum(t * q)
    if not (np.isfinite(cross) and np.isfinite(dot)):
        raise ValueError("plots / reference: positions too large for the sums (overflow)")
    return float(np.degrees(np.arctan2(cross, dot)))
