"""Files the pipeline writes as it runs (rows are written when they happen, nothing is kept
per message): tracks.csv, detections.csv, nav.csv, innovations.csv, camera_frames/ (+ its
camera_frames.csv), then tracks.geojson (from tracks.csv) and summary.json at the end.

Columns (NED metres at the origin, m/s, WGS84 degrees, m²; times UNIX s):
- tracks.csv: time,track_id,north,east,v_north,v_east,lat,lon,cov_nn,cov_ne,cov_ee
- detections.csv: time,sensor,north,east,lat,lon,cov_nn,cov_ne,cov_ee,score
- nav.csv: time,north,east,lat,lon,heading_deg,roll_deg,pitch_deg (one row per sensor message)
- innovations.csv: time,track_id,sensor,nis,dof,gate (gate: the tracker's gate probability P_G,
  which truncates every reported NIS; usvfast.metrics.consistency)
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from usvfast import geodesy

__all__ = ["OutputWriter", "write_geojson"]

TRACK_COLUMNS = "time,track_id,north,east,v_north,v_east,lat,lon,cov_nn,cov_ne,cov_ee".split(",")
DETECTION_COLUMNS = "time,sensor,north,east,lat,lon,cov_nn,cov_ne,cov_ee,score".split(",")
NAV_COLUMNS = "time,north,east,lat,lon,heading_deg,roll_deg,pitch_deg".split(",")
INNOVATION_COLUMNS = "time,track_id,sensor,nis,dof,gate".split(",")


def _f(x: float, digits: int = 6) -> str:
    return f"{x:.{digits}f}" if math.isfinite(x) else "nan"


class OutputWriter:
    """Streams the pipeline's rows into `out_dir` (created). origin (lat, lon, h) of NED;
    frames_hz / frame_width: camera thumbnails (0 Hz or None: none)."""

    def __init__(
        self,
        out_dir: Path | str,
        origin: tuple[float, float, float],
        *,
        frames_hz: float | None = 2.0,
        frame_width: int = 480,
        nis_gate: float = 1.0,
    ) -> None:
        """nis_gate: the tracker's gate probability P_G (innovations.csv "gate")."""
        self.out = Path(out_dir)
        self.nis_gate = float(nis_gate)
        self.out.mkdir(parents=True, exist_ok=True)
        self.origin = origin
        self._files: list[Any] = []
        self.tracks = self._csv("tracks.csv", TRACK_COLUMNS)
        self.detections = self._csv("detections.csv", DETECTION_COLUMNS)
        self.nav = self._csv("nav.csv", NAV_COLUMNS)
        self.innovations = self._csv("innovations.csv", INNOVATION_COLUMNS)
        self.frames_hz = frames_hz or 0.0
        self.frame_width = int(frame_width)
        self._last_frame = -math.inf
        self.frames = None
        if self.frames_hz > 0:
            (self.out / "camera_frames").mkdir(exist_ok=True)
            self.frames = self._csv("camera_frames/camera_frames.csv", ["time", "file"])
        self.rows = {"tracks": 0, "detections": 0, "nav": 0, "innovations": 0, "frames": 0}

    def _csv(self, name: str, columns: Sequence[str]) -> Any:
        fh = open(self.out / name, "w", newline="")
        self._files.append(fh)
        w = csv.writer(fh)
        w.writerow(columns)
        return w

    def _latlon(self, ne: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ne = np.asarray(ne, dtype=np.float64).reshape(-1, 2)
        if not len(ne):
            return np.zeros(0), np.zeros(0)
        lat, lon, _ = geodesy.ned2geodetic(ne[:, 0], ne[:, 1], np.zeros(len(ne)), *self.origin)
        return np.atleast_1d(lat), np.atleast_1d(lon)

    def write_nav(self, pose: Any) -> None:
        """One nav.csv row for a VesselPose."""
        lat, lon = self._latlon(np.array([[pose.north, pose.east]]))
        self.nav.writerow(
            [
                _f(pose.time),
                _f(pose.north, 4),
                _f(pose.east, 4),
                _f(lat[0], 9),
                _f(lon[0], 9),
                _f(math.degrees(pose.heading), 4),
                _f(math.degrees(pose.roll), 4),
                _f(math.degrees(pose.pitch), 4),
            ]
        )
        self.rows["nav"] += 1

    def write_detections(
        self, t: float, sensor: str, positions: np.ndarray, covs: np.ndarray, scores: np.ndarray
    ) -> None:
        """detections.csv rows: positions (k, 2), covs (k, 2, 2), scores (k,) (NaN: none)."""
        lat, lon = self._latlon(positions)
        for k in range(len(positions)):
            c = covs[k]
            self.detections.writerow(
                [
                    _f(t),
                    sensor,
                    _f(positions[k, 0], 4),
                    _f(positions[k, 1], 4),
                    _f(lat[k], 9),
                    _f(lon[k], 9),
                    _f(c[0, 0], 6),
                    _f(c[0, 1], 6),
                    _f(c[1, 1], 6),
                    _f(float(scores[k]), 4),
                ]
            )
        self.rows["detections"] += len(positions)

    def write_tracks(self, t: float, snapshot: Any) -> None:
        """tracks.csv rows of a tracker Snapshot (one per confirmed track)."""
        x, p = snapshot.states, snapshot.covariances
        lat, lon = self._latlon(x[:, [0, 2]])
        for k, tid in enumerate(snapshot.ids.tolist()):
            self.tracks.writerow(
                [
                    _f(t),
                    tid,
                    _f(x[k, 0], 4),
                    _f(x[k, 2], 4),
                    _f(x[k, 1], 5),
                    _f(x[k, 3], 5),
                    _f(lat[k], 9),
                    _f(lon[k], 9),
                    _f(p[k, 0, 0], 6),
                    _f(p[k, 0, 2], 6),
                    _f(p[k, 2, 2], 6),
                ]
            )
        self.rows["tracks"] += len(snapshot.ids)
        for tid, sensor, nis in snapshot.innovations:
            self.innovations.writerow(
                [_f(t), tid, ("lidar", "camera")[sensor], _f(nis, 5), 2, _f(self.nis_gate, 6)]
            )
        self.rows["innovations"] += len(snapshot.innovations)

    def write_frame(self, t: float, image: np.ndarray) -> None:
        """A downscaled jpeg of a camera frame, at most frames_hz per second."""
        import cv2

        if self.frames is None or t - self._last_frame < 1.0 / self.frames_hz - 1e-6:
            return
        self._last_frame = t
        h, w = image.shape[:2]
        scale = min(1.0, self.frame_width / w)
        small = cv2.resize(image, (max(1, round(w * scale)), max(1, round(h * scale))))
        name = f"frame_{self.rows['frames']:05d}.jpg"
        cv2.imwrite(str(self.out / "camera_frames" / name), small, [cv2.IMWRITE_JPEG_QUALITY, 80])
        self.frames.writerow([_f(t), name])
        self.rows["frames"] += 1

    def close(self) -> None:
        """Flush and close the CSV files, then write tracks.geojson from tracks.csv."""
        for fh in self._files:
            fh.close()
        self._files = []
        write_geojson(self.out / "tracks.csv", self.out / "tracks.geojson")


def write_geojson(tracks_csv: Path, out: Path) -> None:
    """One GeoJSON LineString per track (lon, lat order of RFC 7946), property track_id,
    reading tracks.csv row by row (one list of coordinates per track in memory)."""
    lines: dict[int, list[list[float]]] = {}
    with open(tracks_csv, newline="") as fh:
        for row in csv.DictReader(fh):
            lines.setdefault(int(row["track_id"]), []).append(
                [round(float(row["lon"]), 9), round(float(row["lat"]), 9)]
            )
    features = []
    for tid, coords in lines.items():
        geom = (
            {"type": "LineString", "coordinates": coords}
            if len(coords) > 1
            else {"type": "Point", "coordinates": coords[0]}
        )
        features.append({"type": "Feature", "properties": {"track_id": tid}, "geometry": geom})
    out.write_text(json.dumps({"type": "FeatureCollection", "features": features}))
