"""What each simulated sensor could physically see of every truth object: `visibility.csv`.

`simulate` writes it beside truth.csv while it casts the VLP-16's rays and renders the camera
frames, from the same rays and pixels that make the recording (nothing is re-simulated, so
the recording's bytes do not change). One row per (sensor sample, object) where the object
was seen at all:

    time,object_id,sensor,count,width_px,height_px,visible_fraction

- sensor "lidar": `time` is the rotation's stamp (UNIX s, its last packet: the rotation spans
  the 0.1 s before it), `count` the returns from the object in that rotation (any range;
  wave-crest returns and the quays' are no object's), width_px / height_px /
  visible_fraction empty;
- sensor "camera": `time` is the frame's exposure time (UNIX s), `count` the object's visible
  pixels (the renderer's pixel centres that see it first), `width_px` × `height_px` the box
  around them (px, as a detector's xyxy box), `visible_fraction` the visible share of the
  pixels it would cover unoccluded (0..1).

`object_id` is truth.csv's integer id (floats, vessels, moored boats; a vessel's or moored
boat's cabin counts as the boat). The report's "detectable" rule reads it
(`usvfast.report.detectable`).
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np

from usvfast._validate import instance

#: Columns of visibility.csv, in order.
VISIBILITY_COLUMNS = (
    "time",
    "object_id",
    "sensor",
    "count",
    "width_px",
    "height_px",
    "visible_fraction",
)


class VisibilityLog:
    """Collects visibility rows as the simulator makes its sensor samples.

    ids: truth.csv's integer id of every truth object by its name in the world
    (`World.truth_ids()`).
    """

    def __init__(self, ids: dict[str, int]) -> None:
        instance("ids", ids, dict)
        self.ids = dict(ids)
        self.rows: list[tuple[float, int, str, int, Any, Any, Any]] = []

    def lidar(self, stamp: float, object_ids: np.ndarray) -> None:
        """One rotation stamped `stamp` (UNIX s) whose returns belong to `object_ids` (n,)
        (`Scan.object_ids`: a body's object id, '' for structure, 'water' for crests)."""
        names, counts = np.unique(np.asarray(object_ids, dtype=str), return_counts=True)
        for name, count in zip(names.tolist(), counts.tolist(), strict=True):
            if name in self.ids:
                self.rows.append((float(stamp), self.ids[name], "lidar", int(count), "", "", ""))

    def camera(self, time: float, boxes: list[Any]) -> None:
        """One frame exposed at `time` (UNIX s) and its ground-truth pixel boxes
        (`usvfast.sim.camera.PixelBox`, rendered with min_pixels=1)."""
        for b in boxes:
            if b.object_id in self.ids:
                self.rows.append(
                    (
                        float(time),
                        self.ids[b.object_id],
                        "camera",
                        int(b.pixels),
                        round(float(b.x1 - b.x0), 3),
                        round(float(b.y1 - b.y0), 3),
                        round(float(b.visible_fraction), 4),
                    )
                )

    def write(self, path: str | Path) -> int:
        """Write visibility.csv (rows by time, then sensor, then object id); returns the row
        count."""
        rows = sorted(self.rows, key=lambda r: (r[0], r[2], r[1]))
        with open(path, "w", newline="") as fh:
            out = csv.writer(fh, lineterminator="\n")
            out.writerow(VISIBILITY_COLUMNS)
            for t, oid, sensor, count, w, h, frac in rows:
                out.writerow([f"{t:.6f}", oid, sensor, count, w, h, frac])
        return len(rows)


__all__ = ["VISIBILITY_COLUMNS", "VisibilityLog"]
