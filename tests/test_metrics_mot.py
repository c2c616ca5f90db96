"""Multi-target scores against their reference implementations on the same frames: CLEAR MOT
and IDF1 against py-motmetrics (world positions with a gate and image boxes with IoU), HOTA
against TrackEval, GOSPA/OSPA against Stone Soup; MOTChallenge text round trip."""

from __future__ import annotations

import numpy as np
import pytest

from usvfast import DimensionError
from usvfast.metrics import (
    FrameSequence,
    box_iou,
    gospa_metrics,
    hota_metrics,
    mot_metrics,
    read_motchallenge,
    write_motchallenge,
)


def _scenario(seed: int, n_frames: int = 40, n_truth: int = 5, boxes: bool = False):
    """Truth objects on random walks, tracks that follow them with noise, drop out, swap ids,
    restart with new ids, plus clutter tracks. Returns truth and track rows."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(0, 60, (n_truth, 2))
    steps = rng.normal(0, 0.6, (n_frames, n_truth, 2))
    path = start[None] + np.cumsum(steps, axis=0)
    life = np.sort(rng.integers(0, n_frames, (n_truth, 2)), axis=1)
    life[:, 1] += 5
    gt, tr = [], []
    next_id = 100
    track_of = np.arange(n_truth) + 10
    for k in range(n_frames):
        if rng.random() < 0.1:  # a pair of tracks swap their targets
            a, b = rng.choice(n_truth, 2, replace=False)
            track_of[[a, b]] = track_of[[b, a]]
        for j in range(n_truth):
            if not life[j, 0] <= k <= life[j, 1]:
                continue
            gt.append((k, j + 1, *path[k, j]))
            if rng.random() < 0.12:
                continue  # missed
            if rng.random() < 0.03:
                track_of[j] = next_id  # track lost and re-born under a new id
                next_id += 1
            noise = rng.normal(0, 1.5, 2)
            tr.append((k, int(track_of[j]), *(path[k, j] + noise)))
        for _ in range(rng.poisson(0.7)):
            tr.append((k, int(rng.integers(500, 505)), *rng.uniform(0, 60, 2)))
    gt = np.array(gt)
    tr = np.array(tr)
    # one row per (frame, id): clutter ids can repeat within a frame
    _, keep = np.unique(tr[:, :2], axis=0, return_index=True)
    tr = tr[np.sort(keep)]
    if boxes:
        # boxes in pixels whose size grows with the image position (perspective)
        def size(xy):
            return np.column_stack([12 + 0.1 * xy[:, 0], 8 + 0.1 * xy[:, 1]])

        gt = np.column_stack([gt[:, :2], 2 * gt[:, 2:4], size(2 * gt[:, 2:4])])
        tr_xy = 2 * tr[:, 2:4]
        tr = np.column_stack([tr[:, :2], tr_xy, size(tr_xy) * rng.uniform(0.9, 1.1, (len(tr), 2))])
    return gt, tr


def _seq(gt, tr, boxes: bool, gate: float):
    cols = slice(2, 6) if boxes else slice(2, 4)
    args = (
        gt[:, 0].astype(int),
        gt[:, 1].astype(int),
        gt[:, cols],
        tr[:, 0].astype(int),
        tr[:, 1].astype(int),
        tr[:, cols],
    )
    if boxes:
        return FrameSequence.from_boxes(*args, iou_threshold=gate)
    return FrameSequence.from_positions(*args, max_distance=gate)


def _motmetrics(seq: FrameSequence, boxes: bool, gate: float):
    import motmetrics as mm
    from trackeval.datasets._base_dataset import _BaseDataset

    acc = mm.MOTAccumulator(auto_id=True)
    for g, t, gv, tv in zip(
        seq.truth_ids, seq.track_ids, seq.truth_values, seq.track_values, strict=True
    ):
        if boxes:
            # TrackEval's IoU (py-motmetrics' iou_matrix needs numpy < 2)
            d = 1 - _BaseDataset._calculate_box_ious(gv, tv, box_format="xywh")
            d[d > 1 - gate] = np.nan
        else:
            d = mm.distances.norm2squared_matrix(gv, tv, max_d2=gate**2)
            d = np.sqrt(d)
        acc.update(list(g), list(t), d)
    names = [
        "mota",
        "motp",
        "precision",
        "recall",
        "idf1",
        "idp",
        "idr",
        "num_matches",
        "num_switches",
        "num_misses",
        "num_false_positives",
        "num_objects",
        "idtp",
        "mostly_tracked",
        "partially_tracked",
        "mostly_lost",
    ]
    return mm.metrics.create().compute(acc, metrics=names, name="run").iloc[0]


@pytest.mark.parametrize(("seed", "boxes"), [(s, b) for s in range(6) for b in (False, True)])
def test_mot_metrics_equal_motmetrics(seed, boxes):
    gate = 0.5 if boxes else 3.0
    gt, tr = _scenario(seed, boxes=boxes)
    seq = _seq(gt, tr, boxes, gate)
    ours = mot_metrics(seq)
    ref = _motmetrics(seq, boxes, gate)
    assert ours.switches > 0 or seed % 3  # the scenarios do exercise switches
    assert ours.matches == ref.num_matches
    assert ours.switches == ref.num_switches
    assert ours.misses == ref.num_misses
    assert ours.false_positives == ref.num_false_positives
    assert ours.n_truth == ref.num_objects
    assert ours.idtp == ref.idtp
    for name in ("mota", "motp", "precision", "recall", "idf1", "idp", "idr"):
        assert getattr(ours, name) == pytest.approx(ref[name], rel=1e-12), name
    assert ours.mostly_tracked == ref.mostly_tracked
    assert ours.partially_tracked == ref.partially_tracked
    assert ours.mostly_lost == ref.mostly_lost
    if boxes:
        assert ours.motp_iou == pytest.approx(1 - ref.motp, rel=1e-12)


def _trackeval(seq: FrameSequence):
    from trackeval.metrics import HOTA

    all_g = np.unique(np.concatenate(seq.truth_ids))
    all_t = np.unique(np.concatenate(seq.track_ids))
    data = {
        "num_timesteps": len(seq.frames),
        "num_gt_ids": len(all_g),
        "num_tracker_ids": len(all_t),
        "num_gt_dets": seq.n_truth,
        "num_tracker_dets": seq.n_tracks,
        "gt_ids": [np.searchsorted(all_g, g) for g in seq.truth_ids],
        "tracker_ids": [np.searchsorted(all_t, t) for t in seq.track_ids],
        "similarity_scores": seq.similarity,
    }
    return HOTA().eval_sequence(data)


@pytest.mark.parametrize(("seed", "boxes"), [(s, b) for s in range(4) for b in (False, True)])
def test_hota_equals_trackeval(seed, boxes):
    gt, tr = _scenario(seed + 10, boxes=boxes)
    seq = _seq(gt, tr, boxes, 0.5 if boxes else 4.0)
    ours = hota_metrics(seq)
    ref = _trackeval(seq)
    from trackeval.datasets._base_dataset import _BaseDataset

    for g, t, sim in zip(seq.truth_values, seq.track_values, seq.similarity, strict=True):
        if boxes:
            want = _BaseDataset._calculate_box_ious(g, t, box_format="xywh")
        else:
            want = _BaseDataset._calculate_euclidean_similarity(g, t, zero_distance=4.0)
        np.testing.assert_allclose(sim, want, rtol=1e-12, atol=1e-15)
    for name in ("HOTA", "DetA", "AssA", "DetRe", "DetPr", "AssRe", "AssPr", "LocA", "OWTA"):
        assert getattr(ours, name.lower()) == pytest.approx(np.mean(ref[name]), rel=1e-12), name
    np.testing.assert_allclose(ours.hota_alpha, ref["HOTA"], rtol=1e-12)
    np.testing.assert_array_equal(ours.tp_alpha, ref["HOTA_TP"])
    assert ours.hota_0 == pytest.approx(ref["HOTA(0)"], rel=1e-12)
    assert 0 < ours.hota < 1


def test_hota_empty_sides_equal_trackeval():
    gt, _ = _scenario(3)
    f, i, v = gt[:, 0].astype(int), gt[:, 1].astype(int), gt[:, 2:4]
    for seq in (
        FrameSequence.from_positions(f, i, v, [], [], np.zeros((0, 2))),
        FrameSequence.from_positions([], [], np.zeros((0, 2)), f, i, v),
    ):
        from trackeval.metrics import HOTA

        data = {
            "num_tracker_dets": seq.n_tracks,
            "num_gt_dets": seq.n_truth,
        }
        ref = HOTA().eval_sequence(data)
        ours = hota_metrics(seq)
        assert ours.hota == pytest.approx(np.mean(ref["HOTA"]))
        np.testing.assert_array_equal(ours.fn_alpha, ref["HOTA_FN"])
        np.testing.assert_array_equal(ours.fp_alpha, ref["HOTA_FP"])


def test_perfect_tracks_score_one():
    gt, _ = _scenario(4)
    f, i, v = gt[:, 0].astype(int), gt[:, 1].astype(int), gt[:, 2:4]
    seq = FrameSequence.from_positions(f, i, v, f, i + 7, v, max_distance=1.0)
    m = mot_metrics(seq)
    assert m.mota == m.idf1 == m.precision == m.recall == 1.0
    assert m.motp == 0.0 and m.switches == 0
    h = hota_metrics(seq)
    assert h.hota == pytest.approx(1.0) and h.loca == pytest.approx(1.0)
    g = gospa_metrics(seq, cutoff=5.0)
    assert g.mean_distance == 0.0 and g.mean_ospa == 0.0


def test_mota_log10_switch_cost():
    # one object, two tracks alternating: every frame after the first is a switch
    f = np.arange(10)
    seq = FrameSequence.from_positions(
        f, np.zeros(10, int), np.zeros((10, 2)), f, f % 2, np.full((10, 2), 0.5)
    )
    m = mot_metrics(seq)
    assert m.switches == 9 and m.misses == 0 and m.false_positives == 0
    assert m.mota == pytest.approx(1 - 9 / 10)
    assert m.mota_log10 == pytest.approx(1 - np.log10(9) / 10)


@pytest.mark.parametrize("seed", range(4))
def test_gospa_ospa_equal_stonesoup(seed):
    from datetime import datetime, timedelta

    from stonesoup.metricgenerator.ospametric import GOSPAMetric, OSPAMetric
    from stonesoup.types.state import State

    gt, tr = _scenario(seed + 20, n_frames=15)
    seq = _seq(gt, tr, False, 3.0)
    c, p = 4.0, [1.0, 2.0, 3.0, 2.0][seed]
    ours = gospa_metrics(seq, cutoff=c, order=p)
    gospa, ospa = GOSPAMetric(c=c, p=p), OSPAMetric(c=c, p=p)
    t0 = datetime(2025, 1, 1)
    for k, (gv, tv) in enumerate(zip(seq.truth_values, seq.track_values, strict=True)):
        ts = t0 + timedelta(seconds=k)
        truth = [State(v.reshape(2, 1), timestamp=ts) for v in gv]
        track = [State(v.reshape(2, 1), timestamp=ts) for v in tv]
        if not truth and not track:
            continue
        ref = gospa.compute_gospa_metric(track, truth)[0].value
        assert ours.distance[k] == pytest.approx(ref["distance"], rel=1e-12, abs=1e-12)
        assert ours.localisation[k] == pytest.approx(ref["localisation"], rel=1e-9, abs=1e-12)
        assert ours.missed[k] == pytest.approx(ref["missed"])
        assert ours.false[k] == pytest.approx(ref["false"])
        ref_o = ospa.compute_OSPA_distance(track, truth).value
        assert ours.ospa[k] == pytest.approx(ref_o, rel=1e-12, abs=1e-12)


def test_box_iou_hand_case():
    a = np.array([[0, 0, 10, 10], [0, 0, 2, 2]])
    b = np.array([[5, 5, 10, 10], [20, 20, 1, 1]])
    iou = box_iou(a, b)
    assert iou[0, 0] == pytest.approx(25 / 175)
    assert iou[0, 1] == 0 and iou[1, 0] == 0 and iou[1, 1] == 0


def test_frame_sequence_bad_input():
    z = np.zeros((2, 2))
    with pytest.raises(DimensionError, match="lengths differ"):
        FrameSequence.from_positions([0, 1], [0], z, [0], [0], z[:1])
    with pytest.raises(ValueError, match="twice in one frame"):
        FrameSequence.from_positions([0, 0], [3, 3], z, [0], [0], z[:1])
    with pytest.raises(TypeError, match="truth_frame"):
        FrameSequence.from_positions([0.5, 1], [0, 1], z, [0], [0], z[:1])
    with pytest.raises(ValueError, match="max_distance"):
        FrameSequence.from_positions([0], [0], z[:1], [0], [0], z[:1], max_distance=0)
    with pytest.raises(ValueError, match="iou_threshold"):
        FrameSequence.from_boxes(
            [0], [0], [[0, 0, 1, 1]], [0], [0], [[0, 0, 1, 1]], iou_threshold=2
        )
    with pytest.raises(ValueError, match="truth_boxes"):
        FrameSequence.from_boxes([0], [0], [[0, 0, -1, 1]], [0], [0], [[0, 0, 1, 1]])
    with pytest.raises(TypeError, match="seq"):
        mot_metrics("tracks.txt")
    seq = FrameSequence.from_positions([0], [0], z[:1], [0], [0], z[:1])
    with pytest.raises(ValueError, match="cutoff"):
        gospa_metrics(seq, cutoff=-1)


def test_motchallenge_round_trip(tmp_path):
    _, tr = _scenario(5, boxes=True)
    path = tmp_path / "tracks.txt"
    write_motchallenge(path, tr[:, 0].astype(int) + 1, tr[:, 1].astype(int), tr[:, 2:6])
    back = read_motchallenge(path)
    order = np.lexsort((tr[:, 1], tr[:, 0]))
    np.testing.assert_array_equal(back.frame, tr[order, 0] + 1)
    np.testing.assert_array_equal(back.ids, tr[order, 1])
    np.testing.assert_allclose(back.boxes, tr[order, 2:6], atol=0.005)
    with path.open("a") as fh:
        fh.write("3,1,garbage,0,1,1,1,-1,-1,-1\n7,2,0,0,-5,1,1,-1,-1,-1\n")
    with pytest.warns(UserWarning, match="skipped 2 damaged"):
        again = read_motchallenge(path)
    assert again.skipped == 2 and len(again.frame) == len(back.frame)
    with pytest.raises(FileNotFoundError, match="path"):
        read_motchallenge(tmp_path / "nope.txt")
