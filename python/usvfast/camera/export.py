"""Export a torch detector network for the two backends: TorchScript (`.pt`, for
:class:`usvfast.camera.yolo.YoloDetector`) and ONNX (`.onnx`, for
:class:`usvfast.camera.dnn.OnnxDetector`, no torch needed to run it).

Both are traced at a fixed input (1, 3, height, width) RGB float32 in [0, 1]. Needs torch and the
`onnx` package (`pip install usvfast[yolo]`).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any


def _example(input_size: tuple[int, int]) -> Any:
    import torch

    w, h = (int(v) for v in input_size)
    return torch.zeros(1, 3, h, w)


def export_torchscript(module: Any, path: str | Path, input_size: tuple[int, int]) -> Path:
    """Trace `module` (eval mode) at `input_size` (width, height) px and save TorchScript."""
    import torch

    module = module.eval()
    with warnings.catch_warnings():  # torch >= 2.10 deprecates TorchScript creation
        warnings.simplefilter("ignore", FutureWarning)
        traced = torch.jit.trace(module, _example(input_size))
        traced.save(str(path))  # pyright: ignore[reportAttributeAccessIssue]
    return Path(path)


def export_onnx(
    module: Any, path: str | Path, input_size: tuple[int, int], opset: int = 17
) -> Path:
    """Export `module` (eval mode) at `input_size` (width, height) px to ONNX (`opset`), input
    named "images", output "output", batch of 1 fixed."""
    import torch

    module = module.eval()
    with warnings.catch_warnings():  # the TorchScript-based exporter is deprecated upstream
        warnings.simplefilter("ignore", DeprecationWarning)
        warnings.simplefilter("ignore", FutureWarning)
        torch.onnx.export(
            module,
            (_example(input_size),),
            str(path),
            dynamo=False,
            opset_version=opset,
            input_names=["images"],
            output_names=["output"],
        )
    return Path(path)
