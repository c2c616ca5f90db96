"""Haar cascade trained in Rust: it separates boats from water on synthetic windows, its
OpenCV XML loads in `cv2.CascadeClassifier` (an opencv-contrib build; the headless 5.x wheel
has no cascade module) with the same accept/reject decisions as our evaluator, and it trains
and detects on real MarDCT frames."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from usvfast._core import HaarCascade
from usvfast.cli import app
from usvfast.shore.cascade import CascadeConfig, group_boxes, train_detector
from usvfast.shore.mardct import load_mardct
from usvfast.shore.mot import read_mot
from usvfast.shore.scores import DetectionCounts

has_cascade_module = hasattr(cv2, "CascadeClassifier")


def synthetic_windows(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """60 × 30 windows: hulls (dark bar + superstructure on brighter water) and water only."""
    rng = np.random.default_rng(seed)
    pos, neg = [], []
    for _ in range(120):
        w = rng.normal(120, 8, (30, 60))
        y0 = int(rng.integers(13, 17))
        w[y0 : y0 + 8, 6:54] = rng.normal(40, 6)
        x0 = int(rng.integers(18, 30))
        w[y0 - 7 : y0, x0 : x0 + 12] = rng.normal(60, 6)
        pos.append(w)
    for _ in range(3000):
        w = rng.normal(rng.uniform(60, 200), rng.uniform(2, 30), (30, 60))
        if rng.random() < 0.3:  # a bright wake stripe
            r = int(rng.integers(3, 25))
            w[r : r + 3] += 60
        neg.append(w)
    cast = lambda a: np.ascontiguousarray(np.clip(a, 0, 255).astype(np.uint8))  # noqa: E731
    return cast(np.array(pos)), cast(np.array(neg))


@pytest.fixture(scope="module")
def cascade() -> HaarCascade:
    pos, neg = synthetic_windows(0)
    return HaarCascade.train(
        pos, neg, max_stages=6, negatives_per_stage=400, feature_step=6, max_weak=20
    )


def test_cascade_separates_boats_from_water(cascade):
    pos, neg = synthetic_windows(1)  # fresh samples
    assert cascade.num_stages >= 1 and cascade.window_size == (60, 30)
    assert cascade.accepts(pos).mean() > 0.95
    assert cascade.accepts(neg).mean() < 0.02
    r = cascade.stage_reports[0]
    assert r["hit_rate"] >= 0.995 and r["false_alarm"] <= 0.5
    # a boat pasted into a larger image is found where it is
    img = np.full((120, 200), 120, np.uint8)
    img[50:80, 70:130] = pos[0]
    hits = cascade.scan(img, 1)
    assert len(hits) and np.abs(hits - [70, 50]).max(axis=1).min() <= 2


def test_cascade_rejects_bad_input(cascade):
    pos, neg = synthetic_windows(2)
    with pytest.raises(ValueError, match="min_hit_rate"):
        HaarCascade.train(pos, neg, min_hit_rate=1.5)
    with pytest.raises(ValueError, match="windows"):
        cascade.accepts(pos[:, :20, :40].copy())
    with pytest.raises(ValueError, match="negatives"):
        cascade.add_stage(pos, np.zeros((3, 20, 20), np.uint8))


def test_opencv_loads_the_xml_and_agrees(cascade, tmp_path):
    # OpenCV 5 moved CascadeClassifier to the contrib build; `make dev` installs
    # opencv-contrib-python-headless (a superset of the headless wheel) so this always runs.
    assert has_cascade_module, (
        "cv2 has no CascadeClassifier: install opencv-contrib-python-headless"
    )
    path = tmp_path / "boat.xml"
    path.write_text(cascade.to_opencv_xml())
    cv = cv2.CascadeClassifier(str(path))
    assert not cv.empty()
    pos, neg = synthetic_windows(3)
    windows = np.concatenate([pos[:60], neg[:200]])
    ours = cascade.accepts(windows)
    theirs = []
    for w in windows:
        # OpenCV scans (size − window) positions: pad by 2 px so only (0, 0) is tried
        img = cv2.copyMakeBorder(w, 0, 2, 0, 2, cv2.BORDER_REPLICATE)
        r = cv.detectMultiScale(img, scaleFactor=1.5, minNeighbors=0, minSize=(60, 30))
        theirs.append(any(x == 0 and y == 0 for x, y, _, _ in np.reshape(r, (-1, 4))))
    assert np.mean(ours == np.array(theirs)) >= 0.98
    assert ours[:60].mean() > 0.9


def test_group_boxes_needs_neighbours():
    boxes = np.array([[10, 10, 60, 30], [12, 10, 60, 30], [11, 11, 60, 30], [200, 5, 60, 30]])
    d = group_boxes(boxes.astype(float), min_neighbors=2, iou=0.3)
    assert len(d) == 1 and np.allclose(d.boxes[0], [11, 10.333333, 60, 30])


def test_cascade_trains_and_detects_on_mardct(mardct_annotations):
    frames = [f for v in ("2", "3") for f in load_mardct(mardct_annotations)[v]]
    cfg = CascadeConfig(max_stages=6, pool_size=4000, negatives_per_stage=400, max_weak=20)
    det, report = train_detector(frames, cfg)
    assert report["positives"] == 2 * sum(len(f.boxes) for f in frames)
    c = DetectionCounts()
    for f in frames:
        c.add(f.boxes, det.detect(cv2.imread(str(f.path))).boxes)
    assert c.tpr > 0.5


def test_shore_train_then_shore_with_the_cascade(mardct_annotations, tmp_path):
    ann = tmp_path / "ann"
    ann.mkdir()
    for p in mardct_annotations.glob("3_*"):
        (ann / p.name).symlink_to(p)
    model = tmp_path / "boat.xml"
    runner = CliRunner()
    res = runner.invoke(app, ["shore-train", str(ann), "--out", str(model), "--max-stages", "5"])
    assert res.exit_code == 0, res.output
    cascade = HaarCascade.from_opencv_xml(model.read_text())
    windows = np.concatenate(synthetic_windows(4))
    again = HaarCascade.from_opencv_xml(cascade.to_opencv_xml())
    np.testing.assert_array_equal(again.accepts(windows), cascade.accepts(windows))
    frames = tmp_path / "frames"
    frames.mkdir()
    for p in mardct_annotations.glob("3_*.png"):
        (frames / p.name).symlink_to(p)
    out = tmp_path / "out"
    args = ["shore", str(frames), "--out", str(out), "--detector", "cascade", "--model", str(model)]
    res = runner.invoke(app, [*args, "--no-progress", "--no-video"])
    assert res.exit_code == 0, res.output
    det = read_mot(out / "detections.txt")
    assert len(det) >= 3 and set(det[:, 0].astype(int)) <= {1, 2, 3, 4, 5}
    bad = runner.invoke(app, ["shore", str(frames), "--out", str(out), "--detector", "cascade"])
    assert bad.exit_code != 0 and "cascade_model" in bad.output
    with pytest.raises(ValueError, match="xml"):
        HaarCascade.from_opencv_xml("<cascade/>")
