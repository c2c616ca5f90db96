"""The bundled harbour demo detector per frame at the demo frame size (640 x 360, rendered by the
simulator), through both backends in one process: ONNX through OpenCV DNN (the default install,
no torch) and TorchScript through torch, end to end (letterbox + network + decode + NMS) and the
network alone; both on the same frames, with the ratio. Thread counts: torch 2, OpenCV 2.

Run: python benches/bench_detector.py [--repeat N]
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np

from usvfast.camera.backends import demo_weights, load_detector

from timing import best_of


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=20)
    a = ap.parse_args()
    from usvfast.sim import render_frame

    frame, _ = render_frame(2100, 12.0)
    cv2.setNumThreads(2)
    onnx = load_detector("onnx", demo_weights("onnx"))
    rows = []
    try:
        import torch

        torch.set_num_threads(2)
        torch_det = load_detector("torch", demo_weights("torch"))
        backends = [("OpenCV DNN (ONNX)", onnx), ("torch (TorchScript)", torch_det)]
    except ImportError:
        print("torch not installed: OpenCV DNN only")
        backends = [("OpenCV DNN (ONNX)", onnx)]
    for name, det in backends:
        batch, _ = det.preprocess([frame])
        for _ in range(10):  # warm-up (TorchScript profiles and optimises its first calls)
            det([frame])
        t, out = best_of(lambda d=det: d([frame]), a.repeat)
        t_net, _ = best_of(lambda d=det, b=batch: d.forward(b), a.repeat)
        rows.append((name, t, t_net, len(out[0].boxes)))
    print(f"harbour-demo, frame {frame.shape[1]}x{frame.shape[0]}, best of {a.repeat}:")
    for name, t, t_net, n in rows:
        print(
            f"  {name:22s} {t * 1e3:7.1f} ms/frame end to end, network {t_net * 1e3:7.1f} ms"
            f"  ({n} boxes)"
        )
    if len(rows) == 2:
        print(f"  torch / OpenCV end-to-end ratio: {rows[1][1] / rows[0][1]:.2f}")
    same = np.allclose(
        backends[0][1]([frame])[0].boxes, backends[-1][1]([frame])[0].boxes, atol=1e-2
    )
    print(f"  same boxes: {same}")


if __name__ == "__main__":
    main()
