"""The run's figures by group of targets (floating objects, vessels; `group_metrics`): a
synthetic truth and tracks where the grouping changes every figure, checked against numbers
worked out by hand (and scipy's χ² quantiles), and the printed one-row-per-group table."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from rich.console import Console
from scipy.stats import chi2

from usvfast.metrics import Innovations, Tracks, Truth, chi2_band, thesis_metrics
from usvfast.report.evaluate import (
    evaluate_run,
    group_metrics,
    kind_group,
    sensor_switch,
    track_groups,
)
from usvfast.report.table import print_summary

T = np.arange(11.0)  # s, truth and tracks every second


def _truth() -> Truth:
    # a bottle, a vessel, a moored boat (not a target), all still
    objs = [
        (1, "bottle", (10.0, 0.0)),
        (2, "vessel", (0.0, 10.0)),
        (3, "moored_boat", (30.0, 30.0)),
    ]
    time, oid, kind, pos = [], [], [], []
    for i, k, p in objs:
        time += list(T)
        oid += [i] * len(T)
        kind += [k] * len(T)
        pos += [p] * len(T)
    return Truth(np.array(time), np.array(oid), np.array(kind), np.array(pos, float))


def _tracks() -> Tracks:
    # (track id, times, position, covariance diagonal)
    spec = [
        (10, T, (10.1, 0.0), 0.01),  # the bottle, 0.1 m off: NEES 1
        (20, T[:6], (1.0, 10.5), 1.0),  # the vessel, (1, 0.5) m off: NEES 1.25
        (21, T[6:], (0.0, 12.0), 4.0),  # the vessel again, 2 m off: NEES 1
        (30, T, (30.0, 30.0), 1.0),  # on the moored boat
        (40, T[:3], (-50.0, -50.0), 1.0),  # clutter
    ]
    time, tid, pos, cov = [], [], [], []
    for i, ts, p, c in spec:
        time += list(ts)
        tid += [i] * len(ts)
        pos += [p] * len(ts)
        cov += [np.diag([c, c])] * len(ts)
    n = len(time)
    return Tracks(
        np.array(time), np.array(tid), np.array(pos, float), np.zeros((n, 2)), np.array(cov)
    )


def _innovations() -> Innovations:
    tid = [10, 10, 10, 20, 20, 21, 30, 40]
    nis = [1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 5.0, 7.0]
    sensor = ["lidar", "lidar", "camera", "camera", "camera", "lidar", "lidar", "lidar"]
    return Innovations(
        np.arange(8.0), np.array(tid), np.array(sensor), np.array(nis), np.full(8, 2)
    )


def _band(n: int) -> tuple[float, float]:
    lo, hi = chi2.ppf([0.025, 0.975], 2 * n)
    return lo / n, hi / n


def test_groups_split_the_pooled_figures():
    th = thesis_metrics(_truth(), _tracks(), innovations=_innovations())
    assert track_groups(th) == {10: "floats", 20: "vessels", 21: "vessels"}
    g = group_metrics(th, _innovations())
    fl, ve = g["floats"], g["vessels"]
    assert fl["label"] == "floating objects" and ve["label"] == "vessels"
    assert (fl["n_targets"], fl["targets_tracked"], fl["mean_trf"], fl["max_trf"]) == (1, 1, 1, 1)
    assert (ve["n_targets"], ve["targets_tracked"], ve["mean_trf"], ve["max_trf"]) == (1, 1, 2, 2)
    assert fl["rmse"] == pytest.approx(0.1)
    # 6 rows 1.25 m² + 5 rows 4 m² over 11 rows
    assert ve["rmse"] == pytest.approx(math.sqrt((6 * 1.25 + 5 * 4.0) / 11))
    assert th.rmse == pytest.approx(math.sqrt((11 * 0.01 + 6 * 1.25 + 5 * 4.0) / 22))
    assert fl["anees"]["mean"] == pytest.approx(1.0)
    assert ve["anees"]["mean"] == pytest.approx((6 * 1.25 + 5 * 1.0) / 11)
    # ANIS: the group's tracks' innovations only (moored-boat and clutter tracks in neither)
    assert fl["anis"]["mean"] == pytest.approx(2.0) and fl["anis"]["n"] == 3
    assert ve["anis"]["mean"] == pytest.approx(6.0) and ve["anis"]["n"] == 3
    assert th.anis is not None and th.anis.mean == pytest.approx(36.0 / 8)
    assert (fl["anis"]["lower"], fl["anis"]["upper"]) == pytest.approx(_band(3))
    assert fl["anis"]["inside"] and not ve["anis"]["inside"]
    assert fl["anis_by_sensor"]["lidar"]["mean"] == pytest.approx(1.5)
    assert ve["anis_by_sensor"]["camera"]["mean"] == pytest.approx(5.0)
    assert ve["anis_by_sensor"]["lidar"]["mean"] == pytest.approx(8.0)
    assert fl["tracks"] == [10] and ve["tracks"] == [20, 21]


def test_track_goes_to_the_group_of_most_of_its_matches():
    truth = _truth()
    tr = _tracks()
    # track 10 also follows the vessel for 7 s after the bottle's first 4: a vessel track
    pos = tr.positions.copy()
    on_bottle = np.flatnonzero(tr.track_id == 10)
    pos[on_bottle[4:]] = (0.0, 10.2)
    moved = Tracks(tr.time, tr.track_id, pos, tr.velocities, tr.covariances)
    th = thesis_metrics(truth, moved)
    assert track_groups(th)[10] == "vessels"
    assert kind_group("bag") == kind_group("buoy") == "floats" and kind_group("vessel") == "vessels"


def test_empty_group_and_the_printed_table(tmp_path):
    truth = _truth()
    keep = truth.kind != "vessel"
    floats_only = Truth(
        truth.time[keep], truth.object_id[keep], truth.kind[keep], truth.positions[keep]
    )
    m = evaluate_run(floats_only, _tracks(), innovations=_innovations())
    ve = m["groups"]["vessels"]
    assert ve["n_targets"] == 0 and math.isnan(ve["rmse"]) and ve["anis"] is None
    assert m["groups"]["floats"]["rmse"] == pytest.approx(m["thesis"]["rmse"])
    full = evaluate_run(truth, _tracks(), innovations=_innovations())
    with open(tmp_path / "t.txt", "w") as fh:
        print_summary(full, Console(file=fh, width=100))
    text = (tmp_path / "t.txt").read_text()
    rows = {line.split("  ")[0]: line for line in text.splitlines() if "/1" in line or "/2" in line}
    assert "all (pooled)" in rows and "floating objects" in rows and "vessels" in rows
    assert "2/2" in rows["all (pooled)"] and "0.100" in rows["floating objects"]
    assert f"{math.sqrt(2.5):.3f}" in rows["vessels"] and "2.00/2" in rows["vessels"]


def test_bad_input_names_the_argument():
    from usvfast.report.table import group_table

    with pytest.raises(TypeError, match="metrics"):
        group_table(0.0)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="th"):
        group_metrics({"rmse": 0.1})  # type: ignore[arg-type]
    th = thesis_metrics(_truth(), _tracks())
    with pytest.raises(TypeError, match="innovations"):
        group_metrics(th, innovations=[1.0])  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="kind"):
        kind_group(4)  # type: ignore[arg-type]
    assert group_table({"thesis": {}}) is None


def test_gated_innovations_give_gated_bands():
    inn = replace(_innovations(), gate=np.full(8, 0.99))
    th = thesis_metrics(_truth(), _tracks(), innovations=inn)
    g = group_metrics(th, inn)
    fl = g["floats"]
    assert fl["anis"]["gate"] == 0.99 and th.anis is not None and th.anis.gate == 0.99
    assert (fl["anis"]["lower"], fl["anis"]["upper"]) == pytest.approx(chi2_band(2, 3, gate=0.99))
    assert fl["anis"]["expected"] == pytest.approx(1.907, abs=5e-4)
    assert th.anis_by_sensor["camera"].gate == 0.99
    assert g["vessels"]["anis_by_sensor"]["lidar"]["gate"] == 0.99


def test_sensor_switch_marks_a_change_of_sensor_within_a_track():
    # rows out of time order, two tracks interleaved
    inn = Innovations(
        np.array([3.0, 1.0, 2.0, 1.0, 2.0, 4.0]),
        np.array([1, 1, 1, 2, 2, 1]),
        np.array(["lidar", "lidar", "camera", "camera", "camera", "lidar"]),
        np.ones(6),
        np.full(6, 2),
    )
    assert sensor_switch(inn).tolist() == [True, False, True, False, False, False]


def test_groups_split_anis_by_sensor_switch():
    g = group_metrics(
        thesis_metrics(_truth(), _tracks(), innovations=_innovations()), _innovations()
    )
    # float track 10: lidar, lidar, camera (NIS 1, 2, 3); vessel tracks 20 (camera twice), 21
    fl, ve = g["floats"]["anis_by_switch"], g["vessels"]["anis_by_switch"]
    assert (fl["same_sensor"]["n"], fl["same_sensor"]["mean"]) == (2, pytest.approx(1.5))
    assert (fl["sensor_switch"]["n"], fl["sensor_switch"]["mean"]) == (1, pytest.approx(3.0))
    assert ve["same_sensor"]["mean"] == pytest.approx(6.0) and ve["sensor_switch"] is None


def test_corrected_bands_follow_each_track_in_time_order():
    rng = np.random.default_rng(5)
    n = 200
    inn = Innovations(
        np.tile(np.arange(n / 2), 2),
        np.repeat([10, 20], n // 2),
        np.array(["lidar", "camera"] * (n // 2)),
        np.repeat(rng.chisquare(2, n // 4), 4),  # runs of 4 equal NIS: correlated
        np.full(n, 2),
    )
    shuffled = np.random.default_rng(6).permutation(n)
    mixed = Innovations(
        *(getattr(inn, k)[shuffled] for k in ("time", "track_id", "sensor", "nis", "dof"))
    )
    th, th_mixed = (thesis_metrics(_truth(), _tracks(), innovations=x) for x in (inn, mixed))
    assert th.anis is not None and th_mixed.anis is not None
    assert th.anis.variance_factor == pytest.approx(th_mixed.anis.variance_factor, rel=1e-12)
    assert th.anis.variance_factor > 2  # the runs of equal NIS, seen in time order
    # the ANEES too: each track's NEES in time order (the fixture's tracks err steadily)
    assert th.anees is not None and th.anees.variance_factor is not None
    assert th.anees.corrected_upper >= th.anees.upper
    g, g_mixed = group_metrics(th, inn), group_metrics(th_mixed, mixed)
    keys = ("mean", "lower", "upper", "variance_factor", "corrected_lower", "corrected_upper")
    a, b = g["floats"]["anis"], g_mixed["floats"]["anis"]
    assert [a[k] for k in keys] == pytest.approx([b[k] for k in keys], rel=1e-12)
    assert g["floats"]["anis"]["corrected_upper"] > g["floats"]["anis"]["upper"]
