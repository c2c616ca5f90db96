"""Joyride reader and track-quality metrics: facts of the data, hand-checked cases, CLEAR MOT
against py-motmetrics (the Stone Soup anchor run on Joyride is in test_joyride_tracking.py)."""

from __future__ import annotations

import hypothesis.strategies as st
import numpy as np
import pytest
from hypothesis import example, given

from usvfast import DimensionError, NonFiniteError
from usvfast.datasets import load_joyride
from usvfast.metrics import clear_mot, track_quality

from conftest import SHARED_DATA

JOYRIDE = SHARED_DATA / "joyride" / "joyride.mat"


@pytest.fixture(scope="module")
def joyride():
    return load_joyride(JOYRIDE)


def test_joyride_matches_its_readme(joyride):
    # The data README: 238 scans over 638 s, median interval 2.51 s, 1..7 plots (mean 1.8).
    assert joyride.n_scans == 238
    assert joyride.skipped_scans == joyride.skipped_plots == 0
    assert joyride.times[-1] - joyride.times[0] == pytest.approx(638, abs=1)
    assert np.median(np.diff(joyride.times)) == pytest.approx(2.51, abs=0.01)
    counts = [len(m) for m in joyride.measurements]
    assert min(counts) == 1 and max(counts) == 7
    assert np.mean(counts) == pytest.approx(1.8, abs=0.05)
    assert joyride.target.shape == joyride.ownship.shape == (238, 4)
    rng = np.hypot(*(joyride.target[:, [0, 2]] - joyride.ownship[:, [0, 2]]).T)
    assert 165 < rng.min() < 180 and 800 < rng.max() < 820
    idx, plots = joyride.scan_arrays()
    assert plots.shape == (sum(counts), 2) and idx[-1] == 237


def test_joyride_nearest_plot_rmse_is_the_issue_figure(joyride):
    # Issue 3: "the nearest plot to the truth — 20.6 m".
    d = [
        np.min(np.hypot(*(z - tr[[0, 2]]).T))
        for z, tr in zip(joyride.measurements, joyride.target, strict=True)
    ]
    near = np.array(d)[np.array(d) <= 50]
    assert np.sqrt(np.mean(near**2)) == pytest.approx(20.6, abs=0.15)


def test_joyride_reader_skips_damaged_records(tmp_path):
    from scipy.io import loadmat, savemat

    data = loadmat(JOYRIDE)
    data = {k: v for k, v in data.items() if not k.startswith("__")}
    data["time"] = data["time"].copy()
    data["time"][5, 0] = np.nan  # a damaged scan
    meas = data["measurements"].copy()
    bad = np.array(meas[7, 0], dtype=float)
    bad = np.vstack([bad, [np.inf, 1.0]])  # one damaged plot
    meas[7, 0] = bad
    meas[9, 0] = np.zeros((3, 5))  # a malformed scan
    data["measurements"] = meas
    path = tmp_path / "damaged.mat"
    savemat(path, data)
    with pytest.warns(UserWarning, match="skipped 2 damaged scans and 1 non-finite"):
        rec = load_joyride(path)
    assert rec.n_scans == 236 and rec.skipped_scans == 2 and rec.skipped_plots == 1
    assert len(rec.measurements[6]) == len(np.asarray(meas[7, 0])) - 1  # others kept


def test_joyride_reader_fails_loudly(tmp_path):
    from scipy.io import savemat

    with pytest.raises(FileNotFoundError, match="path"):
        load_joyride(tmp_path / "nope.mat")
    savemat(tmp_path / "other.mat", {"x": np.zeros(3)})
    with pytest.raises(ValueError, match="no 'time'"):
        load_joyride(tmp_path / "other.mat")


def test_track_quality_hand_case():
    truth = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [30.0, 0.0], [40.0, 0.0]])
    # scan 0: track 7 at 3 m; scan 1: 7 at 4 m and 8 at 1 m (8 nearer); scan 2: none;
    # scan 3: 7 at 60 m only (too far); scan 4: 7 at 2 m. Track 9 always 500 m away.
    rows = [
        (0, 7, (3.0, 0.0)),
        (1, 7, (10.0, 4.0)),
        (1, 8, (11.0, 0.0)),
        (3, 7, (30.0, 60.0)),
        (4, 7, (42.0, 0.0)),
        (0, 9, (500.0, 0.0)),
        (4, 9, (500.0, 0.0)),
    ]
    s, i, p = zip(*rows, strict=True)
    q = track_quality(truth, np.array(s), np.array(i), np.array(p), gate=50.0)
    assert q.coverage == pytest.approx(3 / 5)
    assert q.rmse == pytest.approx(np.sqrt((9 + 1 + 4) / 3))
    assert list(q.counted_ids) == [7, 8, -1, -1, 7]
    assert q.id_switches == 2 and q.fragments == 3 and q.distinct_tracks == 2
    assert q.tracks_elsewhere == 1 and q.n_tracks == 3


def test_metrics_bad_input():
    truth = np.zeros((3, 2))
    with pytest.raises(DimensionError, match="truth_positions"):
        track_quality(np.zeros((3, 3)), [0], [0], [[0.0, 0.0]])
    with pytest.raises(DimensionError, match="lengths differ"):
        track_quality(truth, [0, 1], [0], [[0.0, 0.0]])
    with pytest.raises(ValueError, match="scan_index"):
        track_quality(truth, [3], [0], [[0.0, 0.0]])
    with pytest.raises(NonFiniteError, match="track_positions"):
        track_quality(truth, [0], [0], [[np.nan, 0.0]])
    with pytest.raises(TypeError, match="track_ids"):
        clear_mot(truth, [0], [0.5], [[0.0, 0.0]])
    empty = track_quality(truth, np.zeros(0, int), np.zeros(0, int), np.zeros((0, 2)))
    assert empty.coverage == 0 and empty.fragments == 0 and np.isnan(empty.rmse)


def _motmetrics(truth, scans, ids, pos, gate):
    import motmetrics as mm

    acc = mm.MOTAccumulator(auto_id=True)
    for k in range(len(truth)):
        m = scans == k
        # the same distance arithmetic as clear_mot: np.hypot and np.linalg.norm differ by an
        # ulp, which decides a match for an offset exactly on the gate
        d = np.linalg.norm(pos[m] - truth[k], axis=1).reshape(1, -1)
        d[d > gate] = np.nan
        acc.update([0], list(ids[m]), d)
    names = ["mota", "motp", "num_matches", "num_misses", "num_false_positives", "num_switches"]
    return mm.metrics.create().compute(acc, metrics=names, name="run").iloc[0]


@given(
    st.integers(2, 25),
    st.lists(st.tuples(st.integers(0, 24), st.integers(0, 4), st.floats(-80, 80)), max_size=60),
)
@example(2, [(0, 0, 44.721359549995796), (1, 0, 0.0)])  # on the 50 m gate to the last ulp
def test_clear_mot_equals_motmetrics(n_scans, rows):
    truth = np.column_stack([np.arange(n_scans) * 5.0, np.zeros(n_scans)])
    rows = [(k, i, off) for k, i, off in rows if k < n_scans]
    # one row per (scan, track id): motmetrics does not accept a hypothesis twice in a frame
    rows = list({(k, i): (k, i, off) for k, i, off in rows}.values())
    scans = np.array([r[0] for r in rows], np.int64)
    ids = np.array([r[1] for r in rows], np.int64)
    pos = truth[scans] + np.array([[r[2], 0.5 * r[2]] for r in rows]).reshape(-1, 2)
    ours = clear_mot(truth, scans, ids, pos, gate=50.0)
    ref = _motmetrics(truth, scans, ids, pos, 50.0)
    assert ours.matches == ref.num_matches
    assert ours.misses == ref.num_misses
    assert ours.false_positives == ref.num_false_positives
    assert ours.switches == ref.num_switches
    assert ours.mota == pytest.approx(ref.mota, abs=1e-12)
    if ours.matches + ours.switches:
        assert ours.motp == pytest.approx(ref.motp, rel=1e-12)
    # every scan covered by clear_mot is covered by track_quality and vice versa
    q = track_quality(truth, scans, ids, pos, gate=50.0)
    assert round(q.coverage * n_scans) == ours.matches + ours.switches
