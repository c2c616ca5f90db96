"""The thesis's metrics (§4.3 with the §7.3.1 matching) on synthetic runs whose answers are
known: RMSE of a constant offset, TPD of a half-covered object, TT/TRF of a fragmented track,
NEES/NIS inside and outside their χ² bands, the per-component cap and the ±1 s window,
Table 6.1 detector scores; NEES against filterpy; readers skip damaged lines."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from usvfast import DimensionError
from usvfast._damage import DamagedRecordsWarning
from usvfast.metrics import (
    average_consistency,
    chi2_band,
    detector_scores,
    in_range,
    longest_run,
    match_tracks,
    nees,
    read_detections,
    read_innovations,
    read_nav,
    read_tracks,
    read_truth,
    thesis_metrics,
)

from synthrun import EPOCH, Obj, TrackSpec, default_objects, write_run, write_truth


def _load(d):
    return (
        read_truth(d / "truth.csv"),
        read_tracks(d / "tracks.csv"),
        read_innovations(d / "innovations.csv"),
    )


def _run(tmp_path, tracks, objects=None, **kw):
    objects = objects or default_objects()
    write_truth(tmp_path, objects)
    write_run(tmp_path, objects, tracks, **kw)
    return _load(tmp_path)


def test_constant_offset_gives_its_rmse_and_full_coverage(tmp_path):
    # every object tracked the whole time, 0.2 m off (0.12 north, 0.16 east)
    tracks = [TrackSpec(10 + i, i, 0.0, 30.0, offset=(0.12, 0.16)) for i in (1, 2, 3, 4)]
    truth, trk, inn = _run(tmp_path, tracks)
    m = thesis_metrics(truth, trk, innovations=inn)
    assert m.rmse == pytest.approx(0.2, abs=1e-4)
    assert m.n_targets == 4 and m.targets_tracked == 4 and m.tpd == 1.0
    for o in m.objects:
        if o.target:
            assert o.rmse == pytest.approx(0.2, abs=1e-4)
            assert o.tpd == pytest.approx(1.0) and o.tt == pytest.approx(30.0)
            assert o.trf == 1 and o.track_ids == [10 + o.object_id]
    moored = next(o for o in m.objects if o.kind == "moored_boat")
    assert not moored.target and moored.n_matches == 0
    assert m.false_tracks == [] and m.excluded_tracks == {}
    assert set(m.by_kind) == {"bottle", "bag", "box", "vessel"}
    assert m.by_kind["bag"] == {
        "n_targets": 1,
        "targets_tracked": 1,
        "mean_tpd": 1.0,
        "rmse": pytest.approx(0.2, abs=1e-4),
    }
    # NEES of a constant error e with P = 0.04 I: |e|² / 0.04 = 1.0 every row
    assert m.anees.mean == pytest.approx(1.0, abs=1e-3)


def test_half_covered_object_has_tpd_half(tmp_path):
    tracks = [
        TrackSpec(10, 1, 0.0, 15.0),  # bottle: first half only
        TrackSpec(11, 2, 0.0, 30.0),
        TrackSpec(12, 3, 0.0, 30.0),
    ]
    objs = default_objects()[:3]
    truth, trk, inn = _run(tmp_path, tracks, objs)
    m = thesis_metrics(truth, trk, innovations=inn)
    bottle = m.objects[0]
    assert bottle.tpd == pytest.approx(0.5, abs=1e-9)
    assert bottle.tt == pytest.approx(15.0) and bottle.visible_time == pytest.approx(30.0)
    assert m.tpd == 1.0  # every target got a track (the thesis's TPD)
    assert m.mean_tpd == pytest.approx((0.5 + 1 + 1) / 3)


def test_fragmented_track_counts_trf_and_longest_segment(tmp_path):
    tracks = [
        TrackSpec(10, 1, 0.0, 8.0),
        TrackSpec(11, 1, 12.0, 30.0),  # re-born after a 4 s gap
        TrackSpec(12, 2, 0.0, 30.0),
        TrackSpec(20, None, 0.0, 10.0, position=(-15.0, 30.0)),  # clutter track
        TrackSpec(21, 5, 0.0, 30.0),  # a track on the moored boat
    ]
    objs = [*default_objects()[:2], default_objects()[4]]
    truth, trk, inn = _run(tmp_path, tracks, objs)
    m = thesis_metrics(truth, trk, innovations=inn)
    bottle = m.objects[0]
    assert bottle.trf == 2 and bottle.track_ids == [10, 11]
    assert bottle.tt == pytest.approx(18.0)
    assert bottle.tpd == pytest.approx(26.0 / 30.0)
    assert m.mean_trf == pytest.approx(1.5) and m.max_trf == 2
    assert m.false_tracks == [20]
    assert m.excluded_tracks == {"moored_boat": [21]}
    assert m.n_tracks == 5


def test_nees_consistent_inside_band_and_inflated_outside(tmp_path):
    p = np.array([[0.09, 0.03], [0.03, 0.05]])
    ok = [TrackSpec(10 + i, i, 0.0, 30.0, noise=p, cov=p) for i in (1, 2, 3)]
    objs = default_objects()[:3]
    truth, trk, inn = _run(tmp_path / "ok", ok, objs)
    m = thesis_metrics(truth, trk, innovations=inn)
    assert m.anees.n == 3 * 301 and m.anees.dof == 2
    assert m.anees.lower < m.anees.mean < m.anees.upper and m.anees.inside
    assert m.anis.inside and set(m.anis_by_sensor) == {"lidar", "camera"}
    bad = [TrackSpec(10 + i, i, 0.0, 30.0, noise=4 * p, cov=p) for i in (1, 2, 3)]
    truth, trk, inn = _run(tmp_path / "bad", bad, objs, nis_scale=2.0)
    m = thesis_metrics(truth, trk, innovations=inn)
    assert m.anees.mean > m.anees.upper and not m.anees.inside
    assert m.anees.mean == pytest.approx(2 * 4.0, rel=0.15)  # E = tr(P⁻¹ 4P)
    assert m.anis.mean > m.anis.upper and not m.anis.inside


def test_chi2_band_matches_the_thesis_interval():
    # §6.3.1: "the 90 % confidence interval for the NIS given by two degrees of freedom is
    # I = [0.102, 5.991]"
    lo, hi = chi2_band(2, 1, confidence=0.90)
    assert lo == pytest.approx(0.1026, abs=1e-4) and hi == pytest.approx(5.991, abs=1e-3)
    lo, hi = chi2_band(2, 100, confidence=0.95)
    assert lo == pytest.approx(chi2.ppf(0.025, 200) / 100)
    assert chi2_band([2, 2, 3], confidence=0.95) == pytest.approx(
        tuple(chi2.ppf([0.025, 0.975], 7) / 3)
    )
    with pytest.raises(ValueError, match="confidence"):
        chi2_band(2, 1, confidence=1.5)
    assert average_consistency([], 2) is None


def test_nees_equals_filterpy():
    from filterpy.stats import NEES

    rng = np.random.default_rng(3)
    a = rng.normal(size=(50, 4, 4))
    cov = a @ np.swapaxes(a, 1, 2) + 0.1 * np.eye(4)
    x = rng.normal(size=(50, 4))
    est = x + rng.normal(size=(50, 4))
    np.testing.assert_allclose(nees(est - x, cov), NEES(x, est, cov), rtol=1e-10)
    with pytest.raises(DimensionError, match="covariances"):
        nees(np.zeros((3, 2)), np.zeros((3, 3, 3)))
    with pytest.raises(ValueError, match="positive definite"):
        nees(np.zeros((1, 2)), -np.eye(2)[None])


def test_matching_cap_per_component_and_time_window(tmp_path):
    objs = [Obj(1, "bottle", (0.0, 0.0)), Obj(2, "bag", (50.0, 0.0), span=(0.0, 10.0))]
    tracks = [
        TrackSpec(10, 1, 0.0, 10.0, offset=(4.9, 4.9)),  # 6.9 m away, each component ≤ 5: in
        TrackSpec(11, 1, 10.0, 20.0, offset=(0.0, 5.1)),  # one component > 5: out
        # the bag's truth stops at 10 s: matched within 1 s after it, not later
        TrackSpec(12, 2, 0.0, 13.0, offset=(0.1, 0.0)),
    ]
    write_truth(tmp_path, objs)
    write_run(tmp_path, objs, tracks, duration=20.0)
    truth, trk, _ = _load(tmp_path)
    m = match_tracks(truth, trk)
    assert set(m.track_id[m.object_id == 1]) == {10}
    bag_times = m.time[m.track_id == 12] - EPOCH
    assert bag_times.max() == pytest.approx(11.0)
    np.testing.assert_allclose(m.error[m.track_id == 10], 4.9, atol=1e-5)
    with pytest.raises(ValueError, match="cap"):
        match_tracks(truth, trk, cap=0)


def test_one_to_one_matching_per_update(tmp_path):
    # two tracks on one bottle: the nearer wins, the other is a false track
    objs = [Obj(1, "bottle", (0.0, 0.0))]
    tracks = [TrackSpec(10, 1, 0.0, 10.0, offset=(0.5, 0.0)), TrackSpec(11, 1, 0, 10, (2.0, 0))]
    write_truth(tmp_path, objs)
    write_run(tmp_path, objs, tracks, duration=10.0)
    truth, trk, inn = _load(tmp_path)
    m = thesis_metrics(truth, trk, innovations=inn, min_visible=1.0)
    assert m.objects[0].track_ids == [10] and m.false_tracks == [11]
    assert m.rmse == pytest.approx(0.5, abs=1e-6)


def test_visibility_limits_the_targets_and_tpd(tmp_path):
    objs = default_objects()
    tracks = [TrackSpec(10 + i, i, 0.0, 30.0) for i in (1, 2, 3, 4)]
    truth, trk, inn = _run(tmp_path, tracks, objs)
    nav = read_nav(tmp_path / "nav.csv")
    vis = in_range(truth, nav, 20.0)
    m = thesis_metrics(truth, trk, innovations=inn, visible=vis)
    # the vessel starts 36 m away and passes within 20 m for a while; objects that are never
    # within 20 m for 5 s are no targets
    by_id = {o.object_id: o for o in m.objects}
    for o in m.objects:
        n_vis = vis[truth.object_id == o.object_id].sum()
        assert o.visible_time == pytest.approx(max(n_vis - 1, 0) * 0.1, abs=0.11 * 3)
    assert m.n_targets == sum(o.target for o in m.objects) < 5
    assert all(o.tpd == pytest.approx(1.0) for o in m.objects if o.target)
    assert by_id[5].visible_time < 5.0
    with pytest.raises(DimensionError, match="visible"):
        thesis_metrics(truth, trk, visible=vis[:-1])


def test_detector_scores_table_6_1(tmp_path):
    objs = [Obj(1, "bottle", (10.0, 0.0)), Obj(2, "bag", (0.0, 10.0), span=(0.0, 4.9))]
    miss = {10, 11, 12, 30}
    write_truth(tmp_path, objs)
    write_run(tmp_path, objs, [], lidar_miss=miss, duration=10.0)
    truth = read_truth(tmp_path / "truth.csv")
    det = read_detections(tmp_path / "detections.csv")
    s = {o.object_id: o for o in detector_scores(truth, det, sensor="lidar")}
    assert s[1].frames == 101 and s[1].fn == 4 and s[1].tp == 97 and s[1].cn == 3
    assert s[1].tp_rate == pytest.approx(97 / 101)
    assert s[2].frames == 50 and s[2].fn == 4 and s[2].cn == 3
    # the thesis's 50 consecutive frames
    s50 = detector_scores(truth, det, sensor="lidar", max_frames=50)[0]
    assert (s50.frames, s50.tp, s50.fn, s50.cn) == (50, 46, 4, 3)
    cam = detector_scores(truth, det, sensor="camera", period=0.5, gate=2.0)[0]
    assert cam.frames == 21 and cam.fn == 0
    assert longest_run([0, 1, 1, 0, 1, 1, 1]) == 3 and longest_run([0, 0]) == 0
    with pytest.raises(ValueError, match="gate"):
        detector_scores(truth, det, gate=0)


def test_readers_skip_damaged_lines_and_name_missing_columns(tmp_path):
    objs = default_objects()[:2]
    write_truth(tmp_path, objs)
    write_run(tmp_path, objs, [TrackSpec(10, 1, 0.0, 30.0)])
    with (tmp_path / "tracks.csv").open("a") as fh:
        fh.write("1700000031.0,10,nan,1,0,0,0,0,1,0,1\n1700000032.0,10,1\nx,y\n")
    with pytest.warns(DamagedRecordsWarning, match="skipped 3 damaged line"):
        trk = read_tracks(tmp_path / "tracks.csv")
    assert trk.skipped == 3 and len(trk.time) == 301
    assert trk.covariances.shape == (301, 2, 2)
    (tmp_path / "bad.csv").write_text("time,north\n1,2\n")
    with pytest.raises(ValueError, match="missing column"):
        read_truth(tmp_path / "bad.csv")
    with pytest.raises(ValueError, match="path"):
        read_tracks(tmp_path / "none.csv")


def test_in_range_with_field_of_view():
    from usvfast.metrics import Nav, Truth

    t = np.array([0.0, 1.0])
    nav = Nav(time=t, positions=np.zeros((2, 2)), heading_deg=np.array([90.0, 90.0]))
    # at t = 0.5: one object 10 m north, one 10 m east, one 50 m east, one 10 m south-east
    pos = np.array([[10.0, 0.0], [0.0, 10.0], [0.0, 50.0], [-7.0, 7.0]])
    truth = Truth(
        time=np.full(4, 0.5), object_id=np.arange(4), kind=np.array(["bottle"] * 4), positions=pos
    )
    assert in_range(truth, nav, 20.0).tolist() == [True, True, False, True]
    assert in_range(truth, nav, 20.0, fov_deg=60).tolist() == [False, True, False, False]
    assert in_range(truth, nav, 20.0, fov_deg=100).tolist() == [False, True, False, True]
    assert in_range(truth, nav, 20.0, fov_deg=60, yaw_deg=-90).tolist() == [
        True,
        False,
        False,
        False,
    ]
    late = Truth(
        time=np.array([2.0]),
        object_id=np.zeros(1, int),
        kind=np.array(["bag"]),
        positions=np.zeros((1, 2)),
    )
    assert in_range(late, nav, 20.0).tolist() == [False]  # after the last pose
    with pytest.raises(ValueError, match="fov_deg"):
        in_range(truth, nav, 20.0, fov_deg=0)


def test_truth_with_text_object_ids(tmp_path):
    # the simulator names its objects ("box0", "bottle1"): numbered in sorted order, named back
    objs = default_objects()[:2]
    write_truth(tmp_path, objs)
    text = (tmp_path / "truth.csv").read_text().splitlines()
    rows = [text[0]] + [
        ",".join([r.split(",")[0], r.split(",")[2] + r.split(",")[1], *r.split(",")[2:]])
        for r in text[1:]
    ]
    (tmp_path / "truth.csv").write_text("\n".join(rows) + "\n")
    truth = read_truth(tmp_path / "truth.csv")
    assert truth.names == ("bag2", "bottle1") and set(truth.object_id.tolist()) == {0, 1}
    assert truth.kinds() == {0: "bag", 1: "bottle"} and truth.name(1) == "bottle1"
    write_run(tmp_path, objs, [TrackSpec(10, 1, 0.0, 30.0, offset=(0.2, 0.0))])
    m = thesis_metrics(truth, read_tracks(tmp_path / "tracks.csv"))
    bottle = next(o for o in m.objects if o.name == "bottle1")
    assert bottle.rmse == pytest.approx(0.2, abs=1e-4) and bottle.track_ids == [10]
    assert detector_scores(truth, read_detections(tmp_path / "detections.csv"))[1].name == "bottle1"
