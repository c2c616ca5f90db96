"""`usvfast.report.write_report` on synthetic runs in the interface formats: the files it writes,
strict JSON with the figures the metrics give on the same tables, pictures of a readable size,
the animation with the camera inset, tracks on walls and moored boats, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image
from rich.console import Console

from usvfast.metrics import (
    in_range,
    mot_metrics,
    read_innovations,
    read_nav,
    read_tracks,
    read_truth,
    thesis_metrics,
)
from usvfast.report import write_report
from usvfast.report.evaluate import frame_sequence

from synthrun import Obj, TrackSpec, default_objects, write_run, write_scene, write_truth

P = np.diag([0.05, 0.03])


def _tracks():
    return [
        TrackSpec(1, 1, 2.0, 30.0, noise=P, cov=P),
        TrackSpec(2, 2, 0.0, 14.0, noise=P, cov=P),
        TrackSpec(5, 2, 17.0, 30.0, noise=P, cov=P),
        TrackSpec(3, 3, 0.0, 30.0, offset=(0.2, 0.1), cov=P),
        TrackSpec(4, 4, 5.0, 25.0, noise=P, cov=P),
        TrackSpec(9, None, 3.0, 9.0, position=(30.0, -15.0)),  # clutter
        TrackSpec(7, 5, 0.0, 30.0),  # on the moored boat
        TrackSpec(8, None, 0.0, 30.0, position=(10.0, 47.0)),  # inside the pier polygon
    ]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("run")
    objs = default_objects()
    write_truth(d, objs)
    write_scene(d, objs)
    write_run(d / "out", objs, _tracks(), frames=True, duration=30.0)
    return d


def _strict(text: str):
    def bad(name):
        raise ValueError(f"non-standard JSON constant {name}")

    return json.loads(text, parse_constant=bad)


def test_write_report_files_and_metrics(run, tmp_path):
    out = run / "out"
    console = Console(file=open(tmp_path / "table.txt", "w"), width=120)
    m = write_report(
        out, truth=run / "truth.csv", scene=run / "scene.json", animation=False, console=console
    )
    console.file.close()
    for name in ("metrics.json", "map.png", "nis.png", "errors.png"):
        assert (out / name).is_file(), name
    saved = _strict((out / "metrics.json").read_text())
    assert saved == m
    # rows at 0.1 s over each track's span: 281 + 141 + 131 + 301 + 201 + 61 + 301 + 301
    assert m["inputs"]["tracks"] == {"rows": 1718, "skipped_lines": 0}
    assert m["inputs"]["truth"]["skipped_lines"] == 0 and m["inputs"]["nav"]["rows"] == 301
    # the same figures as the metrics on the same tables
    truth, tracks = read_truth(run / "truth.csv"), read_tracks(out / "tracks.csv")
    inn, nav = read_innovations(out / "innovations.csv"), read_nav(out / "nav.csv")
    vis = in_range(truth, nav, 40.0)
    th = thesis_metrics(truth, tracks, innovations=inn, visible=vis)
    assert m["thesis"]["rmse"] == pytest.approx(th.rmse)
    assert m["thesis"]["tpd"] == th.tpd and m["thesis"]["n_targets"] == th.n_targets
    assert m["thesis"]["anis"]["mean"] == pytest.approx(th.anis.mean)
    assert m["thesis"]["false_tracks"] == [8, 9]
    assert m["thesis"]["excluded_tracks"] == {"moored_boat": [7]}
    assert m["walls"]["tracks_on_walls"] == [8]
    assert m["walls"]["tracks_on_moored_boats"] == [7]
    assert m["walls"]["object_tracks_near_walls"] == []
    targets = [o.object_id for o in th.objects if o.target]
    seq = frame_sequence(
        truth,
        tracks,
        targets,
        vis,
        t_span=(nav.time.min(), nav.time.max()),
        frame_period=0.5,
        cap=5.0,
        zero_distance=2.0,
    )
    mot = mot_metrics(seq)
    assert m["clear_mot"]["mota"] == pytest.approx(mot.mota)
    assert m["clear_mot"]["switches"] == mot.switches == 1  # the bag: track 2 then 5
    # tracks 7 (moored boat), 8 (wall) and 9 (clutter) are false positives every frame
    assert mot.false_positives >= 61 + 61 + 12
    assert 0 < m["hota"]["hota"] < 1 and m["gospa"]["gospa"] > 0
    lidar = m["detectors"]["lidar"]
    assert lidar["fn"] == 0 and lidar["tp_rate"] == 1.0
    table = (tmp_path / "table.txt").read_text()
    assert "position RMSE" in table and "tracks on moored_boat" in table and "MOTA" in table
    # pictures a person can read: not tiny, not blank
    for name in ("map.png", "nis.png", "errors.png"):
        with Image.open(out / name) as im:
            assert im.size[0] >= 900 and im.size[1] >= 500
            assert np.asarray(im.convert("L")).std() > 10


def test_an_objects_track_beside_a_quay_is_not_a_track_on_the_wall(tmp_path):
    # the vessel runs 1.5 m beside a quay: its own track (4), within 2 m of the quay, is
    # listed apart; a track on the quay 8 m behind the vessel's start (10) is counted
    objs = default_objects()
    vessel = next(o for o in objs if o.kind == "vessel")
    write_truth(tmp_path, objs)
    scene = json.loads(write_scene(tmp_path, objs).read_text())
    heading = np.array(vessel.velocity) / np.hypot(*vessel.velocity)
    beside = np.array(vessel.start) + 1.5 * np.array([-heading[1], heading[0]])
    scene["walls"].append([list(map(float, beside + k * heading)) for k in (-10, 90)])
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    on_quay = tuple(map(float, beside - 8 * heading))
    specs = [
        TrackSpec(4, vessel.object_id, 5.0, 25.0, noise=P, cov=P),
        TrackSpec(10, None, 0, 30, position=on_quay),
    ]
    out = write_run(tmp_path / "out", objs, specs, duration=30.0)
    console = Console(file=open(tmp_path / "table.txt", "w"), width=120)
    m = write_report(
        out, truth=tmp_path / "truth.csv", scene=tmp_path / "scene.json", console=console
    )
    console.file.close()
    assert m["walls"]["tracks_on_walls"] == [10]
    assert m["walls"]["object_tracks_near_walls"] == [4]
    assert m["walls"]["object_tracks_near_moored_boats"] == []
    assert m["thesis"]["false_tracks"] == [10]
    assert "objects' tracks near walls" in (tmp_path / "table.txt").read_text()


def test_animation_has_camera_inset_and_stays_small(tmp_path):
    objs = default_objects()[:3]
    write_truth(tmp_path, objs)
    out = write_run(tmp_path / "out", objs, [TrackSpec(1, 1, 0, 10)], frames=True, duration=10.0)
    m = write_report(out, print_table=False)
    assert m == {} and not (out / "metrics.json").exists() and not (out / "errors.png").exists()
    with Image.open(out / "animation.gif") as im:
        assert im.n_frames == 21  # 2 fps over 10 s
        wide = im.size
    assert wide[0] > 1.8 * wide[1]  # map and camera side by side
    assert (out / "animation.gif").stat().st_size < 2_000_000
    # without camera frames: the map alone
    for f in (out / "camera_frames").iterdir():
        f.unlink()
    (out / "camera_frames").rmdir()
    (out / "animation.gif").unlink()
    write_report(out, print_table=False)
    assert not (out / "animation.gif").exists()  # no frames: no animation asked for
    write_report(out, print_table=False, animation=True)
    with Image.open(out / "animation.gif") as im:
        assert im.size[0] < wide[0]


def test_report_bad_input(tmp_path, run):
    with pytest.raises(FileNotFoundError, match=r"tracks\.csv"):
        write_report(tmp_path)
    with pytest.raises(FileNotFoundError, match="truth"):
        write_report(run / "out", truth=tmp_path / "none.csv", animation=False)
    with pytest.raises(FileNotFoundError, match="scene"):
        write_report(run / "out", scene=tmp_path / "none.json", animation=False)
    (tmp_path / "bad.json").write_text("[1, 2")
    with pytest.raises(ValueError, match="scene"):
        write_report(run / "out", scene=tmp_path / "bad.json", animation=False)
    with pytest.raises(TypeError, match="origin"):
        write_report(run / "out", origin=("a", 1, 2), animation=False)


def test_report_without_truth_in_range_is_empty_of_targets(tmp_path):
    # an object that is never within 40 m of the USV is no target; the metrics say so
    objs = [Obj(1, "bottle", (300.0, 300.0))]
    write_truth(tmp_path, objs)
    out = write_run(tmp_path / "out", objs, [TrackSpec(1, 1, 0, 10)], duration=10.0)
    m = write_report(out, truth=tmp_path / "truth.csv", animation=False, print_table=False)
    assert m["thesis"]["n_targets"] == 0 and m["thesis"]["tpd"] is None
    assert m["clear_mot"]["false_positives"] == 21


def test_report_command(run, tmp_path):
    from typer.testing import CliRunner

    from usvfast.cli import app

    args = ["report", str(run / "out"), "--truth", str(run / "truth.csv"), "--no-animation"]
    r = CliRunner().invoke(app, [*args, "--html", "--scene", str(run / "scene.json")])
    assert r.exit_code == 0, r.output
    assert "position RMSE" in r.output and "metrics.json" in r.output and "map.html" in r.output
    page = (run / "out" / "map.html").read_text()
    assert "plotly" in page and "track 9" in page and "truth 5 (moored_boat)" in page
    r = CliRunner().invoke(app, ["report", str(tmp_path)])
    assert r.exit_code == 2 and "tracks.csv" in r.output


def test_detector_scores_follow_the_sensor_range_and_fov(run):
    from usvfast.metrics import read_detections
    from usvfast.report import evaluate_run

    out = run / "out"
    tables = {
        "detections": read_detections(out / "detections.csv"),
        "nav": read_nav(out / "nav.csv"),
    }
    truth, tracks = read_truth(run / "truth.csv"), read_tracks(out / "tracks.csv")
    wide = evaluate_run(truth, tracks, **tables)["detectors"]
    narrow = evaluate_run(
        truth, tracks, sensor_range={"lidar": 15.0}, sensor_fov_deg={"camera": 60.0}, **tables
    )["detectors"]
    frames = {k: sum(o["frames"] for o in v["objects"]) for k, v in wide.items()}
    frames_n = {k: sum(o["frames"] for o in v["objects"]) for k, v in narrow.items()}
    assert 0 < frames_n["lidar"] < frames["lidar"] and 0 < frames_n["camera"] < frames["camera"]
    assert narrow["lidar"]["range_m"] == 15.0 and narrow["camera"]["fov_deg"] == 60.0


def test_report_with_no_tracks_and_with_an_empty_truth(tmp_path):
    objs = default_objects()[:2]
    write_truth(tmp_path, objs)
    out = write_run(tmp_path / "out", objs, [], duration=10.0)
    m = write_report(out, truth=tmp_path / "truth.csv", print_table=False)
    th = m["thesis"]
    assert th["n_targets"] == 2 and th["targets_tracked"] == 0 and th["tpd"] == 0.0
    assert th["rmse"] is None and th["anees"] is None and th["anis"] is None
    assert m["clear_mot"]["mota"] == 0.0 and m["clear_mot"]["false_positives"] == 0
    assert (out / "map.png").is_file() and (out / "errors.png").is_file()
    (tmp_path / "empty.csv").write_text("time,object_id,kind,north,east\n")
    write_run(out, objs, [TrackSpec(1, 1, 0, 10)], duration=10.0)
    m = write_report(out, truth=tmp_path / "empty.csv", print_table=False)
    assert m["thesis"]["n_targets"] == 0 and m["thesis"]["false_tracks"] == [1]
    assert m["clear_mot"]["false_positives"] == 21 and m["clear_mot"]["mota"] is None


def test_report_counts_targets_by_the_coverage_the_run_wrote(run, tmp_path):
    import shutil

    out = tmp_path / "out"
    shutil.copytree(run / "out", out)
    truth = run / "truth.csv"
    narrow = {"lidar": (6.0, 360.0, 0.0), "camera": (12.0, 60.0, 0.0)}
    (out / "summary.json").write_text(
        json.dumps({"coverage": {k: list(v) for k, v in narrow.items()}})
    )
    kw = {"animation": False, "print_table": False}
    read = write_report(out, truth=truth, **kw)
    given = write_report(out, truth=truth, coverage=narrow, **kw)
    wide = write_report(out, truth=truth, max_range=40.0, **kw)
    assert read["thesis"] == given["thesis"]
    assert read["thesis"]["n_targets"] < wide["thesis"]["n_targets"]
    assert read["inputs"] == given["inputs"]
    from typer.testing import CliRunner

    from usvfast.cli import app

    for extra, expected in (([], read), (["--max-range", "40"], wide)):
        args = ["report", str(out), "--truth", str(truth), "--no-animation", *extra]
        r = CliRunner().invoke(app, args)
        assert r.exit_code == 0, r.output
        saved = json.loads((out / "metrics.json").read_text())
        assert saved["thesis"]["n_targets"] == expected["thesis"]["n_targets"]
    (out / "summary.json").write_text("[1, 2]")
    with pytest.raises(ValueError, match=r"out_dir: .*summary\.json"):
        write_report(out, truth=truth, **kw)
