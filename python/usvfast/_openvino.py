"""OpenVINO inference of exported ONNX networks (`pip install usvfast[openvino]`, Apache 2.0),
shared by the camera detectors (:class:`usvfast.camera.dnn.OnnxDetector`) and the shore SSD
(:class:`usvfast.shore.ssd_runtime.SsdRuntime`). OpenVINO's CPU plugin runs the same float32
arithmetic as OpenCV DNN (outputs within ~1e-4) 1.6x faster on this project's networks."""

from __future__ import annotations

import importlib.util
from typing import Any

from usvfast._extras import require

#: Inference back-ends of the ONNX detectors; "auto" resolves by :func:`resolve_backend`.
BACKENDS: tuple[str, ...] = ("opencv", "openvino")

_CORE = None


def resolve_backend(backend: str) -> str:
    """`backend`, with "auto" resolved: "openvino" when the package imports, else "opencv"."""
    if backend != "auto":
        return backend
    return "openvino" if importlib.util.find_spec("openvino") is not None else "opencv"


def openvino(purpose: str) -> Any:
    """The `openvino` module, or MissingExtraError naming the extra that `purpose` needs."""
    return require("openvino", "openvino", purpose)


def core(purpose: str = "OpenVINO inference") -> Any:
    """The process's one `openvino.Core` (made on first use); MissingExtraError naming the
    extra that `purpose` needs when OpenVINO does not import."""
    global _CORE
    ov = openvino(purpose)
    if _CORE is None:
        _CORE = ov.Core()
    return _CORE


def infer_request(model: Any, precision: str, threads: int | None) -> Any:
    """An infer request of the OpenVINO `model` compiled for the CPU, latency-tuned, at
    inference `precision` ("f32" or "bf16"; always set: OpenVINO's own default on CPUs with
    bfloat16 is bf16, which moves scores), on `threads` threads (None: every core)."""
    config: dict[str, object] = {
        "PERFORMANCE_HINT": "LATENCY",
        "INFERENCE_PRECISION_HINT": precision,
    }
    if threads is not None:
        config["INFERENCE_NUM_THREADS"] = int(threads)
    return core().compile_model(model, "CPU", config).create_infer_request()
