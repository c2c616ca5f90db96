"""YOLO-layout detection from an ONNX file through OpenCV's DNN module (no torch), or through
OpenVINO's CPU plugin when the `openvino` extra is installed (the same float32 arithmetic,
outputs within ~1e-4, about 1.6x faster).

The letterbox, decoding and Rust NMS are those of :mod:`usvfast.camera.detect`, shared with the
torch backend (:class:`usvfast.camera.yolo.YoloDetector`): the same network exported to
TorchScript and to ONNX gives the same boxes through either.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from usvfast._openvino import BACKENDS, core, infer_request, resolve_backend
from usvfast.camera.detect import GridDetector

#: `OnnxDetector(runtime=...)` values: an inference back-end, or "auto" (OpenVINO when it
#: imports, else OpenCV DNN).
RUNTIMES: tuple[str, ...] = ("auto", *BACKENDS)


class OnnxDetector(GridDetector):
    """An ONNX detector network run by `cv2.dnn`, as a callable: list of images (H, W, 3 uint8,
    BGR as OpenCV reads them) -> list of :class:`usvfast.camera.detect.Detections` in original
    pixels.

    `weights`: path of an `.onnx` file whose input is (1 or N, 3, h, w) RGB float32 in [0, 1]
    and whose output is a YOLO v5 `[N, A, 5 + nc]` or v8 `[N, 4 + nc, A]` array in letterboxed
    pixels. `input_size` (width, height) = (w, h) of that input; None takes it from the file
    (640 x 640 when the file leaves it dynamic). The other keywords are those of
    :class:`usvfast.camera.detect.GridDetector`. Frames run one at a time (networks exported
    with a fixed batch of 1 are the common case). `runtime` (:data:`RUNTIMES`) runs the
    network on OpenCV DNN or, in float32, on OpenVINO; the resolved name is `self.runtime`.

    Raises FileNotFoundError for a missing file, ValueError for a file OpenCV cannot read or a
    network whose declared input differs from `input_size` or that rejects it (checked once,
    at construction: OpenCV may otherwise clamp mismatched shapes silently), or an unknown
    `runtime`; MissingExtraError for runtime="openvino" without OpenVINO.
    """

    def __init__(
        self,
        weights: str | Path,
        *,
        input_size: tuple[int, int] | None = None,
        layout: str = "auto",
        conf_threshold: float = 0.25,
        iou_threshold: float = 0.45,
        classes: Sequence[int] | None = None,
        agnostic: bool = False,
        max_det: int = 300,
        bgr: bool = True,
        runtime: str = "auto",
    ) -> None:
        if runtime not in RUNTIMES:
            raise ValueError(f"runtime: expected one of {RUNTIMES}, got {runtime!r}")
        path = Path(weights)
        if not path.is_file():
            raise FileNotFoundError(f"weights: no such ONNX file: {path}")
        try:
            net = cv2.dnn.readNetFromONNX(str(path))
        except cv2.error as e:
            raise ValueError(f"weights: OpenCV cannot read {path} as ONNX: {_first(e)}") from e
        declared = declared_input_shape(net)
        # (width, height) the network declares, None for a dynamic or unreported input size
        fixed_wh: tuple[int, int] | None = None
        if declared is not None and declared[2] is not None and declared[3] is not None:
            fixed_wh = (declared[3], declared[2])
        if input_size is None:
            input_size = fixed_wh or (640, 640)
        super().__init__(
            input_size=input_size,
            layout=layout,
            conf_threshold=conf_threshold,
            iou_threshold=iou_threshold,
            classes=classes,
            agnostic=agnostic,
            max_det=max_det,
            bgr=bgr,
        )
        self.weights = path
        self.net = net
        w, h = self.input_size
        if fixed_wh is not None and fixed_wh != (w, h):
            raise ValueError(
                f"input_size: {path.name} takes (width, height) = {fixed_wh}, got {self.input_size}"
            )
        if declared is not None and declared[1] not in (None, 3):
            raise ValueError(f"weights: {path.name} takes {declared[1]} channels, expected 3")
        self.runtime = resolve_backend(runtime)
        self._request = None
        self.forward(np.zeros((1, 3, h, w), np.float32))  # fail now, naming input_size
        if self.runtime == "openvino":  # OpenCV has checked the network and its input size
            model = core("the OpenVINO detector runtime").read_model(str(path))
            model.reshape([1, 3, h, w])
            self._request = infer_request(model, "f32", None)

    def forward(self, batch: np.ndarray) -> np.ndarray:
        """Run the network on a preprocessed (N, 3, h, w) float32 batch, one frame at a time;
        raw output (N, ...) float32. Raises ValueError naming `input_size` when OpenCV rejects
        the input shape."""
        outs = []
        for x in batch:
            if self._request is not None:
                self._request.infer({0: np.ascontiguousarray(x[None])})
                outs.append(self._request.get_output_tensor(0).data.copy())
                continue
            self.net.setInput(np.ascontiguousarray(x[None]))
            try:
                y = self.net.forward()
            except cv2.error as e:
                raise ValueError(
                    f"input_size: the network {self.weights.name} rejected an input of shape "
                    f"{(1, *x.shape)} (input_size={self.input_size}): {_first(e)}"
                ) from e
            if y.ndim != 3 or y.shape[0] != 1:
                raise ValueError(
                    f"weights: {self.weights.name} gives an output of shape {y.shape}, expected "
                    "a YOLO (1, A, 5 + nc) or (1, 4 + nc, A) array"
                )
            outs.append(y)
        return np.concatenate(outs).astype(np.float32, copy=False)


def declared_input_shape(net: cv2.dnn.Net) -> tuple[int | None, ...] | None:
    """The (N, C, H, W) input shape an ONNX network declares (None for a dynamic axis), read
    from OpenCV's graph dump; None when this OpenCV does not report it."""
    try:
        text = net.dump()
    except (cv2.error, AttributeError):
        return None
    m = re.search(r"<Input>\s+\S+\s+\[([^\]]*)\]", text)
    if m is None:
        return None
    dims = [d.strip() for d in m.group(1).split(" x ")]
    if len(dims) != 4:
        return None
    return tuple(int(d) if d.isdigit() else None for d in dims)


def _first(e: cv2.error) -> str:
    """The informative line of an OpenCV error message."""
    lines = [ln.strip() for ln in str(e).splitlines() if ln.strip()]
    return lines[-1] if lines else repr(e)
