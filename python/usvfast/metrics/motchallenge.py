"""MOTChallenge text files: one box per line, `frame,id,x,y,w,h,conf,x3d,y3d,z3d` (frame
numbers from 1, pixels, (x, y) the top-left corner; ground-truth files put flag, class and
visibility in the last three columns). Lines that do not parse are skipped and counted.

Example::

    boxes = read_motchallenge("gt/gt.txt")
    write_motchallenge("tracks.txt", boxes.frame, boxes.ids, boxes.boxes, boxes.conf)
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from usvfast._core import DimensionError
from usvfast._validate import as_float_array


@dataclass(frozen=True)
class MotBoxes:
    """Boxes of a MOTChallenge file: frame (N,) int, ids (N,) int, boxes (N, 4) (x, y, w, h)
    pixels, conf (N,) the 7th column (1.0 when absent); skipped: damaged lines."""

    frame: np.ndarray
    ids: np.ndarray
    boxes: np.ndarray
    conf: np.ndarray
    skipped: int


def read_motchallenge(path: str | Path, *, min_conf: float | None = None) -> MotBoxes:
    """Read a MOTChallenge file. min_conf: drop rows whose 7th column is below it (in a
    ground-truth file this is the "consider" flag, so 0.5 keeps the boxes to score). Raises
    FileNotFoundError naming `path`; warns with the count of skipped damaged lines."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"path: no such file {p}")
    rows: list[list[float]] = []
    skipped = 0
    for line in p.read_text().splitlines():
        if not line.strip():
            continue
        try:
            vals = [float(v) for v in line.replace(" ", "").split(",")]
        except ValueError:
            skipped += 1
            continue
        if len(vals) < 6 or not np.all(np.isfinite(vals[:6])) or vals[4] < 0 or vals[5] < 0:
            skipped += 1
            continue
        rows.append(vals[:7] if len(vals) >= 7 else [*vals[:6], 1.0])
    if skipped:
        warnings.warn(f"{p}: skipped {skipped} damaged lines", UserWarning, stacklevel=2)
    a = np.array(rows, float).reshape(-1, 7)
    if min_conf is not None:
        a = a[a[:, 6] >= min_conf]
    return MotBoxes(
        frame=a[:, 0].astype(np.int64),
        ids=a[:, 1].astype(np.int64),
        boxes=a[:, 2:6].copy(),
        conf=a[:, 6].copy(),
        skipped=skipped,
    )


def write_motchallenge(
    path: str | Path, frame: ArrayLike, ids: ArrayLike, boxes: Any, conf: ArrayLike | None = None
) -> None:
    """Write boxes as `frame,id,x,y,w,h,conf,-1,-1,-1` lines sorted by frame then id.
    frame, ids: (N,) integers (detections use id −1); boxes: (N, 4) pixels; conf: (N,) or
    None (1). Raises DimensionError / TypeError naming the argument."""
    f = np.asarray(frame)
    i = np.asarray(ids)
    for name, arr in (("frame", f), ("ids", i)):
        if arr.ndim != 1 or (arr.size and arr.dtype.kind not in "iu"):
            raise TypeError(f"{name}: expected a 1-D integer array, got {arr.dtype} {arr.shape}")
    b = as_float_array("boxes", np.reshape(boxes, (-1, 4)), ndim=2)
    c = np.ones(len(f)) if conf is None else as_float_array("conf", conf, ndim=1)
    if not (len(f) == len(i) == len(b) == len(c)):
        raise DimensionError(
            f"frame, ids, boxes, conf: lengths differ ({len(f)}, {len(i)}, {len(b)}, {len(c)})"
        )
    order = np.lexsort((i, f))
    table = np.column_stack([f[order], i[order], b[order], c[order]])
    with Path(path).open("w") as fh:
        for r in table:
            fh.write(
                f"{int(r[0])},{int(r[1])},{r[2]:.2f},{r[3]:.2f},{r[4]:.2f},{r[5]:.2f},"
                f"{r[6]:.4g},-1,-1,-1\n"
            )
