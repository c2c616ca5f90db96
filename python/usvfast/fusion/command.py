"""`usvfast vts`: radar + AIS (+ camera) situational picture from files.

Inputs: `--radar` a Joyride `.mat` (NED plots and own ship; needs `--origin`), a `.csv` of
plots (time, range, bearing or time, north, east) or an NMEA log of ARPA targets (TTM/TLL);
`--ais` an AIS feed (tag blocks, a leading time column or the log's ZDA/RMC clock); `--own`
an NMEA log of the own ship (GGA/RMC/GLL positions, HDT/THS heading, else course over
ground); `--camera` a video with `--calibration` (camera YAML/JSON) and `--detections` (CSV
time,x1,y1,x2,y2 of image boxes). Outputs in `--out`: fused.csv, situation.png, overlay/*.jpg
(with a camera), summary.json.
"""

from __future__ import annotations

import csv
import json
import math
import time as _time
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from usvfast import geodesy
from usvfast.fusion.ais_feed import AisTargets, read_ais_feed
from usvfast.fusion.associate import Chi2Test, JCost
from usvfast.fusion.pipeline import FusedRow, OwnShip, TrackerConfig, VtsResult, run_vts
from usvfast.radar.readers import RadarPlots, plots_from_ned, read_radar_csv, read_radar_nmea

__all__ = ["load_own_nmea", "vts_command", "write_fused_csv"]

FUSED_COLUMNS = (
    "time",
    "track_id",
    "mmsi",
    "name",
    "north",
    "east",
    "lat",
    "lon",
    "v_north",
    "v_east",
    "pos_std",
    "source",
)


def _origin(text: str | None) -> tuple[float, float] | None:
    if text is None:
        return None
    try:
        lat, lon = (float(v) for v in text.split(","))
    except ValueError:
        raise typer.BadParameter(f"expected LAT,LON in degrees, got {text!r}") from None
    if not (abs(lat) <= 90 and abs(lon) <= 180):
        raise typer.BadParameter(f"LAT,LON out of range: {text!r}")
    return lat, lon


def load_own_nmea(path: Path, origin: tuple[float, float] | None) -> tuple[OwnShip, tuple]:
    """Own ship from an NMEA log: positions (GGA/RMC/GLL) in the plane at `origin` (default
    the first fix), heading from HDT/THS, else the course over ground. Returns (own, origin)."""
    from usvfast.nav.nmea import read_nmea

    log = read_nmea(path)
    p = log.positions
    ok = np.isfinite(p.lat_deg) & np.isfinite(p.lon_deg)
    if not ok.any():
        raise ValueError(f"own: no position fix in {path}")
    if origin is None:
        origin = (float(p.lat_deg[ok][0]), float(p.lon_deg[ok][0]))
    n, e, _ = geodesy.geodetic2ned(p.lat_deg[ok], p.lon_deg[ok], 0.0, origin[0], origin[1], 0.0)
    t = p.time[ok]
    h = log.headings
    src_t, src_h = (
        (h.time, h.heading_deg)
        if len(h.time)
        else (
            log.velocities.time,
            log.velocities.course_deg,
        )
    )
    good = np.isfinite(src_h)
    if good.any():
        rad = np.radians(src_h[good])
        head = np.degrees(
            np.arctan2(
                np.interp(t, src_t[good], np.sin(rad)), np.interp(t, src_t[good], np.cos(rad))
            )
        )
    else:
        head = np.full(len(t), np.nan)
    return OwnShip(t, n, e, head % 360.0), origin


def _load_radar(path: Path, origin) -> tuple[RadarPlots, OwnShip | None]:
    """Radar plots (and the own ship when the file carries it) by file type."""
    if path.suffix.lower() == ".mat":
        from usvfast.datasets import load_joyride

        rec = load_joyride(path)
        if origin is None:
            raise typer.BadParameter("--origin LAT,LON is required with NED radar plots (.mat)")
        own = OwnShip(
            rec.times,
            rec.ownship[:, 0],
            rec.ownship[:, 2],
            np.degrees(np.arctan2(rec.ownship[:, 3], rec.ownship[:, 1])) % 360.0,
        )
        return plots_from_ned(rec.times, rec.measurements), own
    if path.suffix.lower() == ".csv":
        return read_radar_csv(path), None
    return read_radar_nmea(path), None


def write_fused_csv(rows: list[FusedRow], names: dict[int, str], path: Path) -> None:
    """fused.csv: one row per target per scan (FUSED_COLUMNS); mmsi and name empty when none,
    track_id empty for AIS-only targets."""
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(FUSED_COLUMNS)
        for r in rows:
            w.writerow(
                [
                    f"{r.time:.3f}",
                    r.track_id if r.track_id >= 0 else "",
                    r.mmsi if r.mmsi >= 0 else "",
                    names.get(r.mmsi, "") if r.mmsi >= 0 else "",
                    f"{r.north:.2f}",
                    f"{r.east:.2f}",
                    f"{r.lat:.7f}",
                    f"{r.lon:.7f}",
                    f"{r.v_north:.3f}",
                    f"{r.v_east:.3f}",
                    f"{r.pos_std:.2f}",
                    r.source,
                ]
            )


def _camera_stage(
    res: VtsResult,
    own: OwnShip | None,
    video: Path,
    calibration: Path,
    detections: Path | None,
    out: Path,
    *,
    height: float,
    mount_ypr: str,
    video_start: float | None,
    gamma_max: float,
    max_frames: int,
) -> dict:
    """Project the fused targets into every frame, match detections, draw overlays; appends
    "+camera" to the sources of matched rows. The detections are also georeferenced in the
    camera's own level frame and tracked there (GNN), and their velocities against the fused
    targets' give the camera ↔ VTS rotation θ (`RotationCalibrator`; θ − own heading is the
    camera's yaw misalignment). Returns counts and θ."""
    import cv2

    from usvfast.camera import CameraModel, box_contact_points, georeference, mount_rotation
    from usvfast.fusion.picture import draw_overlay
    from usvfast.fusion.rotation import RotationCalibrator
    from usvfast.fusion.visual import match_detections, project_targets
    from usvfast.nav.video import VideoReader

    if own is None:
        raise typer.BadParameter("--camera needs the own-ship pose (--own or a .mat radar file)")
    cam = CameraModel.load(calibration)
    r_bc = mount_rotation([float(v) for v in mount_ypr.split(",")])
    boxes_by_time: dict[float, np.ndarray] = {}
    if detections is not None:
        d = np.atleast_2d(np.loadtxt(detections, delimiter=",", skiprows=1))
        for t in np.unique(d[:, 0]):
            boxes_by_time[float(t)] = d[d[:, 0] == t, 1:5]
    det_times = np.array(sorted(boxes_by_time))
    scan_times = res.scan_times
    by_scan: dict[float, list[int]] = {}
    for k, r in enumerate(res.rows):
        by_scan.setdefault(r.time, []).append(k)
    (out / "overlay").mkdir(exist_ok=True)
    start = video_start if video_start is not None else float(scan_times[0])
    n_frames = n_matched = 0
    cam_tracker = _camera_tracker()
    calib = RotationCalibrator()
    heading_offsets: list[float] = []
    for frame in VideoReader(video, start_time=start):
        if max_frames and n_frames >= max_frames:
            break
        s = int(np.searchsorted(scan_times, frame.time, side="right")) - 1
        if s < 0:
            continue
        idx = by_scan.get(float(scan_times[s]), [])
        on, oe, head = own.at(frame.time)
        ne = np.array([[res.rows[k].north, res.rows[k].east] for k in idx]).reshape(-1, 2)
        proj = project_targets(
            ne,
            cam,
            own_ne=(float(on), float(oe)),
            heading=math.radians(float(head) if np.isfinite(head) else 0.0),
            height=height,
            mount_rotation=r_bc,
        )
        boxes = np.zeros((0, 4))
        if len(det_times):
            j = int(np.argmin(np.abs(det_times - frame.time)))
            if abs(det_times[j] - frame.time) < 0.5:
                boxes = boxes_by_time[float(det_times[j])]
        pairs, _ = match_detections(proj, cam, boxes, gamma_max_deg=gamma_max)
        if len(boxes):
            geo = georeference(box_contact_points(boxes), cam, height=height, mount_rotation=r_bc)
            z = geo.positions[geo.valid]
        else:
            z = np.zeros((0, 2))
        ct = cam_tracker.step(frame.time - start, z)
        ids = [res.rows[k].track_id * 10**9 + max(res.rows[k].mmsi, 0) for k in idx]
        vts_v = np.array([[res.rows[k].v_north, res.rows[k].v_east] for k in idx]).reshape(-1, 2)
        calib.add(ct.ids, ct.states[:, [1, 3]], ids, vts_v)
        if np.isfinite(head):
            heading_offsets.append(float(head))
        for ti, _bi in pairs:
            row = res.rows[idx[ti]]
            if not row.source.endswith("+camera"):
                res.rows[idx[ti]] = _with_source(row, row.source + "+camera")
            n_matched += 1
        labels = [
            f"{_label(res.rows[k])} {proj.range_m[i]:.0f} m {proj.bearing_deg[i]:.0f} deg"
            for i, k in enumerate(idx)
        ]
        assert frame.image is not None  # frames are read decoded
        img = draw_overlay(frame.image, proj.pixels, labels, boxes)
        cv2.imwrite(str(out / "overlay" / f"{frame.index:06d}.jpg"), img)
        n_frames += 1
    theta, spread, n = calib.estimate()
    out_d: dict = {"frames": n_frames, "camera_matches": n_matched}
    out_d["camera_vts_rotation"] = {
        "theta_deg": math.degrees(theta) if n else None,
        "spread_deg": math.degrees(spread) if n else None,
        "samples": n,
        "matches": len(calib.matches()),
        "own_heading_deg": float(np.mean(heading_offsets)) if heading_offsets else None,
    }
    return out_d


def _camera_tracker() -> Any:
    """GNN tracker of camera detections in the camera's level frame (forward, starboard m)."""
    from usvfast import tracking as tk
    from usvfast.kalman import constant_velocity_2d

    return tk.Tracker(
        motion_model=constant_velocity_2d(0.5),
        sensors=[tk.Sensor.position(noise_std=5.0)],
        association=tk.GNN(missed_distance=5.0),
        deleter=tk.StepsSinceUpdate(4),
        initiator=tk.MultiMeasurementInitiator(
            prior_state=np.zeros(4),
            prior_covariance=np.diag([0.0, 25.0, 0.0, 25.0]),
            min_points=3,
            missed_distance=5.0,
        ),
    )


def _label(r: FusedRow) -> str:
    return str(r.mmsi) if r.mmsi >= 0 else f"T{r.track_id}"


def _with_source(r: FusedRow, source: str) -> FusedRow:
    from dataclasses import replace

    return replace(r, source=source)


def vts_command(
    out: Annotated[Path, typer.Option(help="Output directory.")],
    radar: Annotated[
        Path | None,
        typer.Option(help="Radar plots: Joyride .mat, .csv, or NMEA log of TTM/TLL targets."),
    ] = None,
    ais: Annotated[Path | None, typer.Option(help="AIS feed (NMEA AIVDM/AIVDO log).")] = None,
    own: Annotated[Path | None, typer.Option(help="Own-ship NMEA log (GGA/RMC, HDT).")] = None,
    origin: Annotated[
        str | None, typer.Option(help="LAT,LON (deg) of the NED plane; default: first fix.")
    ] = None,
    method: Annotated[str, typer.Option(help="Radar–AIS test: j (paper §1.3) or chi2.")] = "j",
    window: Annotated[int, typer.Option(help="Association window N, scans.")] = 8,
    j_set: Annotated[float, typer.Option(help="J acceptance threshold J_set.")] = 2.5,
    polar: Annotated[str, typer.Option(help="Polar plot update: ekf, ukf or converted.")] = "ekf",
    range_std: Annotated[float, typer.Option(help="Radar range noise, m.")] = 10.0,
    bearing_std: Annotated[float, typer.Option(help="Radar bearing noise, deg.")] = 1.0,
    camera: Annotated[Path | None, typer.Option(help="Camera video.")] = None,
    calibration: Annotated[Path | None, typer.Option(help="Camera calibration YAML/JSON.")] = None,
    detections: Annotated[
        Path | None, typer.Option(help="Image detections CSV: time,x1,y1,x2,y2 (px).")
    ] = None,
    camera_height: Annotated[float, typer.Option(help="Camera height above water, m.")] = 10.0,
    mount_ypr: Annotated[str, typer.Option(help="Camera mount yaw,pitch,roll, deg.")] = "0,0,0",
    video_start: Annotated[
        float | None, typer.Option(help="UNIX time of the first video frame.")
    ] = None,
    gamma_max: Annotated[float, typer.Option(help="Visual match angle γ_max, deg.")] = 2.0,
    max_frames: Annotated[int, typer.Option(help="Stop the overlays after N frames (0 all).")] = 0,
) -> None:
    """Fuse radar plots and AIS into one picture; write fused.csv, situation.png, summary."""
    from rich.progress import Progress

    if radar is None and ais is None:
        raise typer.BadParameter("give --radar, --ais or both")
    if camera is not None and calibration is None:
        raise typer.BadParameter("--camera needs --calibration")
    if polar not in ("ekf", "ukf", "converted"):
        raise typer.BadParameter(f"--polar: expected ekf, ukf or converted, got {polar!r}")
    if method not in ("j", "chi2"):
        raise typer.BadParameter(f"--method: expected j or chi2, got {method!r}")
    out.mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}
    t0 = _time.perf_counter()
    org = _origin(origin)
    own_ship = None
    if own is not None:
        own_ship, org = load_own_nmea(own, org)
    plots, radar_own = _load_radar(radar, org) if radar is not None else (None, None)
    own_ship = own_ship or radar_own
    feed = read_ais_feed(ais) if ais is not None else None
    if org is None:
        if feed is None:
            raise typer.BadParameter("--origin is needed: no own-ship track or AIS to take it from")
        p = feed.log.positions
        ok = np.isfinite(p.lat_deg) & np.isfinite(p.time)
        org = (float(p.lat_deg[ok][0]), float(p.lon_deg[ok][0]))
    targets = AisTargets(feed, org) if feed is not None else None
    timings["read"] = _time.perf_counter() - t0
    if plots is None:
        assert feed is not None  # --radar or --ais was given
        times = np.unique(np.round(feed.log.positions.time[np.isfinite(feed.log.positions.time)]))
        plots = _empty_plots(times)
    test = JCost(j_set=j_set) if method == "j" else Chi2Test()
    with Progress(transient=True) as bar:
        task = bar.add_task("fusing scans", total=None)
        res = run_vts(
            plots,
            targets,
            own_ship,
            origin=org,
            method=test,
            window=window,
            tracker=TrackerConfig(polar=polar, range_std=range_std, bearing_std_deg=bearing_std),  # pyright: ignore[reportArgumentType]  # (checked above)
            progress=lambda done, total: bar.update(task, completed=done, total=total),
        )
    timings.update({k: v for k, v in res.timings.items() if k != "read"})
    summary: dict = {}
    if camera is not None:
        assert calibration is not None  # checked above
        t1 = _time.perf_counter()
        summary |= _camera_stage(
            res,
            own_ship,
            camera,
            calibration,
            detections,
            out,
            height=camera_height,
            mount_ypr=mount_ypr,
            video_start=video_start,
            gamma_max=gamma_max,
            max_frames=max_frames,
        )
        timings["camera"] = _time.perf_counter() - t1
    t2 = _time.perf_counter()
    write_fused_csv(res.rows, res.names, out / "fused.csv")
    from usvfast.fusion.picture import situation_picture

    situation_picture(res, out / "situation.png")
    timings["write"] = _time.perf_counter() - t2
    tracks = {r.track_id for r in res.radar_rows}
    starts = [a for a in res.associations if a[3] == "start"]
    summary |= {
        "origin": list(org),
        "scans": len(res.scan_times),
        "radar_plots": len(res.plots) if radar is not None else 0,
        "radar_tracks": len(tracks),
        "ais_targets": len({r.mmsi for r in res.ais_rows}),
        "associations": [
            {"time": a[0], "track_id": a[1], "mmsi": a[2], "event": a[3]} for a in res.associations
        ],
        "identified_tracks": sorted({a[1] for a in starts}),
        "method": method,
        "timings_s": {k: round(v, 4) for k, v in timings.items()},
    }
    if feed is not None:
        log = feed.log
        summary["ais_counts"] = {
            "messages": log.n_messages,
            "damaged": log.n_damaged,
            "incomplete": log.n_incomplete,
            "untimed": feed.n_untimed,
            "bad_tag_block": feed.n_bad_tag,
        }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    typer.echo(
        f"scans {summary['scans']}, radar plots {summary['radar_plots']}, radar tracks "
        f"{summary['radar_tracks']}, AIS targets {summary['ais_targets']}, associations "
        f"{len(starts)} ({', '.join(f'T{a[1]}={a[2]}' for a in starts) or 'none'})"
    )
    typer.echo("time per stage: " + ", ".join(f"{k} {v:.3f} s" for k, v in timings.items()))
    typer.echo(f"wrote {out / 'fused.csv'}, {out / 'situation.png'}, {out / 'summary.json'}")


def _empty_plots(times: np.ndarray) -> RadarPlots:
    """A scan schedule without plots (AIS-only runs): one empty scan per time."""
    nan = np.full(len(times), np.nan)
    return RadarPlots(
        time=times.astype(float),
        range_m=nan,
        bearing_deg=nan,
        bearing_true=np.ones(len(times), bool),
        lat_deg=nan,
        lon_deg=nan,
        north=nan,
        east=nan,
        target_number=np.full(len(times), -1, np.int64),
        speed=nan,
        course_deg=nan,
    )
