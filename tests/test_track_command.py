"""`usvfast track`: the Joyride preset on the real recording (constant velocity vs IMM
figures), CSV input equal to the .mat, and bad configurations / rows."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from usvfast.cli import app
from usvfast.datasets import load_joyride
from usvfast.metrics import track_quality
from usvfast.trackcmd import load_config, read_plots, run_tracking, tracker_from_config

from conftest import SHARED_DATA

JOYRIDE = SHARED_DATA / "joyride" / "joyride.mat"


def quality(cfg):
    plots = read_plots(JOYRIDE)
    res, _ = run_tracking(plots, cfg)
    return track_quality(plots.truth, res.scan, res.track_id, res.state[:, [0, 2]])


def test_joyride_preset_cv_imm_and_existence():
    # Tuned on Joyride itself (the only real set): in-sample figures (docs/tracker.md, Joyride).
    # Measured: CV only (joyride-cv) 21.10 m / 93.7 % / 1 fragment / 4 false tracks; IMM with the
    # turn rate in the state (joyride without existence) 20.43 / 96.6 / 1 / 4; IMM + existence
    # (joyride) 20.43 / 96.6 / 1 / 2.
    cfg = load_config("joyride")
    full = quality(cfg)
    imm = quality({k: v for k, v in cfg.items() if k != "existence"})
    cv = quality(load_config("joyride-cv"))
    for q in (cv, imm, full):
        assert q.fragments == 1 and q.distinct_tracks == 1
    assert full.coverage >= 0.96 and full.tracks_elsewhere <= 2 and full.rmse <= 20.5
    assert imm.coverage == full.coverage and imm.tracks_elsewhere > full.tracks_elsewhere
    assert cv.coverage < 0.95 and cv.rmse > full.rmse


def test_joyride_known_turn_presets():
    # The IMM of known-rate turns (named `joyride` before the turn rate went into the state):
    # measured 20.84 m / 96.2 % / 1 / 2, without existence 20.84 / 96.2 / 1 / 7;
    # joyride-accurate (same structure) 20.22 / 94.5 / 1 / 2.
    cfg = load_config("joyride-known-turns")
    full = quality(cfg)
    imm = quality({k: v for k, v in cfg.items() if k != "existence"})
    acc = quality(load_config("joyride-accurate"))
    for q in (imm, full, acc):
        assert q.fragments == 1 and q.distinct_tracks == 1
    assert full.coverage >= 0.96 and full.tracks_elsewhere <= 2 and full.rmse < 21.0
    assert imm.coverage == full.coverage and imm.tracks_elsewhere > full.tracks_elsewhere
    assert acc.rmse < 20.5 and acc.tracks_elsewhere <= 2 and acc.coverage > 0.94


def test_joyride_preset_turn_rate_in_the_state():
    # The shipped preset is the IMM with the turn rate in the state (CV, CV-high,
    # ConstantTurn EKF; tuned on Joyride itself, in-sample, then named `joyride-ct`): measured
    # 20.43 m / 96.6 % / 1 fragment / 2 false tracks, 96.6 % on each half; the turn rates of the
    # target's track stay within a boat's (|ω| < 0.3 rad/s).
    plots = read_plots(JOYRIDE)
    res, _ = run_tracking(plots, load_config("joyride"))
    assert res.state.shape[1] == 5
    q = track_quality(plots.truth, res.scan, res.track_id, res.state[:, [0, 2]])
    assert q.fragments == 1 and q.distinct_tracks == 1
    assert q.coverage >= 0.96 and q.rmse <= 20.5 and q.tracks_elsewhere <= 2
    target = res.track_id == q.counted_ids[np.isfinite(q.errors)][0]
    assert np.abs(res.state[target, 4]).max() < 0.3
    # With the IMM in the initiator too: the same figures (the target's track is confirmed at
    # its second plot; measured 20.43 m / 96.6 % / 1 / 2).
    cfg = load_config("joyride")
    res, _ = run_tracking(plots, {**cfg, "initiator": {**cfg["initiator"], "imm": True}})
    q2 = track_quality(plots.truth, res.scan, res.track_id, res.state[:, [0, 2]])
    assert (q2.fragments, q2.tracks_elsewhere, q2.coverage) == (1, 2, q.coverage)
    assert abs(q2.rmse - q.rmse) < 0.01


def test_command_writes_tracks_and_summary(tmp_path):
    out = tmp_path / "out"
    r = CliRunner().invoke(app, ["track", str(JOYRIDE), "--config", "joyride", "--out", str(out)])
    assert r.exit_code == 0, r.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scans"] == 238 and summary["fragments"] == 1
    with (out / "tracks.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == summary["track_rows"]
    rec = load_joyride(JOYRIDE)
    # Rows of the target's track lie near the truth at their scan time (north/east order).
    by_time = {float(t): i for i, t in enumerate(rec.times)}
    err = [
        np.hypot(
            float(r["north"]) - rec.target[by_time[float(r["time"])], 0],
            float(r["east"]) - rec.target[by_time[float(r["time"])], 2],
        )
        for r in rows
        if r["track_id"] == "0"
    ]
    assert np.median(err) < 30


def test_csv_input_equals_mat(tmp_path):
    rec = load_joyride(JOYRIDE)
    path = tmp_path / "plots.csv"
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time", "north", "east", "sensor"])
        for t, z in zip(rec.times, rec.measurements, strict=True):
            for n, e in z:
                w.writerow([repr(float(t)), repr(float(n)), repr(float(e)), 0])
        w.writerow(["1495196300.0", "nan", "3.0", 0])  # damaged rows are skipped and counted
        w.writerow(["oops", "1.0", "3.0", 0])
    a, b = read_plots(JOYRIDE), read_plots(path)
    assert b.skipped == 2
    cfg = load_config("joyride")
    ra, _ = run_tracking(a, cfg)
    # Every Joyride scan has plots, so the CSV holds the same scans.
    assert all(len(z) for z in rec.measurements) and len(b.times) == len(a.times)
    rb, _ = run_tracking(b, cfg)
    np.testing.assert_array_equal(ra.scan, rb.scan)
    np.testing.assert_array_equal(ra.state, rb.state)


def test_bad_configs_are_named(tmp_path):
    with pytest.raises(ValueError, match="unknown key"):
        tracker_from_config({"q": 1.0, "qq": 2.0})
    with pytest.raises(ValueError, match=r"tracker\.imm"):
        tracker_from_config({"imm": {"turn_rates": [0.1], "speed": 1}})
    with pytest.raises(ValueError, match="no preset"):
        load_config("nonexistent-preset")
    r = CliRunner().invoke(
        app, ["track", str(JOYRIDE), "--config", "nope", "--out", str(tmp_path / "o")]
    )
    assert r.exit_code == 2 and "no preset" in r.output
