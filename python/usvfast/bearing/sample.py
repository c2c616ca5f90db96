"""Synthetic encounter for the bearing-fusion demo: own ship and target trajectories, AIS at
its ITU-R M.1371 reporting rate, and visible + thermal box centres projected through the
inverse of eq. (1) with pixel noise and missed detections.

The bundled files in `usvfast/data/bearing/` were written by

    python -m usvfast.bearing.sample --seed 2023 --out python/usvfast/data/bearing

and the same seed reproduces them byte for byte.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

from usvfast._angles import wrap_360_deg
from usvfast.bearing.ais import VesselTrack, ais_report_interval_s, relative_bearing_deg
from usvfast.bearing.camera import THERMAL_CAMERA, VISIBLE_CAMERA, BearingCamera, bearing_to_pixel
from usvfast.bearing.fusion import THERMAL, VISIBLE

DEFAULT_SEED = 2023
BUNDLED_DIR = Path(__file__).resolve().parent.parent / "data" / "bearing"
"""Directory of the bundled sample: samples.csv, ais.csv, cameras.json."""

EARTH_RADIUS_M = 6_371_008.8
KNOT_M_S = 1852.0 / 3600.0
START_TIME = 1_629_972_000.0  # 2021-08-26 10:00:00 UTC, the paper's second campaign day
# AIS position resolution: 1/10000 minute of arc.
AIS_RESOLUTION_DEG = 1.0 / 600_000.0


@dataclass(frozen=True)
class CameraRig:
    """A camera of the synthetic rig: calibration, frame rate (Hz), pan (degrees), white
    box-centre noise (pixels, 1σ in x and y), a slow horizontal wander of the box centre
    (Gauss–Markov, 1σ pixels, correlation time seconds: the box follows the ship's changing
    aspect, not its AIS antenna) and the detection probability per frame."""

    camera: BearingCamera
    rate_hz: float
    pan_deg: float
    noise_x_px: float
    noise_y_px: float
    wander_x_px: float
    wander_tau_s: float
    detection_probability: float


DEFAULT_RIG: Mapping[int, CameraRig] = {
    # 1920 px over 20°: 35 px ≈ 0.36° of box-centre jitter on a ship ~350 px long,
    # 10 px ≈ 0.1° of wander.
    VISIBLE: CameraRig(VISIBLE_CAMERA, 2.0, 0.0, 35.0, 10.0, 10.0, 10.0, 0.92),
    # 320 px over 19°: 4.5 px ≈ 0.27°, 1.5 px ≈ 0.09° of wander; the thermal camera is
    # panned towards the target.
    THERMAL: CameraRig(THERMAL_CAMERA, 4.0, 16.0, 4.5, 2.0, 1.5, 10.0, 0.92),
}


@dataclass(frozen=True)
class EncounterSample:
    """A generated encounter, exactly as written to disk (values rounded as in the files).

    Detections (k,): source ids, times (UNIX s), x_px/y_px box centres, confidence, pan_deg.
    true_bearing_deg / true_elevation_deg (k,): eq. (2) bearing from the exact positions
    and the depression angle of the target's centre, at each detection time.
    own: own-ship GNSS + gyro track (1 Hz, with headings); target_ais: the target's AIS
    reports. cameras: calibration per source id.
    """

    source: np.ndarray
    times: np.ndarray
    x_px: np.ndarray
    y_px: np.ndarray
    confidence: np.ndarray
    pan_deg: np.ndarray
    true_bearing_deg: np.ndarray
    true_elevation_deg: np.ndarray
    own: VesselTrack
    target_ais: VesselTrack
    cameras: Mapping[int, BearingCamera]


def _turning_path(
    t: np.ndarray, north0: float, east0: float, heading0_deg: float, turn_deg_s: float, speed: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """North, east (m) and heading (deg) of a vessel at constant speed (m/s) and turn rate."""
    heading = heading0_deg + turn_deg_s * t
    if turn_deg_s == 0.0:
        h = math.radians(heading0_deg)
        return north0 + speed * t * math.cos(h), east0 + speed * t * math.sin(h), heading
    radius = speed / math.radians(turn_deg_s)
    h0, h1 = math.radians(heading0_deg), np.radians(heading)
    north = north0 + radius * (np.sin(h1) - math.sin(h0))
    east = east0 + radius * (math.cos(h0) - np.cos(h1))
    return north, east, heading


def _gauss_markov(rng: np.random.Generator, t: np.ndarray, sigma: float, tau: float) -> np.ndarray:
    """Stationary first-order Gauss–Markov process (1σ `sigma`, correlation time `tau` s)."""
    out = np.empty(t.shape)
    out[0] = rng.normal(0.0, sigma)
    decay = np.exp(-np.diff(t) / tau)
    kicks = rng.normal(0.0, sigma, len(t) - 1) * np.sqrt(1.0 - decay**2)
    for k in range(1, len(t)):
        out[k] = decay[k - 1] * out[k - 1] + kicks[k - 1]
    return out


def _to_latlon(
    north: np.ndarray, east: np.ndarray, lat0: float, lon0: float
) -> tuple[np.ndarray, np.ndarray]:
    lat = lat0 + np.degrees(north / EARTH_RADIUS_M)
    lon = lon0 + np.degrees(east / (EARTH_RADIUS_M * math.cos(math.radians(lat0))))
    return lat, lon


def generate_encounter(
    seed: int = DEFAULT_SEED,
    *,
    duration_s: float = 240.0,
    rig: Mapping[int, CameraRig] = DEFAULT_RIG,
    origin_lat_deg: float = 59.80,
    origin_lon_deg: float = 24.85,
) -> EncounterSample:
    """Generate the synthetic encounter of the demo (reproducible from `seed`).

    Own ship: 20 kn, heading 190° turning 0.02°/s to starboard (the Helsinki–Tallinn route).
    Target: 3.2 km away at 52° to port, 12 kn, heading 185° turning 0.01°/s to port, so it is
    overtaken and its bearing drifts aft through both cameras' views. The target's AIS
    reports come every `ais_report_interval_s(12 kn)` = 10 s with 0.3 s jitter, positions
    rounded to the AIS resolution of 1/10000′; own GNSS/gyro at 1 Hz. Each camera frames at
    its rate; a frame yields a box centre with probability `detection_probability`, when the
    noisy centre falls inside the image, and (visible) outside a 12 s glare gap.
    """
    rng = np.random.default_rng(seed)
    own_speed, target_speed = 20.0 * KNOT_M_S, 12.0 * KNOT_M_S
    start_range, start_rel = 3200.0, -52.0

    def own_at(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return _turning_path(t, 0.0, 0.0, 190.0, 0.02, own_speed)

    true0 = math.radians(190.0 + start_rel)
    n0, e0 = start_range * math.cos(true0), start_range * math.sin(true0)

    def target_at(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return _turning_path(t, n0, e0, 185.0, -0.01, target_speed)

    def latlon(path: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        return _to_latlon(path[0], path[1], origin_lat_deg, origin_lon_deg)

    margin = 20.0
    # Own ship: GNSS + gyro at 1 Hz, 1e-7° and 0.01° resolution.
    t_own = np.arange(-margin, duration_s + margin + 0.5, 1.0)
    own_path = own_at(t_own)
    own_lat, own_lon = latlon(own_path)
    own = VesselTrack(
        np.round(START_TIME + t_own, 3),
        np.round(own_lat, 7),
        np.round(own_lon, 7),
        np.round(wrap_360_deg(own_path[2]), 2),
    )
    # Target AIS: nominal interval for its speed, random phase, small jitter.
    interval = ais_report_interval_s(12.0)
    t_ais = -margin + rng.uniform(0.0, interval) + np.arange(0.0, duration_s + 2 * margin, interval)
    t_ais = t_ais + rng.normal(0.0, 0.3, t_ais.shape)
    target_path = target_at(t_ais)
    tgt_lat, tgt_lon = latlon(target_path)
    target_ais = VesselTrack(
        np.round(START_TIME + t_ais, 3),
        np.round(np.round(tgt_lat / AIS_RESOLUTION_DEG) * AIS_RESOLUTION_DEG, 7),
        np.round(np.round(tgt_lon / AIS_RESOLUTION_DEG) * AIS_RESOLUTION_DEG, 7),
        np.round(wrap_360_deg(target_path[2])),
    )

    columns: dict[str, list[np.ndarray]] = {
        k: [] for k in ("src", "t", "x", "y", "c", "pan", "b", "e")
    }
    for sid, cam_rig in sorted(rig.items()):
        t_cam = rng.uniform(0.0, 1.0 / cam_rig.rate_hz) + np.arange(
            0.0, duration_s, 1.0 / cam_rig.rate_hz
        )
        t_cam = np.round(t_cam + rng.normal(0.0, 0.002, t_cam.shape), 3)
        own_p, tgt_p = own_at(t_cam), target_at(t_cam)
        (lat_o, lon_o), (lat_t, lon_t) = latlon(own_p), latlon(tgt_p)
        bearing = relative_bearing_deg(lat_o, lon_o, own_p[2], lat_t, lon_t)
        rng_m = np.hypot(tgt_p[0] - own_p[0], tgt_p[1] - own_p[1])
        # Camera 30 m above the sea, the box centre 12 m: depression angle (down positive).
        elevation = np.degrees(np.arctan2(30.0 - 12.0, rng_m))
        x, y = bearing_to_pixel(bearing, elevation, cam_rig.camera, pan_deg=cam_rig.pan_deg)
        x = np.round(
            x
            + _gauss_markov(rng, t_cam, cam_rig.wander_x_px, cam_rig.wander_tau_s)
            + rng.normal(0.0, cam_rig.noise_x_px, x.shape),
            1,
        )
        y = np.round(y + rng.normal(0.0, cam_rig.noise_y_px, y.shape), 1)
        keep = rng.uniform(size=t_cam.shape) < cam_rig.detection_probability
        keep &= (x >= 0) & (x < cam_rig.camera.width_px) & (y >= 0) & (y < cam_rig.camera.height_px)
        if sid == VISIBLE:
            keep &= ~((t_cam > 150.0) & (t_cam < 162.0))
        conf = np.round(rng.uniform(0.55, 0.95, t_cam.shape), 3)
        for key, arr in zip(
            ("src", "t", "x", "y", "c", "pan", "b", "e"),
            (
                np.full(t_cam.shape, sid),
                t_cam,
                x,
                y,
                conf,
                np.full(t_cam.shape, cam_rig.pan_deg),
                bearing,
                elevation,
            ),
            strict=True,
        ):
            columns[key].append(arr[keep])
    merged = {k: np.concatenate(v) for k, v in columns.items()}
    order = np.lexsort((merged["src"], merged["t"]))
    m = {k: v[order] for k, v in merged.items()}
    return EncounterSample(
        source=m["src"].astype(np.int64),
        times=START_TIME + m["t"],
        x_px=m["x"],
        y_px=m["y"],
        confidence=m["c"],
        pan_deg=m["pan"],
        true_bearing_deg=m["b"],
        true_elevation_deg=m["e"],
        own=own,
        target_ais=target_ais,
        cameras={sid: r.camera for sid, r in rig.items()},
    )


def write_encounter(sample: EncounterSample, out_dir: Path | str) -> list[Path]:
    """Write `samples.csv`, `ais.csv` and `cameras.json` (formats: `usvfast.bearing.io`) into
    `out_dir` (created if missing); returns the paths written."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    samples = out / "samples.csv"
    with samples.open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["source", "t", "x_px", "y_px", "confidence", "pan_deg"])
        for row in zip(
            sample.source,
            sample.times,
            sample.x_px,
            sample.y_px,
            sample.confidence,
            sample.pan_deg,
            strict=True,
        ):
            w.writerow(
                [
                    int(row[0]),
                    f"{row[1]:.3f}",
                    f"{row[2]:.1f}",
                    f"{row[3]:.1f}",
                    f"{row[4]:.3f}",
                    f"{row[5]:g}",
                ]
            )
    ais = out / "ais.csv"
    with ais.open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["vessel", "t", "lat_deg", "lon_deg", "heading_deg"])
        rows = []
        for name, track, fmt in (("own", sample.own, ".2f"), ("target", sample.target_ais, ".0f")):
            headings = cast(
                np.ndarray, track.heading_deg
            )  # both tracks are generated with headings
            for t, lat, lon, hdg in zip(
                track.times, track.lat_deg, track.lon_deg, headings, strict=True
            ):
                rows.append(
                    (t, name, [name, f"{t:.3f}", f"{lat:.7f}", f"{lon:.7f}", format(hdg, fmt)])
                )
        for _, _, row in sorted(rows, key=lambda r: (r[0], r[1])):
            w.writerow(row)
    cameras = out / "cameras.json"
    cameras.write_text(
        json.dumps({str(k): c.to_dict() for k, c in sorted(sample.cameras.items())}, indent=2)
        + "\n"
    )
    return [samples, ais, cameras]


def main(argv: list[str] | None = None) -> None:
    """`python -m usvfast.bearing.sample [--seed N] [--out DIR]`: regenerate the sample."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument(
        "--seed", type=int, default=DEFAULT_SEED, help="random seed (default %(default)s)"
    )
    parser.add_argument("--out", type=Path, default=BUNDLED_DIR, help="output directory")
    parser.add_argument("--duration", type=float, default=240.0, help="seconds of camera data")
    args = parser.parse_args(argv)
    for path in write_encounter(generate_encounter(args.seed, duration_s=args.duration), args.out):
        print(path)


if __name__ == "__main__":
    main()
