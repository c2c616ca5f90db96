"""Error breakdown, overlap + containment suppression and the box verifier of the shore
detectors (real MarDCT frames where it matters)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from usvfast.shore.boxes import Detections, iou_matrix
from usvfast.shore.errors import ErrorBreakdown
from usvfast.shore.scores import DetectionCounts
from usvfast.shore.suppress import containment_matrix, suppress, suppress_indices
from usvfast.shore.verify import (
    BoxVerifier,
    box_features,
    candidates,
    n_features,
    refit_boxes,
    select,
)


def random_boxes(rng, n, size=200.0):
    xy = rng.uniform(0, size, (n, 2))
    wh = rng.uniform(5, 60, (n, 2))
    return np.round(np.concatenate([xy, wh], axis=1))


def test_breakdown_names_each_error_of_a_hand_made_frame():
    truth = np.array(
        [
            [0, 0, 100, 50],  # found well, and a second box inside it: duplicate
            [200, 0, 100, 50],  # found with a box 2.5 × too wide: mislocalised
            [400, 0, 40, 20],  # covered: only the merged box below reaches it
            [440, 0, 40, 20],  # mislocalised by that merged box
            [600, 600, 30, 30],  # missed
        ],
        float,
    )
    det = np.array(
        [
            [0, 0, 100, 52],
            [10, 10, 40, 20],
            [200, 0, 250, 50],
            [400, 0, 84, 22],
            [900, 900, 20, 20],  # pure false
        ],
        float,
    )
    e = ErrorBreakdown()
    e.add(truth, det)
    s = e.summary()
    assert (s["tp"], s["fp_duplicate"], s["fp_false"]) == (1, 1, 1)
    assert s["fp_mislocalised"] == s["fn_mislocalised"] == 2
    assert (s["fn_covered"], s["fn_missed"]) == (1, 1)
    assert sorted(np.round(e.area_ratios, 2)) == [2.31, 2.5]


def test_breakdown_totals_equal_the_scores_on_random_frames():
    rng = np.random.default_rng(3)
    e, c = ErrorBreakdown(), DetectionCounts()
    for _ in range(60):
        t = random_boxes(rng, rng.integers(0, 5))
        d = np.concatenate([t + rng.normal(0, 6, t.shape), random_boxes(rng, rng.integers(0, 4))])
        d[:, 2:] = np.maximum(d[:, 2:], 1)
        e.add(t, d)
        c.add(t, d)
    assert (e.tp, e.fp, e.fn) == (c.tp, c.fp, c.fn)
    assert e.fp_mislocalised > 0 and e.fp_false > 0 and e.fn_missed >= 0


def test_breakdown_of_a_real_detector_adds_up(mardct_annotations):
    from usvfast.shore.contrast import ContrastDetector
    from usvfast.shore.mardct import load_mardct

    frames = load_mardct(mardct_annotations)["2"]
    det = ContrastDetector()
    e, c = ErrorBreakdown(), DetectionCounts()
    for f in frames:
        d = det.detect(cv2.imread(str(f.path), cv2.IMREAD_COLOR))
        e.add(f.boxes, d.boxes)
        c.add(f.boxes, d.boxes)
    assert (e.tp, e.fp, e.fn) == (c.tp, c.fp, c.fn)
    # the contrast detector's known weakness on video 2: merged, badly drawn ship boxes
    assert e.fp_mislocalised >= e.fp_false


def test_plain_suppression_equals_opencv_nms():
    rng = np.random.default_rng(0)
    for trial in range(20):
        b = random_boxes(rng, 25)
        s = rng.uniform(0, 1, 25)
        ours = suppress_indices(b, s, nms=0.3, contain=1.01)
        ref = cv2.dnn.NMSBoxes(b.tolist(), s.tolist(), 0.0, 0.3)
        assert sorted(ours.tolist()) == sorted(np.asarray(ref).ravel().tolist()), trial


def test_containment_equals_a_pixel_count_and_drops_part_boxes():
    rng = np.random.default_rng(1)
    a, b = random_boxes(rng, 6, 60), random_boxes(rng, 5, 60)
    got = containment_matrix(a, b)
    for i, p in enumerate(a.astype(int)):
        for j, q in enumerate(b.astype(int)):
            m1 = np.zeros((200, 200), bool)
            m2 = np.zeros((200, 200), bool)
            m1[p[1] : p[1] + p[3], p[0] : p[0] + p[2]] = True
            m2[q[1] : q[1] + q[3], q[0] : q[0] + q[2]] = True
            ref = (m1 & m2).sum() / min(m1.sum(), m2.sum())
            assert got[i, j] == pytest.approx(ref, abs=1e-12)
    ship = np.array([[100, 100, 200, 40], [110, 105, 50, 30], [400, 100, 50, 30]], float)
    d = Detections(ship, np.array([0.9, 0.95, 0.5]), np.full(3, -1))
    assert iou_matrix(ship[:1], ship[1:2])[0, 0] < 0.3  # plain NMS keeps the bow box
    assert len(suppress(d, nms=0.3, contain=1.01)) == 3
    kept = suppress(d, nms=0.3, contain=0.7)
    assert sorted(kept.scores.tolist()) == [0.5, 0.95]


def test_bad_input_is_a_clear_error():
    with pytest.raises(ValueError, match="scores"):
        suppress_indices(np.zeros((2, 4)), np.zeros(3))
    with pytest.raises(ValueError, match="boxes"):
        suppress_indices(np.zeros(5), np.zeros(1))
    with pytest.raises(TypeError, match="detections"):
        suppress(np.zeros((1, 4)))  # pyright: ignore[reportArgumentType]
    with pytest.raises(ValueError, match="loc_iou"):
        ErrorBreakdown().add(np.zeros((1, 4)), np.zeros((1, 4)), loc_iou=0.6)


def test_refit_snaps_a_shifted_box_to_the_contrasting_blob():
    z = np.zeros((120, 160))
    z[40:60, 50:110] = 10.0  # the boat, working px
    got = refit_boxes(z, 0.5, np.array([[90.0, 70.0, 100.0, 50.0]]), 3.0)  # input px
    np.testing.assert_allclose(got[0], [100, 80, 120, 40])
    empty = np.array([[0.0, 0.0, 20.0, 20.0]])
    np.testing.assert_allclose(refit_boxes(z, 0.5, empty, 3.0), empty)


def test_select_is_threshold_share_then_opencv_nms():
    rng = np.random.default_rng(4)
    b = random_boxes(rng, 30)
    s = rng.uniform(0, 1, 30)
    got = select(b, s, 0.2, 0.5, 0.4)
    ok = (s >= 0.2) & (s >= 0.5 * s.max())
    idx = np.flatnonzero(ok)
    ref = np.asarray(cv2.dnn.NMSBoxes(b[idx].tolist(), s[idx].tolist(), 0.0, 0.4)).ravel()
    assert sorted(got.tolist()) == sorted(idx[ref].tolist())


def test_candidates_features_and_a_verifier_that_learns_the_boat():
    from tests.test_shore_contrast import SKY_LINE, scene

    img = scene(0)
    cnn = Detections(
        np.array([[95.0, 90, 100, 45], [10, 200, 30, 10]]), np.array([0.6, 0.4]), np.full(2, -1)
    )
    c = candidates(img, SKY_LINE, cnn)
    assert c.features.shape == (len(c.boxes), n_features())
    assert np.isfinite(c.features).all()
    truth = np.array([[100.0, 96, 90, 36]])
    y = iou_matrix(truth, c.boxes)[0]
    x = np.concatenate([c.features] * 20)
    model = BoxVerifier(max_iter=30).fit(x, np.tile(y, 20), ["a"] * len(x))
    p = model.predict(c.features)
    assert np.argmax(p) == np.argmax(y) and y.max() > 0.5
    assert box_features(
        img, None, np.zeros((240, 320)), 1.0, np.zeros((0, 4)), *[np.zeros(0)] * 2, cnn, cnn, 3.0
    ).shape == (0, n_features())


def test_suppression_pair_is_picked_on_the_other_videos_and_breakdown_prints():
    from io import StringIO

    from rich.console import Console

    from usvfast.shore.det_scoring import VideoFrames
    from usvfast.shore.det_tables import print_breakdown
    from usvfast.shore.evaluate_det import suppression_rows
    from usvfast.shore.horizon import HorizonConfig
    from usvfast.shore.mardct import AnnotatedFrame

    ship = np.array([[100.0, 100, 200, 40]])
    part = np.array([[110.0, 105, 50, 30]])  # a bow box inside the ship
    img = np.zeros((240, 400, 3), np.uint8)
    videos, dets = {}, {}
    for v in ("a", "b", "c"):
        frames = [AnnotatedFrame(v, k, __file__, ship) for k in range(3)]  # pyright: ignore[reportArgumentType]
        videos[v] = VideoFrames(frames, [img] * 3, [None] * 3)
        d = Detections(np.concatenate([ship, part]), np.array([0.9, 0.8]), np.full(2, -1))
        dets[v] = [d] * 3
    (_, c), rows = suppression_rows(videos, "a", dets, HorizonConfig(), "toy")
    assert c <= 0.7  # only containment removes the bow box; equal TPR, lowest FAR wins
    assert rows[0]["tp"] == 3 and rows[0]["fp"] == 0
    out = StringIO()
    print_breakdown({"a": {"rows": rows}}, Console(file=out, width=200))
    assert "toy" in out.getvalue()
