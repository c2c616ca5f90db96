"""Bearing files and commands: the bundled sample (reproducible, readable), CSV readers with
damaged rows, `usvfast bearing` and `usvfast bearing-demo` end to end."""

from __future__ import annotations

import csv
import filecmp
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from usvfast.bearing import (
    VISIBLE_CAMERA,
    bearing_rmse_table,
    fuse_bearings,
    pixel_to_bearing,
    reference_bearing_deg,
)
from usvfast.bearing.io import (
    FUSION_COLUMNS,
    PAPER_CAMERAS,
    SkippedRowsWarning,
    read_ais,
    read_bearing_samples,
    read_cameras,
)
from usvfast.bearing.sample import BUNDLED_DIR, DEFAULT_SEED, generate_encounter, main
from usvfast.cli import app

runner = CliRunner()
SAMPLES, AIS, CAMERAS = (BUNDLED_DIR / n for n in ("samples.csv", "ais.csv", "cameras.json"))


def read_rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def test_bundled_sample_is_reproducible_from_its_seed(tmp_path):
    main(["--seed", str(DEFAULT_SEED), "--out", str(tmp_path)])
    for name in ("samples.csv", "ais.csv", "cameras.json"):
        assert filecmp.cmp(tmp_path / name, BUNDLED_DIR / name, shallow=False), name
    main(["--seed", "7", "--out", str(tmp_path / "other")])
    assert not filecmp.cmp(tmp_path / "other" / "samples.csv", SAMPLES, shallow=False)


def test_bundled_files_read_back_as_generated():
    gen = generate_encounter(DEFAULT_SEED)
    samples = read_bearing_samples(SAMPLES, read_cameras(CAMERAS))
    assert samples.skipped == 0
    np.testing.assert_array_equal(samples.source, gen.source)
    np.testing.assert_allclose(samples.times, gen.times, atol=1e-6, rtol=0)
    np.testing.assert_allclose(samples.confidence, gen.confidence)
    for sid, cam in gen.cameras.items():
        m = gen.source == sid
        b = pixel_to_bearing(gen.x_px[m], gen.y_px[m], cam, pan_deg=gen.pan_deg[m]).bearing_deg
        np.testing.assert_allclose(samples.bearing_deg[m], b, atol=1e-9)
    ais = read_ais(AIS)
    np.testing.assert_allclose(ais.own.lat_deg, gen.own.lat_deg, atol=1e-12)
    np.testing.assert_allclose(ais.own.heading_deg, gen.own.heading_deg, atol=1e-12)
    np.testing.assert_allclose(ais.target.lon_deg, gen.target_ais.lon_deg, atol=1e-12)
    assert read_cameras(CAMERAS) == dict(PAPER_CAMERAS)


def test_bundled_sample_realism():
    gen = generate_encounter(DEFAULT_SEED)
    # AIS every ~10 s (Class A, 12 kn), own ship at 1 Hz, both covering all camera frames
    assert 9.0 < np.median(np.diff(gen.target_ais.times)) < 11.0
    assert np.allclose(np.diff(gen.own.times), 1.0)
    assert gen.target_ais.times[0] < gen.times[0] and gen.target_ais.times[-1] > gen.times[-1]
    # cameras at their own rates (2 Hz visible, 4 Hz thermal) with missed frames
    for sid, rate in ((1, 2.0), (2, 4.0)):
        t = gen.times[gen.source == sid]
        assert np.median(np.diff(t)) == pytest.approx(1.0 / rate, abs=0.01)
        assert np.max(np.diff(t)) > 3.0 / rate
    # boxes inside the image; the bearing sweeps across both views
    vis = gen.source == 1
    assert np.all((gen.x_px[vis] >= 0) & (gen.x_px[vis] < VISIBLE_CAMERA.width_px))
    assert np.ptp(gen.true_bearing_deg) > 15.0


def test_fusion_beats_single_sources_on_the_bundled_sample():
    samples = read_bearing_samples(SAMPLES, read_cameras(CAMERAS))
    ais = read_ais(AIS)
    fused = fuse_bearings(samples.source, samples.times, samples.bearing_deg, samples.confidence)
    ref = reference_bearing_deg(fused.times, ais.own, ais.target)
    rows = {r.label: r.rmse_deg for r in bearing_rmse_table(fused, ref)}
    best_single = min(rows["visible (unfused)"], rows["thermal (unfused)"])
    assert rows["fused KF + RTS"] < rows["fused KF"] < best_single
    assert rows["fused KF + RTS"] < 0.5 * best_single


def test_cli_bearing_end_to_end(tmp_path):
    out = tmp_path / "run"
    result = runner.invoke(
        app, ["bearing", str(SAMPLES), str(AIS), "--out", str(out), "--cameras", str(CAMERAS)]
    )
    assert result.exit_code == 0, result.output
    for label in ("visible (unfused)", "thermal (unfused)", "fused KF + RTS"):
        assert label in result.output
    rows = read_rows(out / "fused_bearing.csv")
    assert tuple(rows[0]) == FUSION_COLUMNS
    samples = read_bearing_samples(SAMPLES, read_cameras(CAMERAS))
    assert len(rows) == len(samples.times)
    fused = fuse_bearings(samples.source, samples.times, samples.bearing_deg, samples.confidence)
    np.testing.assert_allclose(
        [float(r["bearing_deg"]) for r in rows], fused.bearing_deg, atol=1e-4
    )
    np.testing.assert_allclose(
        [float(r["bearing_rate_deg_s"]) for r in rows], fused.bearing_rate_deg_s, atol=1e-5
    )
    rmse = {r["label"]: float(r["rmse_deg"]) for r in read_rows(out / "rmse.csv")}
    assert rmse["fused KF + RTS"] < min(rmse["visible (unfused)"], rmse["thermal (unfused)"])
    # the printed table shows the same numbers
    printed = re.search(r"fused KF \+ RTS\s*│\s*([0-9.]+)", result.output)
    assert printed and float(printed.group(1)) == pytest.approx(rmse["fused KF + RTS"], abs=1e-3)
    png = (out / "bearing.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000


def test_cli_demo_writes_into_out(tmp_path):
    result = runner.invoke(app, ["bearing-demo", "--out", str(tmp_path / "demo")])
    assert result.exit_code == 0, result.output
    assert "fused KF + RTS" in result.output
    for name in ("fused_bearing.csv", "rmse.csv", "bearing.png"):
        assert (tmp_path / "demo" / name).stat().st_size > 0


def test_cli_bearing_csv_of_bearings(tmp_path):
    samples = tmp_path / "bearings.csv"
    gen = generate_encounter(3, duration_s=60.0)
    with samples.open("w") as f:
        f.write("t,source,bearing_deg,confidence\n")
        for t, s, b, c in zip(
            gen.times, gen.source, gen.true_bearing_deg, gen.confidence, strict=True
        ):
            f.write(f"{t:.3f},{s},{b:.4f},{c}\n")
    ais = tmp_path / "ais.csv"
    shutil.copy(AIS, ais)
    result = runner.invoke(app, ["bearing", str(samples), str(ais), "--out", str(tmp_path / "o")])
    assert result.exit_code == 0, result.output
    rmse = {r["label"]: float(r["rmse_deg"]) for r in read_rows(tmp_path / "o" / "rmse.csv")}
    # noise-free bearings: only the 1e-4° rounding and the AIS interpolation remain
    assert rmse["visible (unfused)"] < 0.01 and rmse["thermal (unfused)"] < 0.01


def damaged_copy(tmp_path: Path) -> tuple[Path, int]:
    lines = SAMPLES.read_text().splitlines()
    bad = [
        "1,1629972010.000,abc,300.0,0.9,0",  # not a number
        "3,1629972010.100,100.0,300.0,0.9,0",  # unknown source
        "2,1629972010.200,100.0,300.0,1.7,0",  # confidence > 1
        "2,nan,100.0,100.0,0.8,16",  # non-finite time
        "1,1629972010.300,100.0",  # too few fields
        "2,1629972010.400,100.0,100.0,0.8,16,99",  # too many fields
    ]
    path = tmp_path / "damaged.csv"
    path.write_text("\n".join([lines[0], *lines[1:50], *bad, *lines[50:]]) + "\n")
    return path, len(bad)


def test_reader_skips_and_counts_bad_rows(tmp_path):
    path, n_bad = damaged_copy(tmp_path)
    with pytest.warns(SkippedRowsWarning, match=f"skipped {n_bad} bad row"):
        samples = read_bearing_samples(path, read_cameras(CAMERAS))
    clean = read_bearing_samples(SAMPLES, read_cameras(CAMERAS))
    assert samples.skipped == n_bad
    np.testing.assert_array_equal(samples.times, clean.times)  # nothing valid lost
    np.testing.assert_array_equal(samples.bearing_deg, clean.bearing_deg)


def test_reader_sorts_by_time_and_skips_bad_ais_rows(tmp_path):
    lines = SAMPLES.read_text().splitlines()
    shuffled = tmp_path / "shuffled.csv"
    shuffled.write_text("\n".join([lines[0], *reversed(lines[1:])]) + "\n")
    samples = read_bearing_samples(shuffled, read_cameras(CAMERAS))
    assert np.all(np.diff(samples.times) >= 0)
    ais_lines = AIS.read_text().splitlines()
    ais = tmp_path / "ais.csv"
    extra = ["own,1629972000.5,59.8,24.85,", "ship,1629972000.6,59.8,24.85,10", "target,x,1,2,3"]
    ais.write_text("\n".join([ais_lines[0], *extra, *ais_lines[1:], ais_lines[5]]) + "\n")
    with pytest.warns(SkippedRowsWarning, match="skipped 4 bad row"):
        data = read_ais(ais)
    assert data.skipped == 4
    np.testing.assert_array_equal(data.own.times, read_ais(AIS).own.times)


def test_cli_reports_skipped_rows(tmp_path):
    path, n_bad = damaged_copy(tmp_path)
    result = runner.invoke(
        app,
        ["bearing", str(path), str(AIS), "--out", str(tmp_path / "o"), "--cameras", str(CAMERAS)],
    )
    assert result.exit_code == 0, result.output
    assert f"skipped {n_bad} bad row(s)" in " ".join(result.output.split())
    clean = read_bearing_samples(SAMPLES, read_cameras(CAMERAS))
    assert len(read_rows(tmp_path / "o" / "fused_bearing.csv")) == len(clean.times)


@pytest.mark.parametrize(
    ("samples_text", "ais_text", "message"),
    [
        ("source,t,bearing_deg\nx,y,z\n1,nan,3\n", None, "no usable row"),
        ("source,time,bearing_deg\n1,2,3\n", None, "lacks column"),
        (None, "vessel,t,lat_deg,lon_deg,heading_deg\nown,1,59,24,10\n", "need at least 2"),
        (None, "vessel,t,lat,lon\nown,1,59,24\nown,2,59,24\n", "need at least 2"),
        (None, "t,lat_deg,lon_deg\n1,2,3\n", "lacks column"),
    ],
)
def test_cli_unusable_files_fail_clearly(tmp_path, samples_text, ais_text, message):
    samples, ais = SAMPLES, AIS
    if samples_text is not None:
        samples = tmp_path / "s.csv"
        samples.write_text(samples_text)
    if ais_text is not None:
        ais = tmp_path / "a.csv"
        ais.write_text(ais_text)
    result = runner.invoke(app, ["bearing", str(samples), str(ais), "--out", str(tmp_path / "o")])
    assert result.exit_code == 1
    output = " ".join(result.output.split())
    assert "error:" in output and message in output


def test_cameras_file_errors(tmp_path):
    bad = tmp_path / "cameras.json"
    bad.write_text(json.dumps({"1": {"width_px": 10, "height_px": 10, "hfov_deg": 500}}))
    with pytest.raises(ValueError, match=r"entry .1.*hfov_deg"):
        read_cameras(bad)
    bad.write_text("{not json")
    with pytest.raises(ValueError, match="cameras: cannot read"):
        read_cameras(bad)
    result = runner.invoke(
        app, ["bearing", str(SAMPLES), str(AIS), "--cameras", str(bad), "--out", str(tmp_path)]
    )
    assert result.exit_code == 1 and "cannot read" in result.output


def test_readme_bearing_example_runs(capsys):
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    section = readme[readme.index("## Bearing fusion") :]
    code = section.split("```python\n", 1)[1].split("```", 1)[0]
    exec(compile(code, "README.md", "exec"), {})
    out = capsys.readouterr().out
    assert "fused KF + RTS" in out and "visible (unfused)" in out
