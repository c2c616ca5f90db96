"""`usvfast lidar`: run the LiDAR detector over a recording and report per-frame counts."""

from __future__ import annotations

import csv
import warnings
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from usvfast.lidar.packets import LidarDataWarning
from usvfast.lidar.pipeline import LidarConfig, LidarDetector
from usvfast.lidar.readers import open_lidar


def load_poses(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a pose CSV with header `time,north,east,heading` (UNIX s, m, m, rad clockwise from
    north) -> (times (t,), poses (t, 3)); rows sorted by time. Raises ValueError on a bad file."""
    data = np.genfromtxt(path, delimiter=",", names=True, dtype=float)
    names = data.dtype.names or ()
    missing = {"time", "north", "east", "heading"} - set(names)
    if missing:
        raise ValueError(f"poses: missing column(s) {sorted(missing)} in {path}")
    data = np.atleast_1d(data)
    order = np.argsort(data["time"])
    t = data["time"][order]
    poses = np.column_stack([data["north"], data["east"], data["heading"]])[order]
    if not np.all(np.isfinite(poses)) or not np.all(np.isfinite(t)):
        raise ValueError(f"poses: non-finite values in {path}")
    return t, poses


def pose_at(times: np.ndarray, poses: np.ndarray, stamp: float) -> np.ndarray:
    """Linear interpolation of (north, east, heading) at `stamp` (clamped at the ends)."""
    heading = np.unwrap(poses[:, 2])
    return np.array(
        [
            np.interp(stamp, times, poses[:, 0]),
            np.interp(stamp, times, poses[:, 1]),
            np.interp(stamp, times, heading),
        ]
    )


def lidar_command(
    path: Annotated[Path, typer.Argument(help="Velodyne .pcap, ROS1 .bag or ROS2 bag directory")],
    topic: Annotated[
        str | None, typer.Option(help="Bag topic (default: every LiDAR topic)")
    ] = None,
    poses: Annotated[
        Path | None,
        typer.Option(
            help="CSV time,north,east,heading (rad); default: sensor at rest at the origin"
        ),
    ] = None,
    csv_out: Annotated[
        Path | None, typer.Option("--csv", help="Write detections to this CSV file")
    ] = None,
    radius: Annotated[float, typer.Option(help="Detection radius, m")] = 10.0,
    height: Annotated[float, typer.Option(help="Sensor height above the water, m")] = 1.0,
    buffer: Annotated[int, typer.Option(help="Frames buffered per clustering cycle")] = 4,
    min_points: Annotated[int, typer.Option(help="Minimum points per cluster")] = 15,
    backend: Annotated[str, typer.Option(help="Mean shift backend: rust or sklearn")] = "rust",
    max_frames: Annotated[int, typer.Option(help="Stop after this many frames (0: all)")] = 0,
) -> None:
    """Run the LiDAR floating-object detector frame by frame; print per-frame counts
    (points, after prefilter, segments, kept, detections) and optionally write a CSV."""
    config = LidarConfig(
        radius=radius,
        mount_height=height,
        buffer_frames=buffer,
        min_cluster_points=min_points,
        backend=backend,
    )
    detector = LidarDetector(config)
    track = load_poses(poses) if poses is not None else None
    reader = open_lidar(path, topic=topic)
    rows = []
    typer.echo("frame  stamp              points  prefiltered  segments  kept  detections")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LidarDataWarning)
        for frame in reader:
            if max_frames and frame.index >= max_frames:
                break
            pose = np.zeros(3) if track is None else pose_at(*track, frame.stamp)
            res = detector.process(frame, pose)
            n_det = "" if res.cycle is None else str(len(res.cycle.detections))
            typer.echo(
                f"{frame.index:5d}  {frame.stamp:17.6f}  {len(frame):6d}  {len(res.xy):11d}  "
                f"{len(res.segments):8d}  {int(res.keep.sum()):4d}  {n_det:>10}"
            )
            if res.cycle is not None:
                for d in res.cycle.detections:
                    c = d.covariance
                    rows.append(
                        [d.time, *d.position, c[0, 0], c[0, 1], c[1, 1], d.n_points, d.sensor_id]
                    )
    for w in caught:
        typer.echo(f"warning: {w.message}", err=True)
    typer.echo(
        f"{reader.stats.frames} frames, {reader.stats.damaged} damaged records skipped, "
        f"{len(rows)} detections"
    )
    if csv_out is not None:
        with open(csv_out, "w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(
                ["time", "north", "east", "cov_nn", "cov_ne", "cov_ee", "n_points", "sensor_id"]
            )
            writer.writerows(rows)
        typer.echo(f"wrote {csv_out}")
