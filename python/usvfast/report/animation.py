"""The global tracking animation (the thesis's `Global_tracking_animation`): frame by frame, the
map of the run up to that time (USV path and heading, the last second of detections, tracks
with their current 2σ ellipse, the truth) beside the camera image of that moment from
`camera_frames/`. Written as an animated GIF (Pillow), a few frames per second, kept small.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PIL import Image

from usvfast.metrics.tables import Detections, Nav, Tracks, Truth
from usvfast.report import figures as F


def read_camera_frames(folder: Path) -> tuple[np.ndarray, list[Path]]:
    """Times (n,) and image paths of `camera_frames/camera_frames.csv` (time,file); rows whose
    file is missing or damaged are skipped. Empty when the folder or the list is absent."""
    listing = folder / "camera_frames.csv"
    if not listing.is_file():
        return np.zeros(0), []
    times, files = [], []
    with listing.open(newline="") as fh:
        for row in csv.DictReader(fh):
            try:
                t = float(row["time"])
            except (KeyError, TypeError, ValueError):
                continue
            p = folder / str(row.get("file", ""))
            if np.isfinite(t) and p.is_file():
                times.append(t)
                files.append(p)
    order = np.argsort(times, kind="stable")
    return np.asarray(times)[order], [files[i] for i in order]


def _image(path: Path) -> np.ndarray | None:
    try:
        with Image.open(path) as im:
            return np.asarray(im.convert("RGB"))
    except (OSError, ValueError):
        return None


def write_animation(
    path: Path,
    tracks: Tracks,
    *,
    detections: Detections | None = None,
    nav: Nav | None = None,
    truth: Truth | None = None,
    scene: dict[str, Any] | None = None,
    camera_dir: Path | None = None,
    fps: float = 2.0,
    max_frames: int = 60,
    dpi: int = 72,
    title: str = "usvfast",
) -> Path | None:
    """Write the animation GIF to `path` (module doc); None when the run has no time span.
    fps: frames per second of the GIF; max_frames: at most this many frames, evenly spaced
    over the run (one per recording second at most 2 fps of playback)."""
    spans = [tracks.time] + ([nav.time] if nav is not None else [])
    allt = np.concatenate([np.zeros(0), *spans])
    if len(allt) == 0:
        return None
    t0, t1 = float(allt.min()), float(allt.max())
    n = int(min(max_frames, max(1, np.floor((t1 - t0) * fps) + 1)))
    times = np.linspace(t0, t1, n)
    cam_t, cam_f = read_camera_frames(camera_dir) if camera_dir else (np.zeros(0), [])
    with_cam = len(cam_t) > 0
    fig = Figure(figsize=(10.5 if with_cam else 6.5, 5.0), dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    if with_cam:
        ax, cx = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1, 1.25]})
        fig.subplots_adjust(left=0.07, right=0.99, bottom=0.1, top=0.92, wspace=0.08)
    else:
        ax, cx = fig.add_subplot(1, 1, 1), None
        fig.subplots_adjust(left=0.12, right=0.97, bottom=0.1, top=0.92)
    colors = F.track_colors(tracks.track_id)
    parts = F.map_extent(tracks, detections, nav, truth)
    # the static layer once: harbour, axes, limits
    F.draw_scene(ax, scene)
    F.fit_limits(ax, parts)
    ax.set_xlabel("east (m)", fontsize=9)
    ax.set_ylabel("north (m)", fontsize=9)
    ax.tick_params(labelsize=8)
    ax.grid(True, alpha=0.3)
    static = set(ax.get_children())
    shown = None
    if cx is not None:
        cx.axis("off")
    pictures: list[Image.Image] = []
    for t in times:
        F.draw_detections(ax, detections, since=t - 1.0, upto=t, size=14)
        F.draw_truth(ax, truth, upto=t, label=False)
        F.draw_usv(ax, nav, upto=t)
        F.draw_tracks(ax, tracks, colors, upto=t)
        ax.set_title(f"{title}  t = {t - t0:5.1f} s", fontsize=10)
        if cx is not None:
            k = int(np.clip(np.searchsorted(cam_t, t, side="right") - 1, 0, len(cam_t) - 1))
            img = _image(cam_f[k])
            if img is not None:
                if shown is not None and shown.get_array().shape == img.shape:
                    shown.set_data(img)
                else:
                    if shown is not None:
                        shown.remove()
                    shown = cx.imshow(img)
            cx.set_title(f"camera  t = {cam_t[k] - t0:5.1f} s", fontsize=10)
        canvas.draw()
        rgb = np.asarray(canvas.buffer_rgba())[..., :3]
        pictures.append(Image.fromarray(rgb).quantize(colors=128, method=Image.Quantize.MEDIANCUT))
        for artist in ax.get_children():
            if artist not in static:
                artist.remove()
    pictures[0].save(
        path,
        save_all=True,
        append_images=pictures[1:],
        duration=round(1000 / fps),
        loop=0,
        optimize=True,
    )
    return path
