"""Shore-camera chain: boxes, scores, horizon line, day/night classifier, threshold +
keypoint detector (eqs. 4–8 against scipy), pixel Kalman filter (filterpy), the trackers,
the frame reader on a truncated video, the `usvfast shore` command, and real MarDCT frames."""

from __future__ import annotations

import json
import warnings

import cv2
import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from scipy import ndimage
from typer.testing import CliRunner

from usvfast.cli import app
from usvfast.shore import (
    DamagedVideoWarning,
    DayNightClassifier,
    Detections,
    FrameSource,
    HorizonConfig,
    SortTracker,
    detect_horizon,
    iou_matrix,
)
from usvfast.shore.bayes import BayesDetector
from usvfast.shore.cascade import CascadeConfig
from usvfast.shore.evaluate import derive_truth_ids, evaluate
from usvfast.shore.horizon import horizon_keep
from usvfast.shore.mardct import load_mardct
from usvfast.shore.mot import mot_rows, read_mot
from usvfast.shore.pixel_kalman import AdaptiveTracker, paper_model
from usvfast.shore.scores import DetectionCounts, matched_pairs


def test_iou_matrix_equals_pixel_counts():
    # integer boxes: IoU by counting the pixels of rasterised masks
    rng = np.random.default_rng(1)
    a = np.column_stack([rng.integers(0, 60, (6, 2)), rng.integers(1, 30, (6, 2))])
    b = np.column_stack([rng.integers(0, 60, (5, 2)), rng.integers(1, 30, (5, 2))])
    b[0] = a[0] + [3, 2, 0, 0]

    def mask(box):
        m = np.zeros((100, 100), bool)
        m[box[1] : box[1] + box[3], box[0] : box[0] + box[2]] = True
        return m

    ref = np.array([[(mask(p) & mask(q)).sum() / (mask(p) | mask(q)).sum() for q in b] for p in a])
    np.testing.assert_allclose(iou_matrix(a, b), ref, atol=1e-12)
    assert ref[0, 0] > 0.3


def test_detection_counts_one_to_one():
    truth = np.array([[0, 0, 10, 10], [20, 0, 10, 10]], float)
    # two detections on the first box (one counts), one miss, one far false positive
    det = np.array([[0, 0, 10, 10], [1, 0, 10, 10], [60, 60, 5, 5]], float)
    assert matched_pairs(truth, det) == 1
    c = DetectionCounts()
    c.add(truth, det)
    c.add(truth, np.zeros((0, 4)))
    assert (c.tp, c.fp, c.fn) == (1, 2, 3)
    assert c.tpr == pytest.approx(0.25) and c.far == pytest.approx(2 / 3)


def synthetic_horizon(tilt_px: float = 6.0, wake: bool = True) -> tuple[np.ndarray, float]:
    """Bright sky over dark water meeting at a slightly tilted line near y = 80 (320 × 240),
    with a bright wake stripe in the water (equal water on both sides)."""
    rng = np.random.default_rng(0)
    h, w = 240, 320
    xs = np.arange(w)
    line = 80 + tilt_px * xs / w
    rows = np.arange(h)[:, None]
    img = np.where(rows < line[None], 200.0, 70.0) + rng.normal(0, 2, (h, w))
    if wake:
        img[170:173, 20:300] = 160.0
    return np.clip(img, 0, 255).astype(np.uint8), 80 + tilt_px / 2


def test_horizon_found_and_wake_rejected():
    img, mid = synthetic_horizon()
    hz = detect_horizon(img)
    assert hz is not None
    assert abs(float(hz.y_at(160.0)) - mid) < 2.0
    assert hz.kind == "water-sky" and hz.differing > 0.9
    # the wake stripe alone: water of equal intensity on both sides, not a valid horizon
    water = np.full((240, 320), 70, np.uint8)
    water[170:173, 20:300] = 160
    assert detect_horizon(water) is None
    # detections well above the line are dropped, boats on it kept
    dets = Detections(np.array([[100, 10, 30, 20], [150, 60, 40, 25]], float), np.ones(2))
    keep = horizon_keep(dets, hz, 240, HorizonConfig())
    assert keep.tolist() == [False, True]


def test_horizon_coast_from_texture():
    img, _ = synthetic_horizon(wake=False)
    rng = np.random.default_rng(2)
    for _ in range(60):  # buildings of the coast above the water
        x, y = int(rng.integers(0, 300)), int(rng.integers(30, 70))
        img[y:80, x : x + int(rng.integers(6, 20))] = int(rng.integers(90, 250))
    hz = detect_horizon(img)
    assert hz is not None and hz.kind == "water-coast"
    assert abs(float(hz.y_at(160.0)) - 83.0) < 4.0


def test_day_night_classifier():
    rng = np.random.default_rng(4)
    colour = rng.integers(0, 255, (60, 80, 3), dtype=np.uint8)
    colour[..., 0] //= 3  # strongly coloured
    grey = cv2.cvtColor(cv2.cvtColor(colour, cv2.COLOR_BGR2GRAY), cv2.COLOR_GRAY2BGR)
    clf = DayNightClassifier.default()
    assert clf.classify(colour) == "eo" and clf.classify(grey) == "ir"
    p = clf.posteriors(colour)
    assert p.sum() == pytest.approx(1.0) and p[0] > 0.99


def test_threshold_and_morphology_equal_the_equations():
    rng = np.random.default_rng(7)
    gray = rng.integers(0, 255, (50, 60)).astype(np.uint8)
    det = BayesDetector()
    b = det.binary(cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR), "eo")
    # eq. 4: 255 where r > 23; eq. 8 with eq. 7: erosion keeps a pixel when all S = 9 pixels
    # of the 3×3 window are set, dilation when at least one is (borders as OpenCV: replicate
    # the set state, i.e. outside counts as set for erosion and unset for dilation)
    f = (gray > 23).astype(int)
    ones = np.ones((3, 3))
    for _ in range(2):
        f = (ndimage.convolve(f, ones, mode="constant", cval=1) >= 9).astype(int)
    for _ in range(2):
        f = (ndimage.convolve(f, ones, mode="constant", cval=0) >= 1).astype(int)
    np.testing.assert_array_equal(b > 0, f > 0)


def test_bayes_detector_boxes_a_dark_vessel():
    img = np.full((120, 160, 3), (170, 140, 110), np.uint8)  # a colour (EO) frame
    cv2.rectangle(img, (50, 60), (110, 80), (10, 10, 10), -1)  # hull darker than 23
    cv2.rectangle(img, (70, 45), (85, 60), (10, 10, 10), -1)  # superstructure
    d = BayesDetector().detect(img)
    assert len(d) == 1 and d.keypoints[0] >= 3
    assert iou_matrix(d.boxes, np.array([[50, 45, 60, 35]]))[0, 0] > 0.5


def test_pixel_kalman_equals_filterpy_and_rejects_jumps():
    model, h, r = paper_model()
    f, q = model.matrices(1.0)
    tr = AdaptiveTracker()
    kf = KalmanFilter(dim_x=4, dim_z=2)
    centres = [(100.0 + 3 * k, 50.0 + k) for k in range(8)]
    out = []
    for k, (cx, cy) in enumerate(centres):
        box = np.array([[cx - 10, cy - 5, 20, 10]])
        if k == 5:  # a jump far from the vessel: replaced by the prediction
            box = np.array([[cx + 150, cy - 5, 20, 10]])
        out.append(tr.step(Detections(box, np.ones(1))))
        if k == 0:
            kf.x = np.array([cx, cy, 0.0, 0.0])
            kf.P = np.diag([1.0, 1.0, 100.0, 100.0])
            kf.F, kf.Q, kf.H, kf.R = f, q, h, r
            continue
        kf.predict()
        if k != 5:
            kf.update(np.array([cx, cy]))
        else:
            assert tr.last_predicted
            np.testing.assert_allclose(out[-1].boxes[0, :2] + [10, 5], kf.x[:2], atol=1e-9)
        np.testing.assert_allclose(tr.x, kf.x, atol=1e-9)
        np.testing.assert_allclose(tr.p, kf.P, atol=1e-9)


def _boat(img: np.ndarray, box, colour) -> None:
    x, y, w, h = (int(v) for v in box)
    img[y : y + h, x : x + w] = colour


def test_sort_keeps_ids_and_reidentifies_by_colour():
    tracker = SortTracker()
    ids_seen: dict[int, set[int]] = {0: set(), 1: set()}
    for k in range(12):
        img = np.full((240, 320, 3), 90, np.uint8)
        boxes = np.array([[20 + 6 * k, 100, 40, 20], [260 - 6 * k, 160, 40, 20]], float)
        _boat(img, boxes[0], (0, 0, 255))
        _boat(img, boxes[1], (255, 0, 0))
        # frames 6 and 7: the red boat is missed, then comes back
        dets = boxes if k not in (6, 7) else boxes[1:]
        ids, out, _ = tracker.step(img, Detections(dets, np.ones(len(dets))))
        for i, b in zip(ids, out, strict=True):
            j = int(np.argmax(iou_matrix(b[None], boxes)[0]))
            ids_seen[j].add(int(i))
            assert iou_matrix(b[None], boxes[j : j + 1])[0, 0] > 0.7
    assert len(ids_seen[0]) == 1 and len(ids_seen[1]) == 1
    assert ids_seen[0] != ids_seen[1]


def test_truncated_video_processed_up_to_the_damage(tmp_path):
    path = tmp_path / "clip.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 48))
    for i in range(30):
        w.write(np.full((48, 64, 3), 8 * i, np.uint8))
    w.release()
    data = path.read_bytes()
    cut = tmp_path / "cut.avi"
    cut.write_bytes(data[: len(data) // 2])
    src = FrameSource(cut)
    with pytest.warns(DamagedVideoWarning, match="undecoded"):
        n = sum(1 for _ in src)
    assert 0 < n < 30 and src.undecoded == 30 - n
    with pytest.raises(ValueError, match="input"):
        FrameSource(tmp_path / "missing.mp4")


def test_shore_command_writes_mot_files(tmp_path):
    frames = tmp_path / "frames"
    frames.mkdir()
    for k in range(6):
        img = np.full((120, 160, 3), (200, 170, 150), np.uint8)
        img[60:, :] = (120, 90, 60)
        cv2.rectangle(img, (30 + 5 * k, 50), (70 + 5 * k, 65), (5, 5, 5), -1)
        cv2.imwrite(str(frames / f"f_{k:03d}.png"), img)
    out = tmp_path / "out"
    args = ["shore", str(frames), "--out", str(out), "--no-progress", "--detector", "bayes"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    det, trk = read_mot(out / "detections.txt"), read_mot(out / "tracks.txt")
    assert len(det) == 6 and np.all(det[:, 1] == -1) and det[:, 0].tolist() == [1, 2, 3, 4, 5, 6]
    assert len(trk) >= 4 and len(np.unique(trk[:, 1])) == 1
    assert np.all(trk[:, 7:] == -1)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"] == 6 and summary["undecoded_frames"] == 0
    cap = cv2.VideoCapture(str(out / summary["outputs"]["video"]))
    assert cap.isOpened() and cap.read()[0]
    bad = CliRunner().invoke(app, ["shore", str(tmp_path / "nope"), "--out", str(out)])
    assert bad.exit_code != 0 and "input" in bad.output


def test_derived_truth_ids_link_nearby_boxes():
    class F:
        def __init__(self, boxes):
            self.boxes = np.array(boxes, float).reshape(-1, 4)

    ids = derive_truth_ids([F([[0, 0, 10, 10]]), F([[300, 0, 10, 10], [5, 0, 10, 10]]), F([])])
    assert ids[0].tolist() == [1] and ids[1].tolist() == [2, 1] and len(ids[2]) == 0


def test_mardct_frames_classify_eo_and_horizon_meets_the_boats(mardct_annotations):
    videos = load_mardct(mardct_annotations)
    assert {k: len(v) for k, v in videos.items()} == {"2": 14, "3": 5, "regDTV9": 70, "video3": 103}
    frames = videos["regDTV9"][::7]
    clf = DayNightClassifier.default()
    hits = found = 0
    for f in frames:
        img = cv2.imread(str(f.path))
        assert clf.classify(img) == "eo"
        grey = cv2.cvtColor(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), cv2.COLOR_GRAY2BGR)
        assert clf.classify(grey) == "ir"
        hz = detect_horizon(img)
        if hz is None:
            continue
        found += 1
        # open sea: the boats sit on the water–sky line, which crosses their boxes
        b = f.boxes
        y = hz.y_at(b[:, 0] + b[:, 2] / 2)
        hits += int(np.all((y > b[:, 1]) & (y < b[:, 1] + b[:, 3] + 3)))
    assert found >= 7 and hits >= 0.8 * found


def test_default_classifier_is_the_fit_on_mardct(mardct_annotations):
    files = sorted(mardct_annotations.glob("*.png"))[::8]
    eo = [cv2.imread(str(p)) for p in files]
    ir = [cv2.cvtColor(cv2.cvtColor(i, cv2.COLOR_BGR2GRAY), cv2.COLOR_GRAY2BGR) for i in eo]
    fit = DayNightClassifier.fit(eo, ir)
    d = DayNightClassifier.default()
    np.testing.assert_allclose(fit.means, d.means, atol=3.0)


def test_leave_one_out_runs_on_the_small_videos(mardct_annotations, tmp_path):
    sub = tmp_path / "ann"
    sub.mkdir()
    for p in mardct_annotations.glob("3_*"):
        (sub / p.name).symlink_to(p)
    for p in mardct_annotations.glob("2_*"):
        (sub / p.name).symlink_to(p)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        small = CascadeConfig(max_stages=4, pool_size=2000, negatives_per_stage=300, max_weak=15)
        res = evaluate(sub, grid=(60.0, 140.0), cascade=small)
    assert set(res) == {"2", "3"}
    r = res["3"]
    s = r["paper_no_horizon"]
    assert s["tp"] + s["fn"] == r["boxes"] == 8
    assert r["tuned_threshold"] in (60.0, 140.0)
    assert -10 < r["tracking"]["bayes"]["sort"]["mota"] <= 1.0
    c = r["cascade_horizon"]
    assert c["tp"] + c["fn"] == 8 and r["cascade_stages"] >= 1
    assert set(r["tracking"]["cascade"]) == {"sort", "particle", "adaptive"}
    assert r["tracking"]["truth boxes"]["particle"]["mota"] > 0.5


def test_mot_rows_check_their_arguments():
    rows = mot_rows(3, [7, 8], [[1.0, 2, 3, 4], [5, 6, 7, 8]], [0.5, 0.25])
    np.testing.assert_array_equal(rows[:, :7], [[3, 7, 1, 2, 3, 4, 0.5], [3, 8, 5, 6, 7, 8, 0.25]])
    assert (rows[:, 7:] == -1).all()
    with pytest.raises(ValueError, match="ids: expected 1 values"):
        mot_rows(1, [1, 2, 3, 4], [0.0, 0, 1, 1], [0.9] * 4)  # one box, not four
    with pytest.raises(ValueError, match="boxes: expected shape"):
        mot_rows(1, [1], [0.0, 0, 1], [0.9])
    with pytest.raises(TypeError, match="frame: expected an integer"):
        mot_rows(None, [1], [0.0, 0, 1, 1], [0.9])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="frame: must be in"):
        mot_rows(0, [1], [0.0, 0, 1, 1], [0.9])


def test_state_to_box_inverts_box_to_z_and_stays_finite():
    from usvfast.shore.sort import box_to_z, state_to_box

    boxes = np.array([[10.0, 20.0, 30.0, 15.0], [0.0, 0.0, 1.0, 400.0], [5.0, 5.0, 640.0, 2.0]])
    z = np.vstack([box_to_z(b) for b in boxes])
    np.testing.assert_allclose(state_to_box(z), boxes, rtol=1e-12, atol=1e-9)
    huge = state_to_box(np.array([[0.0, 0.0, 1e300, 1e300]]))  # s r overflows float64
    np.testing.assert_allclose(huge, [[-5e299, -0.5, 1e300, 1.0]], rtol=1e-12)


def test_box_areas_beyond_float64_and_nan_boxes_are_errors():
    from usvfast.shore.boxes import intersection_matrix

    with pytest.raises(ValueError, match="a, b: out of the representable range"):
        intersection_matrix(np.full((1, 4), 1e300), np.full((1, 4), 1e300))
    with pytest.raises(ValueError, match="b: contains a non-finite value"):
        intersection_matrix(np.zeros((1, 4)), np.full((1, 4), np.nan))
