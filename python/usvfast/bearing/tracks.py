"""Bearings from an image tracker's output: one bearing series per track id.

Gorad, Hassan & Särkkä track the detection boxes (DeepSORT) before fusing their bearings; here
the tracker is `usvfast shore` (SORT-like or Bloisi et al.'s particle filter), whose
`tracks.txt` is MOTChallenge text (`frame,id,x,y,w,h,conf,-1,-1,-1`, frames from 1, pixels
with the origin at the top-left). Each box centre `(x + w/2, y + h/2)` goes through eq. (1)
with the camera's calibration (`BearingCamera`: image size, field of view, mounting offsets);
frame n is at time `start_time + (n − 1) / fps` (UNIX seconds). Each track's series is fused
on its own (Wiener-velocity KF + RTS, `fuse_bearings`) with the camera's source id.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usvfast.bearing.camera import BearingCamera, pixel_to_bearing
from usvfast.bearing.fusion import (
    PAPER_MEASUREMENT_STD_DEG,
    PAPER_NOISE_DIFF_COEFF_DEG2,
    BearingFusion,
    fuse_bearings,
)


@dataclass(frozen=True)
class TrackBearings:
    """Bearing samples of image tracks, sorted by track id then time: track_id (n,), frame
    (n,) from 1, times (n,) UNIX seconds, bearing_deg and elevation_deg (n,) relative to own
    heading (eq. 1), confidence (n,) in [0, 1] (the tracks' conf column, clipped)."""

    track_id: np.ndarray
    frame: np.ndarray
    times: np.ndarray
    bearing_deg: np.ndarray
    elevation_deg: np.ndarray
    confidence: np.ndarray

    def ids(self) -> list[int]:
        """The track ids present, ascending."""
        return [int(i) for i in np.unique(self.track_id)]


def looks_like_mot(path: Path | str) -> bool:
    """Whether the file's first non-empty line is a MOTChallenge row (≥ 6 numbers, no
    header), as `usvfast shore` writes tracks.txt."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.strip():
                    parts = line.strip().split(",")
                    try:
                        [float(p) for p in parts]
                    except ValueError:
                        return False
                    return len(parts) >= 6
    except OSError:
        return False
    return False


def track_bearings(
    tracks_path: Path | str, camera: BearingCamera, *, fps: float, start_time: float = 0.0
) -> TrackBearings:
    """Read a MOTChallenge tracks file and turn each box centre into a bearing (module doc).
    Raises ValueError naming `fps`, or the file and line of a malformed row, or when the file
    holds no track row (id ≥ 0)."""
    from usvfast.shore.mot import read_mot

    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps: must be finite and > 0, got {fps}")
    if not np.isfinite(start_time):
        raise ValueError(f"start_time: must be finite, got {start_time}")
    rows = read_mot(tracks_path)
    rows = rows[rows[:, 1] >= 0]
    if not len(rows):
        raise ValueError(f"tracks: no track rows (id ≥ 0) in {tracks_path}")
    if not np.all(np.isfinite(rows[:, :6])):
        raise ValueError(f"tracks: non-finite frame, id or box in {tracks_path}")
    rows = rows[np.lexsort((rows[:, 0], rows[:, 1]))]
    x = rows[:, 2] + rows[:, 4] / 2
    y = rows[:, 3] + rows[:, 5] / 2
    bearing, elevation = pixel_to_bearing(x, y, camera)
    frame = rows[:, 0].astype(np.int64)
    return TrackBearings(
        rows[:, 1].astype(np.int64),
        frame,
        start_time + (frame - 1) / fps,
        np.asarray(bearing, float),
        np.asarray(elevation, float),
        np.clip(rows[:, 6], 0.0, 1.0),
    )


def fuse_tracks(
    samples: TrackBearings,
    *,
    source: int,
    measurement_std_deg: Mapping[int, float] = PAPER_MEASUREMENT_STD_DEG,
    noise_diff_coeff_deg2: float = PAPER_NOISE_DIFF_COEFF_DEG2,
    min_samples: int = 2,
) -> dict[int, BearingFusion]:
    """KF + RTS of each track's bearings (tracks with fewer than `min_samples` are left out),
    every sample from camera `source` (a key of measurement_std_deg)."""
    out = {}
    for tid in samples.ids():
        m = samples.track_id == tid
        if m.sum() < min_samples:
            continue
        out[tid] = fuse_bearings(
            np.full(int(m.sum()), source),
            samples.times[m],
            samples.bearing_deg[m],
            samples.confidence[m],
            measurement_std_deg=measurement_std_deg,
            noise_diff_coeff_deg2=noise_diff_coeff_deg2,
        )
    return out
