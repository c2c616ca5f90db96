"""The report's detectable-target rule (`usvfast.report.detectable`) on a synthetic run whose
answer is known, beside the range rule (both in metrics.json and printed); its per-row
"seen" test against the brute-force definition; the visibility file's reader and the
rule's checks."""

from __future__ import annotations

import io

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from rich.console import Console

from usvfast.metrics.tables import Truth
from usvfast.report import write_report
from usvfast.report.detectable import (
    MIN_SEEN_S,
    DetectableRule,
    Visibility,
    read_visibility,
    seen_mask,
    seen_seconds,
)

T0 = 1.7e9
STEPS = np.round(np.arange(0.0, 20.0 + 1e-9, 0.1), 1)
COVERAGE = {"lidar": (10.0, 360.0, 0.0), "camera": (20.0, 90.0, 0.0)}
# object id -> (kind, north, east): the USV sits at the origin heading north
OBJECTS = {
    1: ("bottle", 5.0, 0.0),  # LiDAR: 3 returns a rotation for 2.0-8.9 s -> detectable
    2: ("bottle", 0.0, 5.0),  # 1 return a rotation, 2.5 px tall: in range 20 s, never seen
    3: ("box", 15.0, 0.0),  # beyond the LiDAR, in the camera's view: 4 px for 0-5.9 s
    4: ("bag", -15.0, 0.0),  # behind the camera: 5 px all along, not within its coverage
}


def _write_run(folder, visibility_rows):
    out = folder / "run"
    out.mkdir()
    with open(folder / "truth.csv", "w") as f:
        f.write("time,object_id,kind,north,east\n")
        for t in STEPS:
            for oid, (kind, n, e) in OBJECTS.items():
                f.write(f"{T0 + t:.1f},{oid},{kind},{n},{e}\n")
    with open(out / "nav.csv", "w") as f:
        f.write("time,north,east,heading_deg\n")
        f.writelines(f"{T0 + t:.1f},0,0,0\n" for t in STEPS)
    with open(out / "tracks.csv", "w") as f:  # a track on object 1 only, all along
        f.write("time,track_id,north,east,v_north,v_east,cov_nn,cov_ne,cov_ee\n")
        f.writelines(f"{T0 + t:.1f},7,5.05,0.0,0,0,0.01,0,0.01\n" for t in STEPS)
    with open(folder / "visibility.csv", "w") as f:
        f.write("time,object_id,sensor,count,width_px,height_px,visible_fraction\n")
        f.writelines(visibility_rows)
    return out


def _rows():
    rows = []
    for k in range(200):  # rotations stamped 0.05, 0.15, ...: each spans the 0.1 s before
        stamp = T0 + 0.05 + 0.1 * k
        if 2.0 < stamp - T0 < 9.0:
            rows.append(f"{stamp:.6f},1,lidar,3,,,\n")
        rows.append(f"{stamp:.6f},2,lidar,1,,,\n")
        rows.append(f"{stamp:.6f},3,lidar,9,,,\n")  # 15 m away: beyond the LiDAR's 10 m
    for k in range(200):  # frames exposed at 0.05, 0.15, ...
        t = T0 + 0.05 + 0.1 * k
        rows.append(f"{t:.6f},2,camera,5,3.0,2.5,1.0\n")
        if t - T0 < 6.0:
            rows.append(f"{t:.6f},3,camera,12,4.0,4.0,1.0\n")
        rows.append(f"{t:.6f},4,camera,30,6.0,5.0,1.0\n")
    return rows


def test_detectable_targets_beside_the_range_rule(tmp_path):
    out = _write_run(tmp_path, _rows())
    buf = io.StringIO()
    m = write_report(
        out,
        truth=tmp_path / "truth.csv",
        coverage=COVERAGE,
        animation=False,
        console=Console(file=buf, width=200),
    )
    # the range rule: objects 1, 2 (LiDAR) and 3 (camera) are targets; 4 is behind the camera
    targets = {o["object_id"] for o in m["thesis"]["objects"] if o["target"]}
    assert targets == {1, 2, 3} and m["thesis"]["targets_tracked"] == 1
    det = m["detectable"]
    assert det["rule"]["lidar_min_returns"] == 2 and det["rule"]["camera_min_height_px"] == 3
    assert det["rule"]["min_seen_s"] == MIN_SEEN_S
    seen = {o["object_id"]: o for o in det["objects"]}
    assert seen[1]["seen_seconds"] == pytest.approx(7.0)  # 70 rows, 2.0 ... 8.9
    assert seen[3]["seen_seconds"] == pytest.approx(6.0)  # 60 rows, 0.0 ... 5.9
    assert seen[2]["seen_seconds"] == 0.0 and seen[4]["seen_seconds"] == 0.0
    assert {o for o, s in seen.items() if s["target"]} == {1, 3}
    assert (det["n_targets"], det["targets_tracked"]) == (2, 1)
    assert det["groups"]["floats"]["n_targets"] == 2
    assert det["groups"]["floats"]["targets_tracked"] == 1
    assert m["inputs"]["visibility"]["rows"] == len(_rows())
    text = buf.getvalue()
    assert "targets (visible ≥ 5 s)" in text and "LiDAR ≥ 2 returns / rotation" in text
    # a stricter rule: 4 returns a rotation -> object 1 is no longer detectable
    strict = write_report(
        out,
        truth=tmp_path / "truth.csv",
        coverage=COVERAGE,
        animation=False,
        print_table=False,
        detectable_rule=DetectableRule(lidar_min_returns=4),
    )
    assert strict["detectable"]["n_targets"] == 1
    assert strict["thesis"]["n_targets"] == 3  # the range rule does not move
    longer = write_report(
        out,
        truth=tmp_path / "truth.csv",
        coverage=COVERAGE,
        animation=False,
        print_table=False,
        detectable_rule=DetectableRule(min_seen_s=6.5),
    )
    assert [o["object_id"] for o in longer["detectable"]["objects"] if o["target"]] == [1]


def test_without_a_visibility_file_there_is_no_detectable_rule(tmp_path):
    out = _write_run(tmp_path, [])
    (tmp_path / "visibility.csv").unlink()
    m = write_report(out, truth=tmp_path / "truth.csv", coverage=COVERAGE, print_table=False)
    assert "detectable" not in m and m["thesis"]["n_targets"] == 3
    with pytest.raises(FileNotFoundError, match="visibility"):
        write_report(out, truth=tmp_path / "truth.csv", visibility=tmp_path / "none.csv")


@given(
    truth_t=st.lists(st.floats(0.0, 5.0), min_size=1, max_size=30),
    stamps=st.lists(st.tuples(st.floats(0.0, 5.0), st.integers(0, 4)), max_size=30),
    frames=st.lists(st.tuples(st.floats(0.0, 5.0), st.floats(0.0, 6.0)), max_size=30),
)
def test_seen_mask_equals_its_definition(truth_t, stamps, frames):
    rule = DetectableRule(lidar_min_returns=2, camera_min_height_px=3.0)
    n = len(truth_t)
    truth = Truth(
        np.asarray(truth_t),
        np.zeros(n, np.int64),
        np.full(n, "bottle"),
        np.zeros((n, 2)),
    )
    k = len(stamps) + len(frames)
    vis = Visibility(
        np.array([s for s, _ in stamps] + [t for t, _ in frames], dtype=np.float64),
        np.zeros(k, np.int64),
        np.array(["lidar"] * len(stamps) + ["camera"] * len(frames), dtype=str),
        np.array([c for _, c in stamps] + [9] * len(frames), dtype=np.int64),
        np.full(k, np.nan),
        np.array([np.nan] * len(stamps) + [h for _, h in frames], dtype=np.float64),
        np.full(k, np.nan),
    )
    got = seen_mask(truth, vis, rule)
    for i, t in enumerate(truth_t):
        # the sample's span, both ends 1/1000 of the 0.1 s period early
        eps = 0.1 * 1e-3
        lidar = any((s - eps) - 0.1 <= t < (s - eps) + 0.0 for s, c in stamps if c >= 2)
        camera = any((f - eps) - 0.05 <= t < (f - eps) + 0.05 for f, h in frames if h >= 3.0)
        assert got["lidar"][i] == lidar and got["camera"][i] == camera


def test_read_visibility_and_rule_checks(tmp_path):
    p = tmp_path / "v.csv"
    p.write_text(
        "time,object_id,sensor,count,width_px,height_px,visible_fraction\n"
        "10.0,1,lidar,3,,,\n"
        "10.1,1,camera,7,4.0,2.0,0.5\n"
        "bad,1,lidar,3,,,\n"
        "10.2,x,lidar,3,,,\n"
    )
    v = read_visibility(p)
    assert v.skipped == 2 and v.sensor.tolist() == ["lidar", "camera"]
    assert v.count.tolist() == [3, 7] and np.isnan(v.height_px[0]) and v.height_px[1] == 2.0
    (tmp_path / "w.csv").write_text("time,object_id,sensor\n")
    with pytest.raises(ValueError, match="count"):
        read_visibility(tmp_path / "w.csv")
    with pytest.raises(FileNotFoundError, match="visibility"):
        read_visibility(tmp_path / "none.csv")
    with pytest.raises(ValueError, match="lidar_min_returns"):
        DetectableRule(lidar_min_returns=0)
    with pytest.raises(TypeError, match="lidar_min_returns"):
        DetectableRule(lidar_min_returns=1.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="camera_min_height_px"):
        DetectableRule(camera_min_height_px=0.0)
    with pytest.raises(ValueError, match="min_seen_s"):
        DetectableRule(min_seen_s=-1.0)


def test_seen_seconds_counts_rows():
    t = np.r_[np.arange(0.0, 3.0, 0.5), np.arange(0.0, 1.0, 0.1)]
    ids = np.r_[np.zeros(6, np.int64), np.ones(10, np.int64)]
    truth = Truth(t, ids, np.full(16, "box"), np.zeros((16, 2)))
    mask = np.r_[[True, False, True, True, False, False], np.ones(10, bool)]
    assert seen_seconds(truth, mask) == pytest.approx({0: 1.5, 1: 1.0})
    with pytest.raises(ValueError, match="mask"):
        seen_seconds(truth, mask[:-1])
