"""`usvfast vts` end to end: Joyride + generated AIS (fused.csv columns and sources, the
picture, the summary), the real GPSD Saab R4 AIS log through the same command, a polar radar
CSV with an own-ship NMEA log and a camera video with detections (overlays, "+camera"), and
bad input with clear errors."""

from __future__ import annotations

import csv
import json
import math
from functools import reduce
from operator import xor
from pathlib import Path

import aisgen as G
import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from usvfast import geodesy
from usvfast._damage import DamagedRecordsWarning
from usvfast.camera import CameraModel, mount_rotation
from usvfast.cli import app
from usvfast.datasets import load_joyride
from usvfast.fusion.visual import project_targets

from conftest import SHARED_DATA

runner = CliRunner()
JOYRIDE = SHARED_DATA / "joyride" / "joyride.mat"


def _nmea(body: str) -> str:
    return f"${body}*{reduce(xor, body.encode(), 0):02X}"


def test_joyride_with_generated_ais(tmp_path):
    lines, _ = G.joyride_scene(load_joyride(JOYRIDE), seed=1)
    ais = tmp_path / "ais.nmea"
    ais.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    origin = ",".join(str(v) for v in G.JOYRIDE_ORIGIN)
    r = runner.invoke(
        app,
        ["vts", "--radar", str(JOYRIDE), "--ais", str(ais), "--origin", origin, "--out", str(out)],
    )
    assert r.exit_code == 0, r.output
    assert "associations 1 (T0=257000001)" in r.output and "time per stage" in r.output
    with (out / "fused.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0])[:8] == ["time", "track_id", "mmsi", "name", "north", "east", "lat", "lon"]
    assert {r["source"] for r in rows} == {"radar", "ais", "radar+ais"}
    fused = [r for r in rows if r["source"] == "radar+ais"]
    assert {r["mmsi"] for r in fused} == {"257000001"} and fused[0]["name"] == "JOYRIDE"
    assert all(r["mmsi"] == "" for r in rows if r["source"] == "radar")
    n, e = float(fused[0]["north"]), float(fused[0]["east"])
    lat, _, _ = geodesy.ned2geodetic(n, e, 0.0, *G.JOYRIDE_ORIGIN, 0.0)
    assert float(fused[0]["lat"]) == pytest.approx(lat, abs=1e-7)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["identified_tracks"] == [0] and summary["ais_targets"] == 3
    assert set(summary["timings_s"]) >= {"read", "track", "associate+fuse", "write"}
    assert (out / "situation.png").stat().st_size > 20000


def test_gpsd_saab_log_through_the_same_command(tmp_path):
    log = SHARED_DATA / "nmea" / "saab-r4.log"
    out = tmp_path / "out"
    r = runner.invoke(app, ["vts", "--ais", str(log), "--own", str(log), "--out", str(out)])
    assert r.exit_code == 0, r.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["ais_targets"] == 1 and summary["radar_tracks"] == 0
    assert summary["ais_counts"]["untimed"] == 0
    with (out / "fused.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert {r["mmsi"] for r in rows} == {"244707571"} and {r["source"] for r in rows} == {"ais"}


T0 = 1_700_000_000.0  # 2023-11-14 22:13:20 UTC
ORIGIN = (59.9, 10.7)
MOUNT = mount_rotation((-20.0, 0.0, 0.0))
CAM = CameraModel(np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]]), np.zeros(5), (640, 480))


def _target(t):
    """A vessel 600 m ahead (north) of the own ship, crossing east at 4 m/s."""
    return np.array([600.0, -100.0 + 4.0 * (t - T0)])


def _polar_scene(tmp_path: Path):
    rng = np.random.default_rng(2)
    times = np.arange(T0, T0 + 120.0, 2.5)
    radar = tmp_path / "radar.csv"
    with radar.open("w") as fh:
        fh.write("time,range,bearing\n")
        for t in times:
            n, e = _target(t) + rng.normal(0, 5, 2)
            fh.write(f"{t:.2f},{math.hypot(n, e):.1f},{math.degrees(math.atan2(e, n)) % 360:.2f}\n")
            if rng.random() < 0.3:
                fh.write(f"{t:.2f},{rng.uniform(200, 2000):.1f},{rng.uniform(0, 360):.2f}\n")
    lat0, lon0 = ORIGIN
    own = tmp_path / "own.nmea"
    lat_s = f"{int(lat0):02d}{(lat0 % 1) * 60:07.4f}"
    lon_s = f"{int(lon0):03d}{(lon0 % 1) * 60:07.4f}"
    with own.open("w") as fh:
        for k in range(0, 130, 1):
            hh, mm, ss = 22, 13 + (20 + k) // 60, (20 + k) % 60
            fh.write(
                _nmea(f"GPRMC,{hh:02d}{mm:02d}{ss:02d}.00,A,{lat_s},N,{lon_s},E,0.0,0.0,141123,,,A")
                + "\n"
            )
            fh.write(_nmea("HEHDT,20.0,T") + "\n")
    v = G.straight(259000001, "CROSSER", T0 - 30.0, T0 + 150.0, _target(T0 - 30.0), (0.0, 4.0))
    ais = tmp_path / "ais.nmea"
    ais.write_text("\n".join(G.feed(G.ais_lines(v, ORIGIN, rng, loss=0.0))) + "\n")
    return radar, own, ais


def test_polar_csv_own_nmea_and_camera_overlays(tmp_path):
    radar, own, ais = _polar_scene(tmp_path)
    calib = tmp_path / "camera.yaml"
    CAM.save(calib)
    video = tmp_path / "cam.avi"
    fps, start = 2.0, T0 + 50.0
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), fps, (640, 480))
    det = tmp_path / "det.csv"
    with det.open("w") as fh:
        fh.write("time,x1,y1,x2,y2\n")
        for k in range(16):
            t = start + k / fps
            writer.write(np.full((480, 640, 3), 90, np.uint8))
            # Own heading 20 deg, camera turned 20 deg to port: it looks north. The box
            # stands on the waterline point.
            pose = dict(own_ne=(0, 0), heading=math.radians(20.0), height=8.0, mount_rotation=MOUNT)
            u, v = project_targets(_target(t)[None], CAM, **pose).pixels[0]
            fh.write(f"{t:.3f},{u - 15:.1f},{v - 16:.1f},{u + 15:.1f},{v:.1f}\n")
    writer.release()
    out = tmp_path / "out"
    args = ["vts", "--radar", str(radar), "--ais", str(ais), "--own", str(own), "--out", str(out)]
    args += [
        "--origin",
        f"{ORIGIN[0]},{ORIGIN[1]}",
        "--camera",
        str(video),
        "--calibration",
        str(calib),
    ]
    args += ["--detections", str(det), "--camera-height", "8", "--video-start", str(start)]
    args += ["--mount-ypr=-20,0,0", "--polar", "ukf", "--range-std", "5", "--bearing-std", "0.5"]
    r = runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    with (out / "fused.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    sources = {r["source"] for r in rows}
    assert "radar+ais+camera" in sources, sources
    matched = [r for r in rows if r["source"].endswith("+camera")]
    assert {r["mmsi"] for r in matched} == {"259000001"}
    assert len(list((out / "overlay").glob("*.jpg"))) == 16
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"] == 16 and summary["camera_matches"] >= 14
    # Camera tracks in the camera's level frame against the fused velocities: theta is the
    # own heading (the camera frame turns with the ship).
    rot = summary["camera_vts_rotation"]
    assert rot["matches"] == 1 and rot["samples"] >= 5
    assert abs(rot["theta_deg"] - 20.0) < 3.0 and rot["spread_deg"] < 3.0


def test_bad_input_is_a_clear_error(tmp_path):
    unknown = tmp_path / "radar.nmea"
    unknown.write_text(_nmea("RAXYZ,1,2") + "\n")
    with pytest.warns(DamagedRecordsWarning, match="unknown radar sentence"):
        r = runner.invoke(app, ["vts", "--radar", str(unknown), "--out", str(tmp_path / "o")])
    assert isinstance(r.exception, ValueError) and "unknown radar sentences" in str(r.exception)
    r = runner.invoke(app, ["vts", "--out", str(tmp_path / "o")])
    assert r.exit_code != 0 and "--radar" in r.output
    r = runner.invoke(app, ["vts", "--radar", str(JOYRIDE), "--out", str(tmp_path / "o")])
    assert r.exit_code != 0 and "--origin" in r.output
    r = runner.invoke(
        app,
        ["vts", "--ais", str(SHARED_DATA / "nmea" / "sample.aivdm"), "--out", str(tmp_path / "o")],
    )
    assert isinstance(r.exception, ValueError) and "receive time" in str(r.exception)
