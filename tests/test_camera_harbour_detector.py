"""The bundled harbour demo detector on frames rendered by the simulator from seeds it never saw
in training: both backends (ONNX through OpenCV DNN, TorchScript through torch) give the same
boxes; the detector reaches the stated precision and recall at IoU >= 0.5; wrong input shapes
are clear errors; the training is reproducible from its seed."""

from __future__ import annotations

import sys

import numpy as np
import pytest
import torch

from usvfast.camera.backends import demo_weights, load_detector, model_card
from usvfast.camera.detect import Detections
from usvfast.camera.dnn import OnnxDetector
from usvfast.camera.train_demo import (
    HELDOUT_SEEDS,
    TRAIN_SEEDS,
    Frame,
    TrainConfig,
    evaluate,
    match_counts,
    render_frames,
    train,
)
from usvfast.camera.yolo import YoloDetector

# Held-out seeds for this test: after those of the training and of the model card's figures.
TEST_SEEDS = (2100, 2101, 2102)


@pytest.fixture(scope="module")
def frames():
    return [f for s in TEST_SEEDS for f in render_frames(s, 4)]


@pytest.fixture(scope="module")
def card():
    return model_card(demo_weights("onnx"))


def test_bundled_weights_are_small_and_described(card):
    for backend in ("onnx", "torch"):
        assert demo_weights(backend).stat().st_size < 2_000_000
    assert card["layout"] == "v8" and card["input_size"] == [640, 368]
    assert card["classes"][:3] == ["bottle", "bag", "box"]
    assert "not a detector of real floating trash" in card["about"]
    assert set(TEST_SEEDS).isdisjoint(TRAIN_SEEDS + HELDOUT_SEEDS)
    seeds = set(card["train"]["train_seeds"])
    assert seeds <= set(range(1000, 2000)) and seeds.isdisjoint(HELDOUT_SEEDS)
    assert set(TRAIN_SEEDS) <= set(range(1000, 2000))


def test_both_backends_same_boxes_on_rendered_frames(frames):
    onnx = load_detector("onnx", demo_weights("onnx"), conf_threshold=0.3)
    pt = load_detector("torch", demo_weights("torch"), conf_threshold=0.3)
    assert isinstance(onnx, OnnxDetector) and isinstance(pt, YoloDetector)
    n = 0
    for f in frames:
        raw_o, _ = onnx.raw([f.image])
        raw_t, _ = pt.raw([f.image])
        np.testing.assert_allclose(raw_o, raw_t, rtol=1e-4, atol=1e-3)
        (do,), (dt,) = onnx([f.image]), pt([f.image])
        assert len(do.boxes) == len(dt.boxes)
        np.testing.assert_allclose(do.boxes, dt.boxes, atol=1e-2)  # px
        np.testing.assert_allclose(do.scores, dt.scores, atol=1e-4)
        np.testing.assert_array_equal(do.classes, dt.classes)
        n += len(do.boxes)
    assert n >= len(frames)  # the comparison covered real detections


def test_openvino_runtime_gives_opencv_dnns_boxes(frames):
    """runtime="openvino" runs the same float32 network: raw outputs within 1e-3 (measured
    9e-5), boxes within 1e-3 px (measured 2e-5) and scores within 1e-5 (3e-7)."""
    cv = load_detector("onnx", demo_weights("onnx"), conf_threshold=0.3, runtime="opencv")
    ov = load_detector("onnx", demo_weights("onnx"), conf_threshold=0.3, runtime="openvino")
    assert (cv.runtime, ov.runtime) == ("opencv", "openvino")  # pyright: ignore[reportAttributeAccessIssue]
    n = 0
    for f in frames:
        np.testing.assert_allclose(ov.raw([f.image])[0], cv.raw([f.image])[0], atol=1e-3)
        (dc,), (do,) = cv([f.image]), ov([f.image])
        assert len(dc.boxes) == len(do.boxes)
        np.testing.assert_allclose(do.boxes, dc.boxes, atol=1e-3)
        np.testing.assert_allclose(do.scores, dc.scores, atol=1e-5)
        np.testing.assert_array_equal(do.classes, dc.classes)
        n += len(dc.boxes)
    assert n >= len(frames)


def test_runtime_choice_and_errors(monkeypatch):
    from usvfast._extras import MissingExtraError
    from usvfast.pipeline import ConfigError, load_config
    from usvfast.pipeline.camera_chain import load_detector as from_table

    bundled = demo_weights("onnx").parents[1] / "harbour" / "recording.toml"
    cfg = load_config(bundled, {"detector.runtime": "opencv"})
    assert from_table(cfg.detector, bundled.parent).runtime == "opencv"
    assert load_config(bundled).detector["runtime"] == "auto"
    with pytest.raises(ConfigError, match=r"key 'detector\.runtime'"):
        load_config(bundled, {"detector.runtime": "tensorrt"})
    with pytest.raises(ConfigError, match=r"key 'detector\.runtime': 'openvino' runs ONNX"):
        load_config(bundled, {"detector.runtime": "openvino", "detector.backend": "torch"})
    with pytest.raises(ValueError, match="runtime: expected one of"):
        OnnxDetector(demo_weights("onnx"), runtime="tensorrt")
    monkeypatch.setitem(sys.modules, "openvino", None)
    assert OnnxDetector(demo_weights("onnx")).runtime == "opencv"  # auto without OpenVINO
    with pytest.raises(MissingExtraError, match=r"usvfast\[openvino\]"):
        OnnxDetector(demo_weights("onnx"), runtime="openvino")


def test_precision_recall_on_unseen_seeds(frames, card):
    det = load_detector("onnx", demo_weights("onnx"), conf_threshold=card["conf_threshold"])
    m = evaluate(det, frames, min_box_px=card["train"]["min_box_px"])
    assert m["truth"] >= 20
    # Measured on these 12 frames: precision 0.59, recall 0.91 (49 of 54 boxes, 34 false; the
    # model card's 24 frames of seeds 2000-2002: 0.52 / 0.85). The network bundled before
    # gave 0.71 / 0.67 here: today's recipe finds the small floats and pays in false boxes
    # (the demo pipeline runs it at 0.5). Most misses and false alarms are trash boxes of
    # 3-6 px, where a 1 px offset already costs IoU 0.5.
    assert m["precision"] >= 0.55, m
    assert m["recall"] >= 0.85, m


def test_wrong_input_shape_is_a_clear_error(frames):
    with pytest.raises(ValueError, match=r"input_size: harbour-demo.onnx takes"):
        OnnxDetector(demo_weights("onnx"), input_size=(640, 640))
    det = YoloDetector(demo_weights("torch"), input_size=(640, 640))
    with pytest.raises(ValueError, match="input_size: the network rejected"):
        det([frames[0].image])
    with pytest.raises(FileNotFoundError, match="weights"):
        load_detector("onnx", "harbour-missing.onnx")


def test_match_counts_greedy_by_score():
    truth = np.array([[0, 0, 10, 10], [20, 0, 30, 10], [50, 50, 52, 52.0]])
    det = Detections(
        np.array([[0, 0, 10, 9], [1, 0, 10, 10], [20, 0, 26, 10], [100, 100, 110, 110.0]]),
        np.array([0.9, 0.8, 0.7, 0.6]),
        np.array([0, 0, 1, 0]),
    )
    ignore = np.array([False, False, True])
    # 0 matches truth 0; 1 is a duplicate (fp); 2 has IoU 0.6 with truth 1; 3 matches nothing.
    assert match_counts(det, truth, np.array([0, 1, 0]), ignore) == (2, 2, 0)
    assert match_counts(det, truth, np.array([0, 0, 0]), ignore, class_aware=True) == (1, 3, 1)
    assert match_counts(det, truth, np.zeros(3), ignore, iou=0.7) == (1, 3, 1)


def test_training_is_reproducible():
    rng = np.random.default_rng(0)
    frames = [
        Frame(
            rng.integers(0, 255, (96, 160, 3), dtype=np.uint8),
            np.array([[20.0, 30.0, 40.0, 42.0]]),
            np.array([1]),
        )
        for _ in range(2)
    ]
    cfg = TrainConfig(
        input_size=(160, 96), crop_size=(96, 64), width=4, steps=3, batch=2, classes=("a", "b")
    )
    nets = [train(cfg, frames, log=lambda _: None) for _ in range(2)]
    for (k, a), (_, b) in zip(
        nets[0].state_dict().items(), nets[1].state_dict().items(), strict=True
    ):
        assert torch.equal(a, b), k


def test_evaluate_per_class_recall():
    """Each class's recall counts only its own boxes, matched by detections of its class."""
    boxes = np.array([[0, 0, 10, 10], [20, 0, 30, 10], [40, 0, 50, 10.0]])
    frame = Frame(np.zeros((16, 64, 3), np.uint8), boxes, np.array([0, 1, 1]))
    # truth 0 found with its class; truth 1 found with the wrong class; truth 2 missed
    det = Detections(boxes[:2], np.array([0.9, 0.8]), np.array([0, 0]))
    m = evaluate(lambda _: [det], [frame], min_box_px=3.0)
    assert m["recall"] == pytest.approx(2 / 3) and m["class_recall"] == pytest.approx(1 / 3)
    assert m["class0_recall"] == 1.0 and m["class0_truth"] == 1
    assert m["class1_recall"] == 0.0 and m["class1_truth"] == 2


def test_class_weights_centre_more_crops_on_the_rare_class():
    """With a weight of 8 on class 1, most object-centred crops hold the class-1 box."""
    from usvfast.camera.train_demo import Sample, random_crop

    boxes = np.array([[10.0, 10, 30, 30], [290, 150, 310, 170]])
    s = Sample(np.zeros((192, 320, 3), np.uint8), boxes, np.array([0, 1]))
    w = np.array([1.0, 8.0])

    def share(weights):
        rng = np.random.default_rng(1)
        crops = [random_crop(s, (96, 64), rng, weights) for _ in range(400)]
        return np.mean([1 in c for _, _, c in crops])

    assert share(w) > 0.6 > 0.5 > share(None)
