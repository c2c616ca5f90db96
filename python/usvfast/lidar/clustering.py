"""Flat-kernel mean shift clustering of buffered LiDAR points (thesis section 3.3.5).

`mean_shift` returns the same cluster centres (same order) and labels as scikit-learn's
`sklearn.cluster.MeanShift` with the same parameters — seeds, bin seeding, convergence at
``1e-3 * bandwidth``, duplicate-centre suppression by intensity within ``bandwidth``, orphans
labelled -1 when ``cluster_all=False`` — computed in Rust with a hash grid instead of a
KD-tree (``backend="rust"``, the default), or by scikit-learn itself (``backend="sklearn"``,
the reference). Centres may differ from scikit-learn's in the last bits (window sums are
taken in a different order).
"""

from __future__ import annotations

import operator
import warnings
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from usvfast import _core
from usvfast._validate import as_float_array

__all__ = ["mean_shift"]

_BACKENDS = ("rust", "sklearn")


def _int(name: str, value: Any, minimum: int) -> int:
    try:
        v = operator.index(value)
    except TypeError:
        raise TypeError(f"{name}: expected an integer, got {type(value).__name__}") from None
    if v < minimum:
        raise ValueError(f"{name}: must be at least {minimum}, got {v}")
    return v


def mean_shift(
    points: ArrayLike,
    *,
    bandwidth: float = 2.0,
    seeds: ArrayLike | None = None,
    bin_seeding: bool = False,
    min_bin_freq: int = 1,
    cluster_all: bool = True,
    max_iter: int = 300,
    backend: str = "rust",
) -> tuple[np.ndarray, np.ndarray]:
    """Mean shift with a flat kernel of radius `bandwidth`: ``(cluster_centers, labels)``.

    points: (n, d) (the LiDAR pipeline: metres, NED world frame, d = 2); bandwidth: same
    unit, > 0; seeds: (k, d) initial kernel positions or None (every point, or the bins
    when `bin_seeding`); min_bin_freq: minimum points per bin for a bin seed;
    cluster_all: give orphans the nearest centre's label instead of -1; max_iter: per
    seed. Returns centres (c, d) float64 sorted by decreasing intensity and labels (n,)
    int64 — scikit-learn's `MeanShift(...).fit(points)` ``cluster_centers_`` and ``labels_``.
    No points: centres (0, d) and no labels. Warns (UserWarning) like scikit-learn when bin
    seeding gives one bin per point. Raises DimensionError / NonFiniteError / TypeError
    naming the argument for bad arrays, ValueError for a non-positive bandwidth, an unknown
    backend, ``min_bin_freq < 1``, ``max_iter < 0``, or when no seed has a point within
    `bandwidth`.
    """
    x = as_float_array("points", points)
    if x.ndim != 2 or x.shape[1] == 0:
        if x.size == 0 and x.ndim == 1:
            x = x.reshape(0, 2)
        else:
            raise _core.DimensionError(f"points: expected shape (n, d), got {x.shape}")
    bw = float(bandwidth)
    if not (np.isfinite(bw) and bw > 0.0):
        raise ValueError(f"bandwidth: must be finite and positive, got {bw}")
    s = None
    if seeds is not None:
        s = as_float_array("seeds", seeds)
        if s.ndim != 2 or s.shape[1] != x.shape[1]:
            raise _core.DimensionError(
                f"seeds: expected shape (k, {x.shape[1]}) like points, got {s.shape}"
            )
    min_bin_freq = _int("min_bin_freq", min_bin_freq, 1)
    max_iter = _int("max_iter", max_iter, 0)
    if backend not in _BACKENDS:
        raise ValueError(f"backend: expected one of {_BACKENDS}, got {backend!r}")
    if len(x) == 0:
        return np.zeros((0, x.shape[1])), np.zeros(0, dtype=np.int64)
    if backend == "sklearn":
        from sklearn.cluster import MeanShift

        try:
            model = MeanShift(
                bandwidth=bw,
                seeds=s,
                bin_seeding=bool(bin_seeding),
                min_bin_freq=min_bin_freq,
                cluster_all=bool(cluster_all),
                max_iter=max_iter,
            ).fit(x)
        except ValueError as exc:
            if "empty sequence" not in str(exc) and "No point was within" not in str(exc):
                raise
            raise ValueError(f"seeds: no point was within bandwidth={bw} of any seed") from exc
        return np.asarray(model.cluster_centers_, dtype=np.float64), model.labels_.astype(np.int64)
    centers, labels, _n_iter, fell_back = _core.mean_shift(
        x,
        bandwidth=bw,
        seeds=s,
        bin_seeding=bool(bin_seeding),
        min_bin_freq=min_bin_freq,
        cluster_all=bool(cluster_all),
        max_iter=max_iter,
    )
    if fell_back:
        warnings.warn(
            f"Binning data failed with provided bin_size={bw:f}, using data points as seeds.",
            UserWarning,
            stacklevel=2,
        )
    return centers, labels
