"""Synthetic recordings and pipeline outputs in the interface formats (truth.csv, scene.json,
origin.json; tracks.csv, detections.csv, nav.csv, innovations.csv, camera_frames/), written
from a known truth with known errors so the metrics' answers are known."""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

EPOCH = 1.7e9
ORIGIN = (63.4386345, 10.3985848, 0.0)


@dataclass
class Obj:
    """One truth object: id, kind, start position (n, e) m, velocity (m/s), truth time span."""

    object_id: int
    kind: str
    start: tuple[float, float]
    velocity: tuple[float, float] = (0.0, 0.0)
    span: tuple[float, float] = (0.0, 30.0)

    def at(self, t: np.ndarray) -> np.ndarray:
        s = t - EPOCH
        return np.column_stack(
            [self.start[0] + self.velocity[0] * s, self.start[1] + self.velocity[1] * s]
        )


@dataclass
class TrackSpec:
    """A track following `object_id` from t0 to t1 (seconds after EPOCH) with a constant
    `offset` (n, e) m plus Gaussian noise of covariance `noise`, reporting `cov` as its
    covariance."""

    track_id: int
    object_id: int | None
    t0: float
    t1: float
    offset: tuple[float, float] = (0.0, 0.0)
    noise: np.ndarray | None = None
    cov: np.ndarray = field(default_factory=lambda: np.diag([0.04, 0.04]))
    position: tuple[float, float] | None = None  # a track at a fixed place (clutter)


def default_objects() -> list[Obj]:
    return [
        Obj(1, "bottle", (20.0, 5.0), (0.02, 0.01)),
        Obj(2, "bag", (25.0, -8.0), (0.0, 0.03)),
        Obj(3, "box", (12.0, 12.0), (-0.02, 0.0)),
        Obj(4, "vessel", (-30.0, -20.0), (1.5, 1.0)),
        Obj(5, "moored_boat", (40.0, 30.0)),
    ]


def _write(path: Path, header: list[str], rows) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


def write_truth(d: Path, objects: list[Obj], dt: float = 0.1) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    rows = []
    for o in objects:
        t = EPOCH + np.arange(round(o.span[0] / dt), round(o.span[1] / dt) + 1) * dt
        p = o.at(t)
        for ti, (n, e) in zip(t, p, strict=True):
            rows.append([f"{ti:.3f}", o.object_id, o.kind, f"{n:.4f}", f"{e:.4f}", 0.0, 0.0])
    rows.sort(key=lambda r: (float(r[0]), r[1]))
    path = d / "truth.csv"
    _write(path, ["time", "object_id", "kind", "north", "east", "lat", "lon"], rows)
    (d / "origin.json").write_text(
        json.dumps({"lat": ORIGIN[0], "lon": ORIGIN[1], "height": ORIGIN[2]})
    )
    return path


def usv_pose(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """USV path: a slow arc from the origin; (n, e) m and heading deg."""
    s = t - EPOCH
    n = 0.5 * s
    e = 3.0 * np.sin(s / 10.0)
    heading = np.degrees(np.arctan2(0.3 * np.cos(s / 10.0), 0.5))
    return np.column_stack([n, e]), heading


def write_scene(d: Path, objects: list[Obj]) -> Path:
    t = EPOCH + np.arange(0, 31)
    p, h = usv_pose(t)
    moored = [
        {
            "id": o.object_id,
            "north": o.start[0],
            "east": o.start[1],
            "length": 8.0,
            "width": 3.0,
            "heading_deg": 20.0,
        }
        for o in objects
        if o.kind == "moored_boat"
    ]
    scene = {
        "walls": [
            [[-40.0, 45.0], [60.0, 45.0], [60.0, 50.0], [-40.0, 50.0]],
            [[60, -40], [60, 45]],
        ],
        "moored": moored,
        "usv": [
            [float(ti), float(n), float(e), float(hh)]
            for ti, (n, e), hh in zip(t, p, h, strict=True)
        ],
    }
    path = d / "scene.json"
    path.write_text(json.dumps(scene))
    return path


def write_run(
    out: Path,
    objects: list[Obj],
    tracks: list[TrackSpec],
    *,
    seed: int = 0,
    dt: float = 0.1,
    duration: float = 30.0,
    nis_scale: float = 1.0,
    lidar_miss: set[int] | None = None,
    frames: bool = False,
) -> Path:
    """Write the pipeline outputs of a run with the given tracks into `out`."""
    rng = np.random.default_rng(seed)
    out.mkdir(parents=True, exist_ok=True)
    by_id = {o.object_id: o for o in objects}
    times = EPOCH + np.arange(round(duration / dt) + 1) * dt
    rows, innov = [], []
    for tr in tracks:
        t = times[(times >= EPOCH + tr.t0 - 1e-9) & (times <= EPOCH + tr.t1 + 1e-9)]
        if tr.position is not None:
            p = np.tile(tr.position, (len(t), 1))
        else:
            p = by_id[tr.object_id].at(t) + np.asarray(tr.offset)
        if tr.noise is not None:
            p = p + rng.multivariate_normal([0, 0], tr.noise, len(t))
        c = tr.cov
        for ti, (n, e) in zip(t, p, strict=True):
            rows.append(
                [
                    f"{ti:.3f}",
                    tr.track_id,
                    f"{n:.6f}",
                    f"{e:.6f}",
                    0.01,
                    0.0,
                    0.0,
                    0.0,
                    c[0, 0],
                    c[0, 1],
                    c[1, 1],
                ]
            )
        nis = rng.chisquare(2, len(t)) * nis_scale
        for ti, v in zip(t, nis, strict=True):
            innov.append(
                [
                    f"{ti:.3f}",
                    tr.track_id,
                    "lidar" if rng.random() < 0.6 else "camera",
                    f"{v:.6f}",
                    2,
                ]
            )
    rows.sort(key=lambda r: (float(r[0]), r[1]))
    innov.sort(key=lambda r: (float(r[0]), r[1]))
    head = [
        "time",
        "track_id",
        "north",
        "east",
        "v_north",
        "v_east",
        "lat",
        "lon",
        "cov_nn",
        "cov_ne",
        "cov_ee",
    ]
    _write(out / "tracks.csv", head, rows)
    _write(out / "innovations.csv", ["time", "track_id", "sensor", "nis", "dof"], innov)
    # detections: LiDAR every frame of every non-moored object (except lidar_miss frames),
    # the camera at 2 Hz, plus clutter
    det = []
    miss = lidar_miss or set()
    for k, t in enumerate(times):
        for o in objects:
            if o.kind == "moored_boat":
                continue
            p = o.at(np.array([t]))[0]
            if k not in miss:
                q = p + rng.normal(0, 0.05, 2)
                det.append([f"{t:.3f}", "lidar", q[0], q[1], 0, 0, 0.01, 0, 0.01, ""])
            if k % 5 == 0:
                q = p + rng.normal(0, 0.4, 2)
                det.append([f"{t:.3f}", "camera", q[0], q[1], 0, 0, 0.2, 0.0, 0.3, 0.8])
        if rng.random() < 0.2:
            q = rng.uniform(-20, 40, 2)
            det.append([f"{t:.3f}", "lidar", q[0], q[1], 0, 0, 0.01, 0, 0.01, ""])
    _write(
        out / "detections.csv",
        ["time", "sensor", "north", "east", "lat", "lon", "cov_nn", "cov_ne", "cov_ee", "score"],
        det,
    )
    p, h = usv_pose(times)
    _write(
        out / "nav.csv",
        ["time", "north", "east", "lat", "lon", "heading_deg", "roll_deg", "pitch_deg"],
        [[f"{t:.3f}", n, e, 0, 0, hh, 0, 0] for t, (n, e), hh in zip(times, p, h, strict=True)],
    )
    if frames:
        import cv2

        fd = out / "camera_frames"
        fd.mkdir(exist_ok=True)
        listing = []
        for k, t in enumerate(times[::5]):
            img = np.zeros((120, 160, 3), np.uint8)
            img[:50] = (200, 150, 90)  # sky (BGR)
            img[50:] = (90, 60, 30)  # sea
            cv2.circle(img, (20 + 4 * k % 140, 80), 5, (0, 0, 255), -1)
            name = f"frame_{k:04d}.jpg"
            cv2.imwrite(str(fd / name), img)
            listing.append([f"{t:.3f}", name])
        _write(fd / "camera_frames.csv", ["time", "file"], listing)
    return out
