"""MOTChallenge text files: one row per box, `frame,id,x,y,w,h,conf,-1,-1,-1`, frame numbers
from 1, pixels with the origin at the image's top-left; detections carry id −1."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from usvfast._validate import as_float_array, integer

#: Columns of a MOTChallenge row.
COLUMNS = ("frame", "id", "x", "y", "w", "h", "conf", "x3d", "y3d", "z3d")


def mot_rows(frame: int, ids: ArrayLike, boxes: ArrayLike, scores: ArrayLike) -> np.ndarray:
    """(k, 10) rows of one frame (>= 1; ids (k,), boxes (k, 4) x, y, w, h px, scores (k,)).
    Raises TypeError / ValueError naming the argument that is not a number or not of k."""
    frame = integer("frame", frame, low=1)
    b = as_float_array("boxes", boxes)
    if b.size % 4 or b.ndim > 2 or (b.ndim == 2 and b.shape[1] != 4):
        raise ValueError(f"boxes: expected shape (k, 4), got {b.shape}")
    b = b.reshape(-1, 4)
    k = len(b)
    rows = np.full((k, 10), -1.0)
    rows[:, 0] = frame
    for col, name, value in ((1, "ids", ids), (6, "scores", scores)):
        v = as_float_array(name, value).reshape(-1)
        if v.shape != (k,):
            raise ValueError(f"{name}: expected {k} values (one per box), got {v.size}")
        rows[:, col] = v
    rows[:, 2:6] = b
    return rows


def write_mot(path: Path | str, rows: np.ndarray) -> None:
    """Write (n, 10) rows as MOTChallenge text (frame and id as integers, boxes to 0.01 px)."""
    with open(path, "w", encoding="utf-8") as fh:
        for r in np.asarray(rows).reshape(-1, 10):
            fh.write(
                f"{int(r[0])},{int(r[1])},{r[2]:.2f},{r[3]:.2f},{r[4]:.2f},{r[5]:.2f},"
                f"{r[6]:.4f},-1,-1,-1\n"
            )


def read_mot(path: Path | str) -> np.ndarray:
    """(n, 10) float rows of a MOTChallenge file (empty file: (0, 10)). Raises ValueError
    naming the file and line on a malformed row."""
    rows = []
    with open(path, encoding="utf-8") as fh:
        for n, line in enumerate(fh, 1):
            if not line.strip():
                continue
            parts = line.strip().split(",")
            try:
                vals = [float(v) for v in parts]
            except ValueError as exc:
                raise ValueError(f"{path}:{n}: not a MOTChallenge row: {line.strip()!r}") from exc
            if len(vals) < 6:
                raise ValueError(f"{path}:{n}: expected at least 6 columns, got {len(vals)}")
            rows.append((vals + [-1.0] * 10)[:10])
    return np.array(rows, dtype=float).reshape(-1, 10)
