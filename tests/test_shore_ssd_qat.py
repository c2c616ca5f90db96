"""Quantisation-aware int8 fine-tuning of the shore SSD (usvfast.shore.ssd_qat)."""

from __future__ import annotations

import json
from dataclasses import replace

import cv2
import numpy as np
import pytest
import torch

from usvfast.shore.pretrained import coco_network, export_onnx, letterboxed, preprocess
from usvfast.shore.ssd import SsdExport
from usvfast.shore.ssd_qat import QAT_CONFIG, float_network, quantization_aware_fine_tune
from usvfast.shore.ssd_runtime import SsdRuntime

from conftest import shared_data

SIZE = (320, 240)


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """The COCO SSD exported at 320 × 240 with a card naming video 3 (5 frames) as its
    training video."""
    folder = tmp_path_factory.mktemp("qat")
    path = export_onnx(coco_network(), folder / "ssd.onnx", SIZE)
    card = {"input_size": list(SIZE), "letterbox": True, "conf_threshold": 0.3, "videos": ["3"]}
    path.with_suffix(".json").write_text(json.dumps(card))
    return path


@pytest.fixture(scope="module")
def frames():
    folder = shared_data("mardct") / "training" / "annotations"
    return folder, [cv2.imread(str(p)) for p in sorted(folder.glob("3_*.png"))]


def test_float_network_is_the_export(model, frames):
    net = float_network(model, SIZE)
    x = torch.from_numpy(preprocess(frames[1][0], SIZE, True)[0])
    with torch.no_grad():
        ours = SsdExport(net, SIZE[1], SIZE[0])(x).numpy()[0]
    theirs = SsdRuntime(model, "opencv")(letterboxed(frames[1][0], SIZE, True)[0])
    assert ours.shape == theirs.shape
    np.testing.assert_allclose(ours, theirs, atol=2e-4)


# NNCF's torch extension loader leaves its one-thread pool open (nncf/torch/extensions)
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_qat_writes_an_int8_model_openvino_runs(model, frames, tmp_path):
    folder, images = frames
    cfg = replace(QAT_CONFIG, steps=3, views=16, warmup=1)
    out = quantization_aware_fine_tune(model, folder, cfg, tmp_path / "ssd-int8.onnx", log=print)
    card = json.loads(out.with_suffix(".json").read_text())
    assert card["int8"]["calibration_videos"] == ["3"] and card["int8"]["frames"] == 5
    assert card["int8"]["train"]["steps"] == 3
    image = letterboxed(images[0], SIZE, True)[0]
    q = SsdRuntime(out, "openvino")(image)
    f = SsdRuntime(model, "openvino")(image)
    assert q.shape == f.shape and np.isfinite(q).all()
    # int8 moves scores, not the picture: the best anchor's box stays where float32 puts it
    best = int(np.argmax(f[:, 4]))
    assert abs(q[best, 4] - f[best, 4]) < 0.25
    np.testing.assert_allclose(q[best, :4], f[best, :4], atol=0.05)


def test_errors_name_the_model(model, frames, tmp_path):
    folder, _ = frames
    with pytest.raises(ValueError, match=r"model: expected an .onnx file with its card"):
        quantization_aware_fine_tune(tmp_path / "none.onnx", folder)
    other = tmp_path / "other.onnx"
    export_onnx(coco_network(), other, (160, 128))  # another input size: other anchors
    with pytest.raises(ValueError, match=r"model: .* is not an SSD export of this network"):
        float_network(other, SIZE)
