"""YOLO detection through torch: a TorchScript / `torch.export` file, an `nn.Module` or an
Ultralytics model behind the shared letterbox, decoding and Rust NMS of
:mod:`usvfast.camera.detect`.

torch is an optional dependency (`pip install usvfast[yolo]`); it is imported only when a torch
model is used. The same network exported to ONNX runs without torch through
:class:`usvfast.camera.dnn.OnnxDetector`, with the same boxes.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from usvfast.camera.chain import CameraDetections, CameraPipeline
from usvfast.camera.detect import Detections, GridDetector, Letterbox, decode, letterbox

__all__ = [
    "CameraDetections",
    "CameraPipeline",
    "Detections",
    "Letterbox",
    "YoloDetector",
    "decode",
    "letterbox",
]


class YoloDetector(GridDetector):
    """A YOLO model run by torch, as a callable: list of images (H, W, 3 uint8, BGR as OpenCV
    reads them) -> list of :class:`Detections` in original pixels.

    `model`: a TorchScript file path (or a `torch.export` `.pt2` file), a `torch.nn.Module`,
    or an Ultralytics `YOLO` object (its own pre/post-processing is used, with our thresholds).
    `input_size` (width, height) of the network; `layout` "auto" | "v5" | "v8";
    `conf_threshold`, `iou_threshold`, `classes` (keep only these ids), `agnostic`
    (class-agnostic NMS), `max_det` per image (see :class:`usvfast.camera.detect.GridDetector`);
    `device` "cpu", "cuda", "cuda:0", ...; `half` runs the network in float16 (CUDA only).
    Raises FileNotFoundError for a missing weights file, TypeError for another kind of model.
    """

    def __init__(
        self,
        model: Any,
        *,
        input_size: tuple[int, int] = (640, 640),
        layout: str = "auto",
        conf_threshold: float = 0.25,
        iou_threshold: float = 0.45,
        classes: Sequence[int] | None = None,
        agnostic: bool = False,
        max_det: int = 300,
        device: str = "cpu",
        half: bool = False,
        bgr: bool = True,
    ) -> None:
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
        import torch

        self._torch = torch
        self.device = torch.device(device)
        self.half = half
        self._ultralytics = type(model).__module__.startswith("ultralytics")
        if isinstance(model, str | Path):
            if not Path(model).is_file():
                raise FileNotFoundError(f"model: no such weights file: {model}")
            if str(model).endswith(".pt2"):
                model = torch.export.load(str(model)).module()
            else:
                # TorchScript is deprecated upstream (FutureWarning) but is what most exported
                # YOLO weights are; load it quietly.
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", FutureWarning)
                    model = torch.jit.load(str(model), map_location=self.device)
        elif not self._ultralytics and not isinstance(model, torch.nn.Module):
            raise TypeError(
                "model: expected a TorchScript path, a torch.nn.Module or an Ultralytics model, "
                f"got {type(model).__name__}"
            )
        if not self._ultralytics and isinstance(model, torch.nn.Module):
            model = model.to(self.device)
            if hasattr(model, "eval"):
                model = model.eval()
            if half:
                model = model.half()
        self.model = model

    def _ultralytics_call(self, images: list[np.ndarray]) -> list[Detections]:
        results = self.model(
            images if self.bgr else [im[..., ::-1] for im in images],
            imgsz=max(self.input_size),
            conf=self.conf_threshold,
            iou=self.iou_threshold,
            classes=self.classes,
            agnostic_nms=self.agnostic,
            max_det=self.max_det,
            device=str(self.device),
            verbose=False,
        )
        out = []
        for r in results:
            b = r.boxes
            out.append(
                Detections(
                    b.xyxy.cpu().numpy().astype(np.float64),
                    b.conf.cpu().numpy().astype(np.float64),
                    b.cls.cpu().numpy().astype(np.int64),
                )
            )
        return out

    def forward(self, batch: np.ndarray) -> np.ndarray:
        """Run the network on a preprocessed (N, 3, h, w) float32 batch; raw output (float32).

        Raises ValueError naming `input_size` when the network rejects the input shape."""
        torch = self._torch
        x = torch.from_numpy(batch).to(self.device)
        if self.half:
            x = x.half()
        try:
            with torch.inference_mode():
                y = self.model(x)
        except RuntimeError as e:
            raise ValueError(
                f"input_size: the network rejected an input of shape {tuple(batch.shape)} "
                f"(input_size={self.input_size}): {str(e).splitlines()[0]}"
            ) from e
        if isinstance(y, list | tuple):
            y = y[0]
        return y.float().cpu().numpy()

    def __call__(self, images: np.ndarray | Sequence[np.ndarray]) -> list[Detections]:
        """Detect on one image (H, W, 3) or a list of images; one :class:`Detections` each."""
        if self._ultralytics:
            if isinstance(images, np.ndarray) and images.ndim == 3:
                images = [images]
            images = list(images)
            return self._ultralytics_call(images) if images else []
        return super().__call__(images)
