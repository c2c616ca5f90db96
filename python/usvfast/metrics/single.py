"""Track-quality metrics of a tracker run against one target's ground truth.

Tracks are given flat, one row per confirmed track per scan: `scan_index` (N,), `track_ids`
(N,), `track_positions` (N, 2) (north, east) metres; the truth is (n_scans, 2).

`track_quality` follows the rule used for the Joyride anchors: at each scan the
confirmed track nearest to the truth counts if it lies within `gate` metres. `clear_mot` gives
the CLEAR MOT figures (MOTA, MOTP) for the same single target with py-motmetrics' matching rule
(a matched track stays matched while it is within the gate), so they can be cross-checked.

Example::

    q = track_quality(truth_ne, scan_index, track_ids, track_ne, gate=50.0)
    q.rmse, q.coverage, q.fragments, q.tracks_elsewhere
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from usvfast._core import DimensionError
from usvfast._validate import as_float_array


@dataclass(frozen=True)
class TrackQuality:
    """Figures of one run against one target.

    rmse: position RMSE (m) over covered scans (NaN when none). coverage: fraction of scans with
    a counted track. fragments: runs of the same counted id over the covered scans
    (id_switches + 1; 0 when never covered). id_switches: changes of the counted id between
    consecutive covered scans. distinct_tracks: distinct ids ever counted. tracks_elsewhere:
    confirmed tracks never within `gate` of the truth. n_tracks: distinct confirmed tracks.
    errors: (n_scans,) distance of the counted track (NaN when uncovered); counted_ids:
    (n_scans,) its id (-1 when uncovered).
    """

    rmse: float
    coverage: float
    fragments: int
    id_switches: int
    distinct_tracks: int
    tracks_elsewhere: int
    n_tracks: int
    errors: np.ndarray
    counted_ids: np.ndarray


def _check_rows(
    truth_positions: Any, scan_index: Any, track_ids: Any, track_positions: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    truth = as_float_array("truth_positions", truth_positions, ndim=2)
    if truth.shape[1] != 2:
        raise DimensionError(f"truth_positions: expected (n_scans, 2), got {truth.shape}")
    scans = np.asarray(scan_index)
    ids = np.asarray(track_ids)
    for name, arr in (("scan_index", scans), ("track_ids", ids)):
        if arr.ndim != 1 or (arr.size and arr.dtype.kind not in "iu"):
            raise TypeError(f"{name}: expected a 1-D integer array, got {arr.dtype} {arr.shape}")
    scans = scans.astype(np.int64)
    ids = ids.astype(np.int64)
    pos = as_float_array("track_positions", np.reshape(track_positions, (-1, 2)), ndim=2)
    if not (len(scans) == len(ids) == len(pos)):
        raise DimensionError(
            f"scan_index, track_ids, track_positions: lengths differ "
            f"({len(scans)}, {len(ids)}, {len(pos)})"
        )
    if len(scans) and (scans.min() < 0 or scans.max() >= len(truth)):
        raise ValueError(f"scan_index: values must lie in [0, {len(truth)})")
    return truth, scans, ids, pos


def track_quality(
    truth_positions: Any,
    scan_index: Any,
    track_ids: Any,
    track_positions: Any,
    *,
    gate: float = 50.0,
) -> TrackQuality:
    """Position RMSE, coverage, fragments and tracks elsewhere of a run (see module doc).

    truth_positions: (n_scans, 2). scan_index, track_ids: (N,) integers; track_positions: (N, 2)
    (one row per confirmed track per scan). gate: metres. Raises DimensionError / TypeError /
    NonFiniteError naming the argument on bad input.
    """
    truth, scans, ids, pos = _check_rows(truth_positions, scan_index, track_ids, track_positions)
    if not gate > 0:
        raise ValueError(f"gate: must be positive, got {gate}")
    n = len(truth)
    dist = np.linalg.norm(pos - truth[scans], axis=1)
    errors = np.full(n, np.nan)
    counted = np.full(n, -1, dtype=np.int64)
    # Nearest row per scan: sort by (scan, distance), keep the first of each scan.
    order = np.lexsort((dist, scans))
    first = order[np.r_[True, scans[order][1:] != scans[order][:-1]]] if len(order) else order
    near = first[dist[first] <= gate]
    errors[scans[near]] = dist[near]
    counted[scans[near]] = ids[near]
    covered = counted >= 0
    seq = counted[covered]
    switches = int(np.count_nonzero(seq[1:] != seq[:-1]))
    near_ids = set(ids[dist <= gate].tolist())
    all_ids = set(ids.tolist())
    return TrackQuality(
        rmse=float(np.sqrt(np.mean(errors[covered] ** 2))) if covered.any() else float("nan"),
        coverage=float(covered.mean()) if n else float("nan"),
        fragments=switches + 1 if len(seq) else 0,
        id_switches=switches,
        distinct_tracks=len(set(seq.tolist())),
        tracks_elsewhere=len(all_ids - near_ids),
        n_tracks=len(all_ids),
        errors=errors,
        counted_ids=counted,
    )


@dataclass(frozen=True)
class ClearMot:
    """CLEAR MOT of one target: mota = 1 - (misses + false_positives + switches) / n_scans;
    motp: mean distance (m) of the truth to its matched track over matched scans; counts as
    py-motmetrics names them (a scan whose match changed id counts as a switch, not a match)."""

    mota: float
    motp: float
    matches: int
    misses: int
    false_positives: int
    switches: int


def clear_mot(
    truth_positions: Any,
    scan_index: Any,
    track_ids: Any,
    track_positions: Any,
    *,
    gate: float = 50.0,
) -> ClearMot:
    """CLEAR MOT for one target with py-motmetrics' rule: the previously matched track stays
    matched while within `gate` metres, else the nearest within `gate`; every other confirmed
    track of the scan is a false positive; a change of matched id is a switch. Same arguments
    and errors as `track_quality`."""
    truth, scans, ids, pos = _check_rows(truth_positions, scan_index, track_ids, track_positions)
    dist = np.linalg.norm(pos - truth[scans], axis=1)
    order = np.argsort(scans, kind="stable")
    bounds = np.searchsorted(scans[order], np.arange(len(truth) + 1))
    prev = None
    matches = misses = fps = switches = 0
    total = 0.0
    for k in range(len(truth)):
        rows = order[bounds[k] : bounds[k + 1]]
        d, i = dist[rows], ids[rows]
        ok = d <= gate
        pick = None
        if prev is not None and np.any(ok & (i == prev)):
            pick = int(np.flatnonzero(ok & (i == prev))[0])
        elif ok.any():
            pick = int(np.flatnonzero(ok)[np.argmin(d[ok])])
        if pick is None:
            misses += 1
            fps += len(rows)
            continue
        total += float(d[pick])
        if prev is not None and i[pick] != prev:
            switches += 1
        else:
            matches += 1
        prev = int(i[pick])
        fps += len(rows) - 1
    n = len(truth)
    return ClearMot(
        mota=1.0 - (misses + fps + switches) / n if n else float("nan"),
        motp=total / (matches + switches) if matches + switches else float("nan"),
        matches=matches,
        misses=misses,
        false_positives=fps,
        switches=switches,
    )
