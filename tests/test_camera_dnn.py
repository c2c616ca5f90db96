"""The OpenCV DNN backend (ONNX, no torch) against the torch backend on the same network: the raw
network outputs agree to float32 rounding, and the shared decoding, NMS and letterbox inverse
give the same boxes; the camera chain takes either backend; bad weights and shapes are clear
errors."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from test_camera_yolo import SIZES, TRUTH, encode, frames
from yolo_nets import KnownBoxesYolo

from usvfast.camera import FovCamera
from usvfast.camera.backends import load_detector, resolve_weights
from usvfast.camera.chain import CameraPipeline
from usvfast.camera.dnn import OnnxDetector, declared_input_shape
from usvfast.camera.export import export_onnx, export_torchscript
from usvfast.camera.yolo import YoloDetector


@pytest.fixture(scope="module", params=["v8", "v5"])
def exported(request, tmp_path_factory):
    """One KnownBoxesYolo network (layout v8 or v5) as TorchScript and as ONNX."""
    layout = request.param
    d = tmp_path_factory.mktemp(f"net-{layout}")
    net = KnownBoxesYolo(encode(layout)[:1], layout=layout, seed=3)
    return (
        layout,
        export_torchscript(net, d / "net.pt", (640, 640)),
        export_onnx(net, d / "net.onnx", (640, 640)),
    )


def test_raw_outputs_agree(exported):
    _, pt, onnx = exported
    ims = frames()
    raw_t, lb_t = YoloDetector(pt).raw(ims[:1])
    raw_o, lb_o = OnnxDetector(onnx).raw(ims[:1])
    assert raw_o.shape == raw_t.shape and raw_o.dtype == np.float32
    assert lb_o == lb_t
    # Every anchor of the real conv backbone (8400 of them), not just the known boxes.
    np.testing.assert_allclose(raw_o, raw_t, rtol=1e-5, atol=1e-4)


def test_same_boxes_both_backends(exported):
    layout, pt, onnx = exported
    ims = frames()[:1]
    kw = {"conf_threshold": 0.3, "iou_threshold": 0.5, "layout": layout}
    (dt,) = YoloDetector(pt, **kw)(ims)
    (do,) = OnnxDetector(onnx, **kw)(ims)
    boxes, scores, cls = TRUTH[0]
    for d in (dt, do):
        np.testing.assert_allclose(d.boxes, boxes, atol=1e-4)
        np.testing.assert_allclose(d.scores, scores, rtol=1e-6)
        np.testing.assert_array_equal(d.classes, cls)
    np.testing.assert_allclose(do.boxes, dt.boxes, atol=1e-4)
    np.testing.assert_allclose(do.scores, dt.scores, atol=1e-6)
    # A batch runs frame by frame through OpenCV and gives one result per frame.
    many = OnnxDetector(onnx, **kw)([ims[0], ims[0][:, ::-1].copy()])
    assert len(many) == 2 and np.allclose(many[0].boxes, do.boxes)


def test_input_size_from_the_file_and_mismatch(exported):
    _, _, onnx = exported
    det = OnnxDetector(onnx)
    assert det.input_size == (640, 640)
    assert declared_input_shape(det.net) == (1, 3, 640, 640)
    with pytest.raises(ValueError, match=r"input_size: net.onnx takes .*\(640, 640\)"):
        OnnxDetector(onnx, input_size=(320, 320))


def test_camera_chain_takes_either_backend(exported):
    _, pt, onnx = exported
    w, h = SIZES[0]
    cam = FovCamera((w, h), (90.0, 50.0))
    results = []
    for det in (YoloDetector(pt, conf_threshold=0.3), OnnxDetector(onnx, conf_threshold=0.3)):
        pipe = CameraPipeline(det, cam, height=2.0, georef_options={"max_range": 500.0})
        (res,) = pipe(frames()[:1])
        results.append(res)
    assert results[0].valid.any()
    np.testing.assert_array_equal(results[0].reason, results[1].reason)
    np.testing.assert_allclose(results[0].positions, results[1].positions, rtol=1e-6)


def test_bad_weights_and_images(tmp_path, exported):
    onnx = exported[2]
    with pytest.raises(FileNotFoundError, match="weights: no such ONNX file"):
        OnnxDetector(tmp_path / "missing.onnx")
    with pytest.raises(FileNotFoundError, match="model: no such weights file"):
        YoloDetector(tmp_path / "missing.pt")
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not a protobuf" * 8)
    with pytest.raises(ValueError, match="weights: OpenCV cannot read"):
        OnnxDetector(bad)
    det = OnnxDetector(onnx)
    with pytest.raises(ValueError, match=r"images: expected \(H, W, 3\)"):
        det([np.zeros((100, 100), np.uint8)])
    with pytest.raises(TypeError, match="images: expected uint8"):
        det([np.zeros((100, 100, 3), np.float32)])
    # A network that only takes 64 x 64 inputs (a dense layer after the convolution).
    fixed = torch.nn.Sequential(
        torch.nn.Conv2d(3, 2, 3), torch.nn.Flatten(), torch.nn.Linear(7688, 6)
    )
    with pytest.raises(
        ValueError, match=r"input_size: the network rejected .*input_size=\(32, 32\)"
    ):
        YoloDetector(fixed, input_size=(32, 32))(frames()[:1])
    with pytest.raises(ValueError, match="conf_threshold"):
        OnnxDetector(onnx, conf_threshold=1.5)


def test_load_detector_by_name(tmp_path, exported):
    _, pt, onnx = exported
    det = load_detector("onnx", onnx.name, base=onnx.parent, conf_threshold=0.3)
    assert isinstance(det, OnnxDetector) and det.conf_threshold == 0.3
    assert isinstance(load_detector("torch", pt), YoloDetector)
    with pytest.raises(ValueError, match="backend"):
        load_detector("tensorrt", onnx)
    with pytest.raises(FileNotFoundError, match=r"weights: no such file 'nope\.onnx'"):
        resolve_weights("nope.onnx", base=tmp_path)
