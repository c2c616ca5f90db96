"""Held-out figures of quantisation-aware int8 (`usvfast.shore.ssd_qat`) for the four
leave-one-video-out SSD fold models, against float32 on OpenVINO.

Decided before any QAT figure was run (and not changed after):
- each fold model (`shore-ssd-without-V.onnx` with its card, from `python -m
  usvfast.shore.ssd_train ... --exclude V`) is copied into --work and fine-tuned with
  quantisation by `quantization_aware_fine_tune` with the shipped `QAT_CONFIG` (120 steps,
  seed 0), calibrated and trained on its card's training videos only; the result is written
  as `shore-ssd-without-V-int8.onnx` beside it, where the evaluation's `openvino-int8`
  run-time takes it;
- scored by `python -m usvfast.shore.evaluate_det --detectors ssd --ssd-runtime R` for
  R = openvino (float32) and openvino-int8 (the QAT models): held-out TPR / FAR at the
  card's threshold, horizon filter on, per video;
- the rule that kept bfloat16 and post-training int8 as options: quantisation-aware int8
  becomes `usvfast shore`'s default run-time only if every held-out TPR and FAR is within
  0.01 of float32's on all four videos; otherwise it is an option and the figures are
  reported as measured.

    python benches/shore_qat_heldout.py --models DIR --work DIR [--data ANNOTATIONS]
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from usvfast.shore.evaluate import default_data
from usvfast.shore.evaluate_det import evaluate
from usvfast.shore.ssd_qat import QAT_CONFIG, quantization_aware_fine_tune

VIDEOS = ("video3", "regDTV9", "2", "3")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", type=Path, required=True, help="Folder of the fold models")
    ap.add_argument("--work", type=Path, required=True, help="Where the QAT models go")
    ap.add_argument("--data", type=Path, default=None, help="MarDCT training/annotations")
    a = ap.parse_args()
    data = a.data or default_data()
    a.work.mkdir(parents=True, exist_ok=True)
    for v in VIDEOS:
        name = f"shore-ssd-without-{v}"
        for suffix in (".onnx", ".json"):
            shutil.copy2(a.models / f"{name}{suffix}", a.work / f"{name}{suffix}")
        if not (a.work / f"{name}-int8.onnx").exists():
            quantization_aware_fine_tune(a.work / f"{name}.onnx", data, QAT_CONFIG)
    figures: dict[str, dict[str, tuple[float, float]]] = {}
    for runtime in ("openvino", "openvino-int8"):
        res = evaluate(data, ["ssd"], a.work, held_out=VIDEOS, ssd_runtime=runtime)
        figures[runtime] = {
            v: next(
                (r["tpr"], r["far"])
                for r in res[v]["rows"]
                if "(card:" in r["detector"] and r["horizon"]
            )
            for v in VIDEOS
        }
    print("held-out TPR / FAR at the card threshold, horizon filter on")
    print(f"{'video':8} {'float32':>15} {'QAT int8':>15} {'delta':>15}")
    within = True
    for v in VIDEOS:
        (t0, f0), (t1, f1) = figures["openvino"][v], figures["openvino-int8"][v]
        within &= abs(t1 - t0) <= 0.01 and abs(f1 - f0) <= 0.01
        print(
            f"{v:8} {t0:7.3f} / {f0:5.3f} {t1:7.3f} / {f1:5.3f} {t1 - t0:+7.3f} / {f1 - f0:+6.3f}"
        )
    verdict = "ADOPT as the default run-time" if within else "KEEP as an option"
    print(f"every TPR and FAR within 0.01 of float32: {within} -> {verdict}")


if __name__ == "__main__":
    main()
