"""YOLO wrapper end to end on a randomly initialised YOLO-layout network: letterbox, decoding
of both layouts, Rust NMS, inverse mapping to original pixels; TorchScript and nn.Module; the
camera pipeline's filters; the NMS against a straightforward reference (hypothesis)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st
from yolo_nets import KnownBoxesYolo

from usvfast.camera import REASONS, FovCamera, nms
from usvfast.camera.detect import GridDetector
from usvfast.camera.yolo import CameraPipeline, Detections, YoloDetector, decode, letterbox


def ref_nms(boxes, scores, thr, classes=None):
    """Textbook greedy NMS: take the best remaining box, drop its same-class overlaps."""
    classes = np.zeros(len(boxes), int) if classes is None else classes
    alive = list(np.lexsort((np.arange(len(boxes)), -scores)))
    kept = []
    while alive:
        i = alive.pop(0)
        kept.append(i)
        rest = []
        for j in alive:
            a, b = boxes[i], boxes[j]
            w = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
            h = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
            inter = w * h
            union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
            iou = inter / union if union > 0 else 0.0
            if not (classes[i] == classes[j] and iou > thr):
                rest.append(j)
        alive = rest
    return np.array(kept, dtype=np.int64)


def random_boxes(rng, n):
    xy = rng.uniform(0, 200, (n, 2))
    wh = rng.uniform(1, 60, (n, 2))
    return np.hstack([xy, xy + wh]), rng.integers(0, 20, n) / 20.0, rng.integers(0, 3, n)


@given(st.integers(0, 2**32 - 1), st.integers(0, 300), st.floats(0.0, 1.0))
def test_nms_equals_reference(seed, n, thr):
    boxes, scores, cls = random_boxes(np.random.default_rng(seed), n)
    np.testing.assert_array_equal(nms(boxes, scores, thr), ref_nms(boxes, scores, thr))
    np.testing.assert_array_equal(nms(boxes, scores, thr, cls), ref_nms(boxes, scores, thr, cls))


def test_nms_torchvision_semantics():
    # IoU exactly at the threshold is kept (strictly-greater suppresses); order by score.
    boxes = np.array([[0, 0, 10, 10], [0, 0, 10, 5], [20, 20, 30, 30.0]])
    scores = np.array([0.5, 0.9, 0.7])
    np.testing.assert_array_equal(nms(boxes, scores, 0.5), [1, 2, 0])
    np.testing.assert_array_equal(nms(boxes, scores, 0.49), [1, 2])
    assert nms(np.zeros((0, 4)), np.zeros(0), 0.5).shape == (0,)
    with pytest.raises(ValueError, match="boxes"):
        nms(np.array([[10, 0, 0, 10.0]]), [1.0], 0.5)


def test_letterbox_inverse_is_exact():
    img = np.zeros((720, 1280, 3), np.uint8)
    out, info = letterbox(img, (640, 640))
    assert out.shape == (640, 640, 3)
    assert info.pad == (0, 140) and info.scale == (0.5, 0.5)
    assert (out[:140] == 114).all() and (out[140:500] == 0).all()
    boxes = np.array([[100.5, 200.25, 300.0, 400.0], [0, 0, 1280, 720]])
    np.testing.assert_allclose(info.to_original(info.to_letterbox(boxes)), boxes, atol=1e-12)


@pytest.mark.parametrize(
    ("size", "shape", "bgr"),
    [((640, 368), (360, 640), True), ((320, 320), (333, 517), False), ((64, 48), (300, 100), True)],
)
def test_preprocess_is_letterbox_flip_and_divide(size, shape, bgr):
    # The one-pass batch equals, bit for bit, letterbox -> BGR to RGB -> float32 / 255.
    rng = np.random.default_rng(7)
    ims = [rng.integers(0, 256, (*shape, 3), dtype=np.uint8) for _ in range(2)]
    batch, infos = GridDetector(input_size=size, bgr=bgr).preprocess(ims)
    boxed = [letterbox(im, size) for im in ims]
    ref = np.stack([b[..., ::-1] if bgr else b for b, _ in boxed]).transpose(0, 3, 1, 2)
    assert batch.flags.c_contiguous and batch.dtype == np.float32
    np.testing.assert_array_equal(batch, ref.astype(np.float32) / np.float32(255.0))
    assert infos == [info for _, info in boxed]


# Original-image boxes the network "detects" in two frames of different sizes.
SIZES = [(1280, 720), (600, 800)]
TRUTH = [
    (np.array([[100.0, 400.0, 180.0, 470.0], [900.0, 500.0, 1000.0, 560.0]]), [0.9, 0.8], [0, 2]),
    (np.array([[50.0, 600.0, 120.0, 700.0]]), [0.7], [1]),
]


def encode(layout, nc=3):
    """Known predictions in letterboxed pixels, with a lower-scored duplicate of every box."""
    rows_all = []
    for (w, h), (boxes, scores, cls) in zip(SIZES, TRUTH, strict=True):
        _, info = letterbox(np.zeros((h, w, 3), np.uint8), (640, 640))
        lb = info.to_letterbox(boxes)
        rows = []
        for b, s, c in zip(lb, scores, cls, strict=True):
            for shift, factor in ((0.0, 1.0), (3.0, 0.6)):
                bb = b + shift
                cx, cy, bw, bh = (
                    (bb[0] + bb[2]) / 2,
                    (bb[1] + bb[3]) / 2,
                    bb[2] - bb[0],
                    bb[3] - bb[1],
                )
                sc = np.zeros(nc)
                sc[c] = s * factor
                obj = [1.0] if layout == "v5" else []
                rows.append([cx, cy, bw, bh, *obj, *sc])
        rows_all.append(rows)
    k = max(len(r) for r in rows_all)
    ch = len(rows_all[0][0])
    arr = np.zeros((len(rows_all), k, ch))
    for i, r in enumerate(rows_all):
        arr[i, : len(r)] = r
    return torch.tensor(arr)


def frames():
    return [
        np.random.default_rng(i).integers(0, 255, (h, w, 3), dtype=np.uint8)
        for i, (w, h) in enumerate(SIZES)
    ]


@pytest.mark.parametrize("layout", ["v8", "v5"])
@pytest.mark.parametrize("kind", ["module", "torchscript"])
def test_detector_end_to_end(layout, kind, tmp_path):
    net = KnownBoxesYolo(encode(layout), layout=layout)
    model = net
    if kind == "torchscript":
        path = tmp_path / "net.pt"
        with warnings.catch_warnings():  # torch >= 2.10 deprecates TorchScript creation
            warnings.simplefilter("ignore", FutureWarning)
            torch.jit.trace(net, torch.zeros(2, 3, 640, 640)).save(str(path))
        model = path
    det = YoloDetector(model, conf_threshold=0.3, iou_threshold=0.5, device="cpu")
    out = det(frames())
    assert len(out) == 2
    for d, (boxes, scores, cls) in zip(out, TRUTH, strict=True):
        np.testing.assert_allclose(d.boxes, boxes, atol=1e-4)  # float32 network output
        np.testing.assert_allclose(d.scores, scores, rtol=1e-6)
        np.testing.assert_array_equal(d.classes, cls)
    # Class filter and a threshold above the duplicates' scores.
    only2 = YoloDetector(net, conf_threshold=0.3, classes=[2])(frames())
    assert only2[0].classes.tolist() == [2] and len(only2[1].boxes) == 0


def test_decode_rejects_bad_layout():
    with pytest.raises(ValueError, match="layout"):
        decode(np.zeros((1, 10, 8)), layout="v9000")
    with pytest.raises(ValueError, match="output"):
        decode(np.zeros((10, 8)))


def test_pipeline_filters_and_any_callable():
    cam = FovCamera((1280, 720), (90.0, 50.0))
    boxes = np.array(
        [
            [600, 500, 680, 560],  # ok
            [600, 300, 680, 340],  # above the horizon line v = 360
            [100, 650, 200, 700],  # inside the own-vessel polygon
            [900, 500, 960, 540],  # low confidence
            [640, 365, 650, 370],  # below the line but beyond max range
        ],
        dtype=float,
    )
    scores = np.array([0.9, 0.9, 0.9, 0.2, 0.9])

    def detector(images):
        return [(boxes, scores) for _ in images]

    pipe = CameraPipeline(
        detector,
        cam,
        height=2.0,
        min_confidence=0.35,
        own_vessel_polygon=np.array([[0, 600], [300, 600], [300, 720], [0, 720]]),
        horizon_line=(0.0, 360.0),
        georef_options={"max_range": 50.0, "pixel_sigma": 1.0},
    )
    (res,) = pipe([np.zeros((720, 1280, 3), np.uint8)])
    assert [REASONS[r] for r in res.reason] == [
        "ok",
        "above_horizon",
        "own_vessel",
        "low_confidence",
        "beyond_max_range",
    ]
    assert np.isfinite(res.positions[0]).all() and np.isnan(res.positions[1:]).all()
    assert isinstance(res.detections, Detections)


def test_nms_accepts_empty_input():
    for boxes in ([], np.zeros((0, 4))):
        keep = nms(boxes, [])
        assert keep.shape == (0,) and keep.dtype == np.int64
    assert nms([], [], classes=[]).shape == (0,)
