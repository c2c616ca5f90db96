"""The situation picture of a `run_vts` result (matplotlib, Agg): own ship, radar plots,
radar tracks, AIS targets with MMSI and name, and radar–AIS association lines, in the NED
plane (east right, north up, metres), with axes, units and a legend; and camera overlays
(fused targets drawn on the image with MMSI, range and bearing)."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from usvfast._validate import image as check_image
from usvfast.fusion.pipeline import FusedRow, VtsResult

__all__ = ["draw_overlay", "situation_picture"]


def _by(rows: list[FusedRow], key: str) -> dict[int, list[FusedRow]]:
    out: dict[int, list[FusedRow]] = defaultdict(list)
    for r in rows:
        out[getattr(r, key)].append(r)
    return out


def situation_picture(res: VtsResult, path: str | Path, *, title: str = "") -> Path:
    """Write the 2-D situation picture of `res` to `path` (PNG) and return the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, 9), dpi=110)
    if len(res.plots):
        ax.scatter(res.plots[:, 2], res.plots[:, 1], s=4, c="0.6", label="radar plots", zorder=1)
    if len(res.own):
        ax.plot(res.own[:, 2], res.own[:, 1], "-", c="k", lw=1.5, label="own ship", zorder=3)
        ax.plot(res.own[-1, 2], res.own[-1, 1], "k^", ms=10, zorder=4)
    cmap = plt.get_cmap("tab10")
    paired_rows = [r for r in res.rows if r.source.startswith("radar+ais")]
    tracks = _by(res.radar_rows, "track_id")
    identified = {r.track_id: r.mmsi for r in paired_rows}
    for k, (tid, rows) in enumerate(sorted(tracks.items())):
        xy = np.array([(r.east, r.north) for r in rows])
        named = tid in identified
        ax.plot(
            xy[:, 0],
            xy[:, 1],
            "-",
            c=cmap(k % 10) if named else "tab:blue",
            lw=2.0 if named else 0.8,
            alpha=1.0 if named else 0.6,
            label="radar tracks" if k == 0 else None,
            zorder=5,
        )
        ax.annotate(f"T{tid}", xy[-1], fontsize=8, color="navy", zorder=6)
    for k, (mmsi, rows) in enumerate(sorted(_by(res.ais_rows, "mmsi").items())):
        xy = np.array([(r.east, r.north) for r in rows])
        ax.plot(
            xy[:, 0],
            xy[:, 1],
            "--",
            c="tab:red",
            lw=1.0,
            label="AIS targets (dead reckoned)" if k == 0 else None,
            zorder=4,
        )
        ax.plot(xy[-1, 0], xy[-1, 1], "s", c="tab:red", ms=5, zorder=6)
        name = res.names.get(mmsi, "")
        ax.annotate(
            f"{mmsi} {name}".strip(),
            xy[-1],
            xytext=(5, -12),
            textcoords="offset points",
            fontsize=8,
            color="tab:red",
            zorder=7,
        )
    # Association lines: radar track to its AIS target, every ~10th scan of each pair.
    ais_at = {(r.time, r.mmsi): r for r in res.ais_rows}
    radar_at = {(r.time, r.track_id): r for r in res.radar_rows}
    first = True
    for n, r in enumerate(paired_rows):
        a, b = ais_at.get((r.time, r.mmsi)), radar_at.get((r.time, r.track_id))
        if a is None or b is None or n % 5:
            continue
        ax.plot(
            [a.east, b.east],
            [a.north, b.north],
            "-",
            c="magenta",
            lw=1.5,
            label="radar–AIS association" if first else None,
            zorder=10,
        )
        first = False
    if paired_rows:
        xy = np.array([(r.east, r.north) for r in paired_rows])
        ax.scatter(xy[:, 0], xy[:, 1], s=2, c="darkgreen", label="fused (radar+AIS)", zorder=9)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, lw=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title or "Situation: radar, AIS and fused targets (NED plane)")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out)
    plt.close(fig)
    return out


def draw_overlay(
    image: np.ndarray, pixels: np.ndarray, labels: list[str], boxes: ArrayLike | None = None
) -> np.ndarray:
    """A copy of `image` (BGR) with detection boxes (n, 4) in grey and targets drawn at
    `pixels` (k, 2) with their label (MMSI, range, bearing); NaN pixels are skipped."""
    check_image("image", image)
    if not (isinstance(labels, list | tuple) and all(isinstance(t, str) for t in labels)):
        raise TypeError(f"labels: expected a list of str, got {type(labels).__name__}")
    import cv2

    out = image.copy()
    if boxes is not None:
        for x1, y1, x2, y2 in np.asarray(boxes, float).reshape(-1, 4):
            cv2.rectangle(out, (int(x1), int(y1)), (int(x2), int(y2)), (160, 160, 160), 1)
    for (u, v), text in zip(np.asarray(pixels, float).reshape(-1, 2), labels, strict=True):
        if not (np.isfinite(u) and np.isfinite(v)):
            continue
        p = (round(float(u)), round(float(v)))
        cv2.drawMarker(out, p, (0, 0, 255), cv2.MARKER_CROSS, 18, 2)
        cv2.putText(out, text, (p[0] + 8, p[1] - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 255), 1)
    return out
