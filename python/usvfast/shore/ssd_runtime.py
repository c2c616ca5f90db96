"""Run an exported SSD (:func:`usvfast.shore.pretrained.export_onnx`: input "images" (1, 3, H, W)
RGB in [−1, 1], output (1, A, 4 + C)) on one of the inference back-ends, all fed the same
letterboxed BGR uint8 image so that each does its own input conversion the fastest way:

* ``"opencv"``: OpenCV DNN (the core dependency); the image becomes the network's blob with
  :func:`cv2.dnn.blobFromImage` ((x − 127.5) · 2/255, BGR → RGB, HWC → CHW in one pass).
* ``"openvino"``: OpenVINO's CPU plugin (`pip install usvfast[openvino]`, Apache 2.0), with the
  conversion compiled into the network (its PrePostProcessor: u8 NHWC BGR in, (x − 127.5) /
  127.5 RGB NCHW to the first layer). `precision` is its inference precision: ``"f32"`` (the
  exported arithmetic) or ``"bf16"`` (bfloat16 where the CPU has it, e.g. AVX512-BF16 or
  AMX; OpenVINO's own default on such CPUs, with score changes of up to ~0.2 on single
  anchors — see the README's speed table). An int8 model written by
  :mod:`usvfast.shore.ssd_quant` (quantize/dequantize pairs in the ONNX file) runs its
  convolutions in int8 (VNNI) whatever `precision` says for the rest.

The ONNX file's input is the network's at the size it was exported with; nothing here
resizes."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from usvfast._openvino import BACKENDS, core, infer_request, openvino, resolve_backend
from usvfast._validate import integer

__all__ = ["BACKENDS", "HALF_RANGE", "MEAN", "PRECISIONS", "SsdRuntime", "resolve_backend"]

#: OpenVINO inference precisions (OpenCV DNN runs float32 only).
PRECISIONS: tuple[str, ...] = ("f32", "bf16")
#: The network's input conversion: x_net = (x_u8 − MEAN) / HALF_RANGE (= x · 2/255 − 1).
MEAN = 127.5
HALF_RANGE = 127.5


class SsdRuntime:
    """The exported SSD at `path` (.onnx) on `backend` (:data:`BACKENDS`) with OpenVINO's
    `precision` (:data:`PRECISIONS`; "f32" only on OpenCV DNN). `threads`: the back-end's
    thread count (None: OpenCV's current setting; OpenVINO: every core; OpenCV's is
    process-wide, so setting it here sets it for every OpenCV call). Call it with a
    letterboxed BGR uint8 image (H, W, 3) at the network's input size -> (A, 4 + C) float32:
    normalised corners (x1, y1, x2, y2) and sigmoid scores per anchor. Raises ValueError for
    an unknown back-end or precision, MissingExtraError when OpenVINO is not installed."""

    def __init__(
        self,
        path: Path | str,
        backend: str = "opencv",
        precision: str = "f32",
        threads: int | None = None,
    ) -> None:
        if backend not in BACKENDS:
            raise ValueError(f"backend: expected one of {BACKENDS}, got {backend!r}")
        if precision not in PRECISIONS:
            raise ValueError(f"precision: expected one of {PRECISIONS}, got {precision!r}")
        if backend == "opencv" and precision != "f32":
            raise ValueError(f"precision: OpenCV DNN runs 'f32' only, got {precision!r}")
        if threads is not None:
            threads = integer("threads", threads, low=1)
        self.path = Path(path)
        self.backend, self.precision = backend, precision
        if backend == "opencv":
            if threads is not None:
                cv2.setNumThreads(int(threads))
            self._net = cv2.dnn.readNetFromONNX(str(self.path))
            self._request = None
        else:
            self._net = None
            self._request = _openvino_request(self.path, precision, threads)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        if self._request is None:
            size = (image.shape[1], image.shape[0])
            blob = cv2.dnn.blobFromImage(image, 1.0 / HALF_RANGE, size, (MEAN,) * 3, swapRB=True)
            self._net.setInput(blob)  # pyright: ignore[reportOptionalMemberAccess]
            return np.asarray(self._net.forward())[0]  # pyright: ignore[reportOptionalMemberAccess]
        self._request.infer({0: image[None]})
        return self._request.get_output_tensor(0).data[0].copy()


def _openvino_request(path: Path, precision: str, threads: int | None):
    """An OpenVINO infer request of the ONNX model at `path` taking (1, H, W, 3) u8 BGR, with
    the input conversion compiled in, at inference `precision`, latency-tuned."""
    ov = openvino("the OpenVINO SSD back-end")
    from openvino.preprocess import ColorFormat, PrePostProcessor

    model = core("the OpenVINO SSD back-end").read_model(str(path))
    ppp = PrePostProcessor(model)
    tensor = ppp.input().tensor()
    tensor.set_element_type(ov.Type.u8).set_layout(ov.Layout("NHWC"))
    tensor.set_color_format(ColorFormat.BGR)
    ppp.input().model().set_layout(ov.Layout("NCHW"))
    steps = ppp.input().preprocess()
    steps.convert_element_type(ov.Type.f32).convert_color(ColorFormat.RGB)
    steps.mean(MEAN).scale(HALF_RANGE)
    return infer_request(ppp.build(), precision, threads)
