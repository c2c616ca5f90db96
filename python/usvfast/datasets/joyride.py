"""Reader of the Joyride radar recording (NTNU; CC0): real radar plots with GNSS truth.

`joyride.mat` (MATLAB v5) holds 238 scans of a marine X-band radar on a small own-ship observing
one manoeuvring boat: per scan the UNIX time, the radar plots (north, east) in metres of a local
tangent plane, the target's GNSS state and the own-ship's state [n, v_n, e, v_e] (m, m/s).

Example::

    from usvfast.datasets import load_joyride

    rec = load_joyride("/path/to/joyride.mat")
    for t, plots in zip(rec.times, rec.measurements):
        ...  # plots: (k, 2) north, east in metres
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class JoyrideRecording:
    """The recording, one entry per usable scan, in time order.

    times: (n,) UNIX seconds. measurements: list of n arrays (k_i, 2) of plots (north, east) in
    metres (k_i may be 0 when a scan's plots were all damaged). target, ownship: (n, 4) states
    [n, v_n, e, v_e] (m, m/s) at the scan times. skipped_scans / skipped_plots: counts of records
    dropped because they were non-finite or malformed.
    """

    times: np.ndarray
    measurements: list[np.ndarray]
    target: np.ndarray
    ownship: np.ndarray
    skipped_scans: int = 0
    skipped_plots: int = 0

    @property
    def n_scans(self) -> int:
        """Number of usable scans."""
        return len(self.times)

    def scan_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """All plots flattened: (scan_index (N,) int64, plots (N, 2)) in scan order."""
        counts = np.array([len(m) for m in self.measurements], dtype=np.int64)
        idx = np.repeat(np.arange(self.n_scans, dtype=np.int64), counts)
        plots = np.concatenate(self.measurements) if counts.sum() else np.zeros((0, 2), np.float64)
        return idx, plots


def _plots(cell: object) -> np.ndarray | None:
    """One scan's plots as (k, 2) float64, or None when the cell is malformed."""
    try:
        arr = np.asarray(cell, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    if arr.size == 0:
        return np.zeros((0, 2))
    if arr.ndim != 2 or arr.shape[1] != 2:
        return None
    return arr


def load_joyride(path: str | PathLike[str]) -> JoyrideRecording:
    """Read `joyride.mat` (MATLAB v5; keys `time`, `measurements`, `target`, `telemetron`).

    Scans whose time or truth is non-finite or malformed are skipped, and plots that are
    non-finite are dropped, with a warning and counts on the result (`skipped_scans`,
    `skipped_plots`); scans out of time order are skipped likewise. Raises FileNotFoundError
    when `path` does not exist, ValueError when the file is damaged, a key is missing or no
    scan is usable.
    """
    from scipy.io import loadmat

    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"path: no such file {p}")
    try:
        data = loadmat(p)
    except Exception as exc:  # scipy raises ValueError, TypeError, OSError, zlib.error, ...
        raise ValueError(f"path: {p.name} is not a readable MATLAB v5 file ({exc})") from exc
    for key in ("time", "measurements", "target", "telemetron"):
        if key not in data:
            raise ValueError(f"path: {p.name} has no '{key}' array; not a Joyride file")
    times = np.asarray(data["time"], dtype=np.float64).ravel()
    cells = np.asarray(data["measurements"], dtype=object).ravel()
    target = np.asarray(data["target"], dtype=np.float64)
    ownship = np.asarray(data["telemetron"], dtype=np.float64)
    n = len(times)
    if len(cells) != n or target.shape != (n, 4) or ownship.shape != (n, 4):
        raise ValueError(
            f"path: inconsistent lengths: time {n}, measurements {len(cells)}, "
            f"target {target.shape}, telemetron {ownship.shape}"
        )
    keep: list[int] = []
    scans: list[np.ndarray] = []
    skipped_scans = skipped_plots = 0
    last_t = -np.inf
    for i in range(n):
        plots = _plots(cells[i])
        ok = (
            plots is not None
            and np.isfinite(times[i])
            and times[i] >= last_t
            and np.all(np.isfinite(target[i]))
            and np.all(np.isfinite(ownship[i]))
        )
        if not ok or plots is None:
            skipped_scans += 1
            continue
        good = np.all(np.isfinite(plots), axis=1)
        skipped_plots += int(np.count_nonzero(~good))
        scans.append(np.ascontiguousarray(plots[good]))
        keep.append(i)
        last_t = times[i]
    if not keep:
        raise ValueError(f"path: no usable scan in {p.name} ({skipped_scans} skipped)")
    if skipped_scans or skipped_plots:
        warnings.warn(
            f"load_joyride: skipped {skipped_scans} damaged scans and {skipped_plots} "
            "non-finite plots",
            stacklevel=2,
        )
    k = np.asarray(keep)
    return JoyrideRecording(
        times=times[k].copy(),
        measurements=scans,
        target=target[k].copy(),
        ownship=ownship[k].copy(),
        skipped_scans=skipped_scans,
        skipped_plots=skipped_plots,
    )
