"""`usvfast bearing` on an image tracker's tracks.txt: one bearing series per track id
(Gorad et al. track boxes before the bearing fusion), checked against the fusion of the same
box centres given as a samples CSV, on the bundled encounter with AIS."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from typer.testing import CliRunner

from usvfast.bearing.camera import pixel_to_bearing
from usvfast.bearing.fusion import VISIBLE, fuse_bearings
from usvfast.bearing.io import read_cameras
from usvfast.bearing.sample import BUNDLED_DIR
from usvfast.bearing.tracks import looks_like_mot, track_bearings
from usvfast.cli import app
from usvfast.shore.mot import mot_rows, write_mot

FPS = 50.0


def _visible_rows():
    with open(BUNDLED_DIR / "samples.csv", encoding="utf-8") as fh:
        rows = [r for r in csv.DictReader(fh) if r["source"] == "1"]
    t = np.array([float(r["t"]) for r in rows])
    xy = np.array([[float(r["x_px"]), float(r["y_px"])] for r in rows])
    conf = np.array([float(r["confidence"]) for r in rows])
    return t, xy, conf


@pytest.fixture
def tracks_txt(tmp_path):
    t, xy, conf = _visible_rows()
    t0 = t[0]
    frames = np.round((t - t0) * FPS).astype(int) + 1
    boxes = np.column_stack([xy - 10, np.full((len(t), 2), 20.0)])
    rows = [mot_rows(f, [7], b[None], [c]) for f, b, c in zip(frames, boxes, conf, strict=True)]
    rows.append(mot_rows(3, [9], np.array([[100.0, 500, 30, 20]]), [0.5]))  # a one-box track
    rows += [mot_rows(5 + k, [4], np.array([[900.0 + k, 600, 30, 20]]), [0.9]) for k in range(6)]
    path = tmp_path / "tracks.txt"
    write_mot(path, np.concatenate(rows))
    return path, t0, frames, xy, conf


def test_tracks_give_one_bearing_series_per_id(tracks_txt):
    path, t0, frames, xy, conf = tracks_txt
    assert looks_like_mot(path) and not looks_like_mot(BUNDLED_DIR / "samples.csv")
    cam = read_cameras(BUNDLED_DIR / "cameras.json")[VISIBLE]
    tb = track_bearings(path, cam, fps=FPS, start_time=t0)
    assert tb.ids() == [4, 7, 9]
    m = tb.track_id == 7
    np.testing.assert_array_equal(tb.frame[m], frames)
    np.testing.assert_allclose(tb.times[m], t0 + (frames - 1) / FPS, rtol=0, atol=1e-6)
    want, _ = pixel_to_bearing(xy[:, 0], xy[:, 1], cam)
    np.testing.assert_allclose(tb.bearing_deg[m], want, atol=1e-9)  # box centres, 0.01 px
    np.testing.assert_allclose(tb.confidence[m], conf, atol=1e-4)
    with pytest.raises(ValueError, match="fps"):
        track_bearings(path, cam, fps=0.0)


def test_bearing_command_reads_tracks(tracks_txt, tmp_path):
    path, t0, frames, xy, _ = tracks_txt
    out = tmp_path / "out"
    res = CliRunner().invoke(
        app,
        [
            "bearing",
            str(path),
            str(BUNDLED_DIR / "ais.csv"),
            "--out",
            str(out),
            "--cameras",
            str(BUNDLED_DIR / "cameras.json"),
            "--tracks-fps",
            str(FPS),
            "--tracks-start",
            str(float(t0)),
        ],
    )
    assert res.exit_code == 0, res.output
    assert {p.name for p in out.iterdir()} == {
        "fused_track_4.csv",
        "fused_track_7.csv",
        "rmse_tracks.csv",
    }
    with open(out / "fused_track_7.csv", encoding="utf-8") as fh:
        fused = np.array([float(r["bearing_deg"]) for r in csv.DictReader(fh)])
    cam = read_cameras(BUNDLED_DIR / "cameras.json")[VISIBLE]
    b, _ = pixel_to_bearing(xy[:, 0], xy[:, 1], cam)
    ref = fuse_bearings(np.full(len(b), VISIBLE), t0 + (frames - 1) / FPS, b)
    np.testing.assert_allclose(fused, ref.bearing_deg, atol=1e-3)  # the CSV keeps 4 decimals
    with open(out / "rmse_tracks.csv", encoding="utf-8") as fh:
        rmse = {(r["track_id"], r["label"]): float(r["rmse_deg"]) for r in csv.DictReader(fh)}
    # the boat's track follows AIS to within a degree; the far box is not the AIS target
    assert rmse[("7", "fused KF + RTS")] < 1.0
    assert rmse[("7", "fused KF + RTS")] < rmse[("7", "visible (unfused)")]
