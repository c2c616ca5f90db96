"""The two-tier multi-clustered particle filter (Bloisi et al. §V): its invariants by
hypothesis, the same numbers as a plain numpy implementation from the same seed
(tests/particle_reference.py), the global tier's fusion, and the tracker on real MarDCT
frames and on a synthetic occlusion with colours; the shore runs' CLEAR MOT equal to
py-motmetrics and HOTA to TrackEval."""

from __future__ import annotations

import numpy as np
import particle_reference as ref
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from usvfast import _core
from usvfast.shore.boxes import Detections
from usvfast.shore.mardct import load_mardct
from usvfast.shore.mot_eval import mot_scores, run_tracker, truth_detections, truth_sequence
from usvfast.shore.particle import ParticleConfig, ParticleTracker


def test_random_stream_equals_numpy_splitmix():
    np.testing.assert_array_equal(_core.particle_uniforms(42, 7, 1000), ref.uniforms(42, 7, 1000))
    assert ref.words(0, 0, 1)[0] == 0xE220A8397B1DCDAF  # SplitMix64's first output of seed 0


weights_st = arrays(
    np.float64, st.integers(1, 40), elements=st.floats(0, 10, allow_subnormal=False)
).filter(lambda w: w.sum() > 1e-3)


@given(weights_st, st.integers(1, 200), st.integers(0, 2**63))
def test_resampling_counts_within_one_of_n_w(w, n, seed):
    idx = _core.particle_resample(w, n, seed=seed)
    assert len(idx) == n and np.all(np.diff(idx) >= 0)
    counts = np.bincount(idx, minlength=len(w))
    np.testing.assert_array_less(np.abs(counts - n * w / w.sum()), 1 + 1e-9)
    assert np.all(counts[w == 0] == 0)
    np.testing.assert_array_equal(idx, ref.resample(w, n, ref.Stream(seed)))


def test_resampling_unbiased_in_expectation():
    w = np.array([0.013, 0.2, 0.0, 0.387, 0.4])
    counts = np.mean(
        [np.bincount(_core.particle_resample(w, 7, seed=s), minlength=5) for s in range(4000)],
        axis=0,
    )
    np.testing.assert_allclose(counts, 7 * w, atol=0.03)


cloud_st = st.tuples(st.integers(0, 2**32), st.integers(1, 5), st.integers(8, 80))


@given(cloud_st, st.floats(5, 60))
def test_kclusterize_invariants_and_numpy_agreement(cloud, delta):
    seed, k, n = cloud
    rng = np.random.default_rng(seed)
    centres = rng.uniform(0, 300, (k, 2))
    p = np.concatenate(
        [np.column_stack([c + rng.normal(0, 4, (n, 2)), rng.normal(0, 1, (n, 2))]) for c in centres]
    )
    w = rng.uniform(0.1, 1.0, len(p))
    lam, mean, std, labels = _core.particle_kclusterize(p, w, delta=delta, min_size=8)
    c = len(lam)
    assert 0 <= c <= len(p) // 8
    assert set(np.unique(labels)) <= set(range(-1, c))
    for j in range(c):
        m = labels == j
        assert m.sum() >= 8
        assert lam[j] == pytest.approx(w[m].sum() / w.sum(), rel=1e-12)
        np.testing.assert_allclose(mean[j], np.average(p[m], axis=0, weights=w[m]), atol=1e-9)
        # members lie within δ of their centroid, so within 2δ of the mean
        assert np.all(np.hypot(*(p[m, :2] - mean[j, :2]).T) <= 2 * delta + 1e-9)
    assert lam.sum() <= 1 + 1e-12
    want = ref.kclusterize(p, w, delta)
    assert len(want) == c
    for j, (lw, mw, sw, members) in enumerate(want):
        np.testing.assert_array_equal(np.flatnonzero(labels == j), members)
        np.testing.assert_allclose([lam[j], *mean[j], *std[j]], [lw, *mw, *sw], rtol=1e-9)


def test_kclusterize_splits_touching_boats():
    rng = np.random.default_rng(2)
    a = np.column_stack([rng.normal([50, 50], 2, (100, 2)), np.zeros((100, 2))])
    b = np.column_stack([rng.normal([80, 50], 2, (100, 2)), np.zeros((100, 2))])
    lam, mean, _, _ = _core.particle_kclusterize(np.vstack([a, b]), np.ones(200), delta=60.0)
    assert len(lam) == 2
    np.testing.assert_allclose(np.sort(mean[:, 0]), [50, 80], atol=1.0)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_local_step_same_numbers_as_numpy(seed):
    rng = np.random.default_rng(seed)
    prior = np.column_stack([rng.normal([100, 80], 5, (50, 2)), rng.normal(1, 0.3, (50, 2))])
    obs = np.array([[104.0, 82.0, 3.0, 2.0], [220.0, 150.0, 4.0, 3.0]])
    vel = np.array([[1.0, 1.0], [0.0, 0.0]])
    kw = dict(count=60, dt=3.0, accel_std=0.05, vel_std=0.5, clutter=1e-9, n_out=120, delta=25.0)
    res, lam, mean, std, labels = _core.particle_local_step(prior, obs, vel, seed=seed, **kw)
    want_res, want = ref.local_step(prior, obs, vel, seed=seed, **kw)
    np.testing.assert_allclose(res, want_res, rtol=1e-12, atol=1e-9)
    assert len(lam) == len(want) == 2
    for j, (lw, mw, sw, members) in enumerate(want):
        np.testing.assert_array_equal(np.flatnonzero(labels == j), members)
        np.testing.assert_allclose([lam[j], *mean[j], *std[j]], [lw, *mw, *sw], rtol=1e-9)
    # the mixture sits on the observations
    np.testing.assert_allclose(np.sort(mean[:, 0]), [104, 220], atol=2.0)


def test_global_tier_fuses_sensors_within_the_window():
    means = np.array([[100.0, 50, 1, 0], [104.0, 52, 1, 0], [300.0, 50, 0, 0], [200.0, 90, 0, 0]])
    stds = np.full((4, 4), 2.0)
    times = np.array([9.8, 10.0, 10.0, 8.0])  # the last is older than Δt
    lam, mean, _, labels, parts = _core.particle_fuse(
        times, np.ones(4), means, stds, now=10.0, window=0.5, count=600, delta=20.0, seed=3
    )
    assert len(parts) == 600 and len(lam) == 2 and labels.min() >= 0
    order = np.argsort(mean[:, 0])
    np.testing.assert_allclose(mean[order, 0], [102, 300], atol=1.0)
    np.testing.assert_allclose(lam[order], [2 / 3, 1 / 3], atol=1e-9)
    with pytest.raises(ValueError, match="window"):
        _core.particle_fuse(
            times, np.ones(4), means, stds, now=10.0, window=-1, count=6, delta=20.0, seed=3
        )


def _dets(boxes):
    b = np.asarray(boxes, float).reshape(-1, 4)
    return Detections(b, np.ones(len(b)), np.full(len(b), -1))


def _scene(x_red: float, x_blue: float) -> np.ndarray:
    img = np.full((240, 320, 3), (160, 120, 60), np.uint8)
    img[100:130, int(x_blue) : int(x_blue) + 40] = (200, 40, 0)
    img[100:130, int(x_red) : int(x_red) + 40] = (0, 0, 220)  # red drawn on top
    return img


def test_occlusion_group_gives_the_ids_back_by_colour():
    """Two boats of different colours cross (the red one hides the blue one for three
    frames); after they separate each keeps its id (Bloisi et al. Fig. 11)."""
    t = ParticleTracker(ParticleConfig(seed=1))
    first, last = None, None
    for f in range(40):
        xr, xb = 40 + 6 * f, 280 - 6 * f
        overlap = abs(xr - xb) < 25
        boxes = (
            [[min(xr, xb), 100, 40 + abs(xr - xb), 30]]
            if overlap
            else [
                [xr, 100, 40, 30],
                [xb, 100, 40, 30],
            ]
        )
        ids, out, _ = t.step(_scene(xr, xb), _dets(boxes))
        if f == 10:
            first = dict(zip(np.round(out[:, 0]).astype(int) < 160, ids, strict=True))
        if f == 39:
            last = dict(zip(np.round(out[:, 0]).astype(int) > 160, ids, strict=True))
    # the boat on the left at frame 10 (red) is on the right at the end
    assert first is not None and last is not None and len(last) == 2
    assert first[True] == last[True] and first[False] == last[False]


def test_same_seed_same_tracks_and_bad_input():
    boxes = [[[10 + 3 * f, 50, 40, 20], [200 - 2 * f, 100, 30, 15]] for f in range(12)]
    runs = []
    for _ in range(2):
        t = ParticleTracker(ParticleConfig(seed=5))
        runs.append([t.step(None, _dets(b), 2.0) for b in boxes])
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[1], b[1])
    assert [len(r[0]) for r in runs[0]][2:] == [2] * 10
    with pytest.raises(ValueError, match="boxes"):
        t.step(None, _dets([[0, 0, -3, 4]]))
    with pytest.raises(ValueError, match="dt"):
        t.step(None, _dets([[0, 0, 3, 4]]), 0.0)
    with pytest.raises(ValueError, match="confirm_hits"):
        _core.ParticleTracker(confirm_hits=5, confirm_window=3)
    with pytest.raises(ValueError, match="boxes"):
        t.step(None, _dets([[0, np.nan, 3, 4]]))


@pytest.fixture(scope="module")
def mardct(mardct_annotations):
    return load_mardct(mardct_annotations)


@pytest.mark.parametrize("video", ["video3", "regDTV9"])
def test_particle_tracker_on_truth_boxes_of_mardct(mardct, video):
    """Noise-free input (the annotations as detections): the tracker alone reaches the
    paper's MOTA range (Table III: 0.81–0.91)."""
    frames = mardct[video]
    s = mot_scores(frames, run_tracker(frames, truth_detections(frames), "particle"))
    assert s["mota"] >= 0.8 and s["precision"] >= 0.99 and s["motp_iou"] >= 0.85, s


def _motmetrics_and_trackeval(seq):
    from test_metrics_mot import _motmetrics, _trackeval

    return _motmetrics(seq, True, 0.5), _trackeval(seq)


@pytest.mark.parametrize("tracker", ["particle", "sort"])
def test_shore_scores_equal_motmetrics_and_trackeval(mardct, tracker):
    frames = mardct["video3"]
    tracks = run_tracker(frames, truth_detections(frames), tracker)
    ours = mot_scores(frames, tracks)
    mm, te = _motmetrics_and_trackeval(truth_sequence(frames, tracks))
    for name in ("mota", "precision", "recall", "idf1"):
        assert ours[name] == pytest.approx(mm[name], rel=1e-12), name
    assert ours["motp_iou"] == pytest.approx(1 - mm["motp"], rel=1e-12)
    assert ours["switches"] == mm["num_switches"] and ours["misses"] == mm["num_misses"]
    log10 = np.log10(mm["num_switches"]) if mm["num_switches"] else 0.0
    n = mm["num_objects"]
    assert ours["mota_log10"] == pytest.approx(
        1 - (mm["num_misses"] + mm["num_false_positives"] + log10) / n, rel=1e-12
    )
    assert ours["hota"] == pytest.approx(np.mean(te["HOTA"]), rel=1e-12)


def test_shore_command_runs_both_trackers_on_one_video(tmp_path):
    import cv2
    from typer.testing import CliRunner

    from usvfast.cli import app
    from usvfast.shore.mot import read_mot

    frames = tmp_path / "frames"
    frames.mkdir()
    for k in range(8):
        img = np.full((120, 160, 3), (200, 170, 150), np.uint8)
        img[60:, :] = (120, 90, 60)
        cv2.rectangle(img, (30 + 5 * k, 50), (70 + 5 * k, 65), (5, 5, 5), -1)
        cv2.imwrite(str(frames / f"f_{k:03d}.png"), img)
    tracks = {}
    for tracker in ("sort", "particle"):
        out = tmp_path / tracker
        args = ["shore", str(frames), "--out", str(out), "--tracker", tracker, "--no-progress"]
        res = CliRunner().invoke(app, [*args, "--no-video", "--detector", "bayes"])
        assert res.exit_code == 0, res.output
        tracks[tracker] = read_mot(out / "tracks.txt")
    det = read_mot(tmp_path / "particle" / "detections.txt")
    assert len(det) == 8
    # the particle tracker confirms on the second frame and keeps one id
    pf = tracks["particle"]
    assert pf[:, 0].tolist() == list(range(2, 9)) and len(np.unique(pf[:, 1])) == 1
    np.testing.assert_allclose(pf[:, 2:6], det[1:, 2:6], atol=3.0)
    bad = CliRunner().invoke(app, ["shore", str(frames), "--out", str(tmp_path), "--tracker", "x"])
    assert bad.exit_code != 0 and "tracker" in bad.output
