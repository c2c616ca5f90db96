"""How far a confidence threshold alone can take the fine-tuned shore SSD: for each
leave-one-video-out fold model, every threshold is tried ON THE HELD-OUT VIDEO ITSELF (an
oracle no deployment has) and the best TPR with FAR ≤ 0.15 is printed, with and without
the shipped overlap and containment suppression (IoU 0.3, inside 0.7), horizon filter on.

An upper bound, not a score: it tells whether any threshold rule or score calibration
(picked on other videos, or adapted to the video while it runs) could reach the aim of
TPR ≥ 0.85 at FAR ≤ 0.15 with these models. Where the oracle misses it, the model's ranking
of its boxes is the limit and only a better detector can help.

    python benches/shore_threshold_oracle.py --models DIR [--data ANNOTATIONS] [--videos V ...]

DIR holds `shore-ssd-without-V.onnx` for V in video3, regDTV9, 2, 3 (`python -m
usvfast.shore.ssd_train ANNOTATIONS --out DIR --exclude V`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from usvfast.shore.det_scoring import FAR_AIM, load_video, score
from usvfast.shore.evaluate import default_data
from usvfast.shore.horizon import HorizonConfig
from usvfast.shore.mardct import load_mardct
from usvfast.shore.pretrained import SsdDetector
from usvfast.shore.suppress import suppress

VIDEOS = ("video3", "regDTV9", "2", "3")
#: The lowest confidence kept from the network; every distinct score above it is tried.
FLOOR = 0.02


def best_under_far(video, raw, hcfg: HorizonConfig, suppressed: bool) -> tuple[float, float, float]:
    """(threshold, TPR, FAR) of the highest TPR with FAR ≤ FAR_AIM over every distinct score
    of the video's boxes (ties: the lower FAR); (nan, 0, 0) when no threshold keeps a box."""
    best = (float("nan"), 0.0, 0.0)
    for t in np.unique(np.concatenate([d.scores for d in raw])):
        dets = [d.subset(d.scores >= t) for d in raw]
        if suppressed:
            dets = [suppress(d, nms=0.3, contain=0.7) for d in dets]
        s = score(video, dets, hcfg, True)
        if s["far"] <= FAR_AIM and (s["tpr"], -s["far"]) > (best[1], -best[2]):
            best = (float(t), s["tpr"], s["far"])
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", type=Path, required=True, help="Folder of the fold models")
    ap.add_argument("--data", type=Path, default=None, help="MarDCT training/annotations")
    ap.add_argument("--videos", nargs="+", default=VIDEOS, help="Held-out videos to score")
    a = ap.parse_args()
    hcfg = HorizonConfig()
    frames = load_mardct(a.data or default_data())
    print(f"best TPR with FAR <= {FAR_AIM} over thresholds chosen on the held-out video itself")
    print("| held-out video | boats | no suppression: threshold, TPR / FAR | suppression |")
    print("| --- | --- | --- | --- |")
    for v in a.videos:
        video = load_video(frames[v], hcfg)
        det = SsdDetector(a.models / f"shore-ssd-without-{v}.onnx", conf_threshold=FLOOR)
        raw = [det.detect(im) for im in video.images]
        cells = []
        for suppressed in (False, True):
            t, tpr, far = best_under_far(video, raw, hcfg, suppressed)
            cells.append(f"≥ {t:.3f}: {tpr:.3f} / {far:.3f}")
        boats = sum(len(f.boxes) for f in frames[v])
        print(f"| {v} | {boats} | {cells[0]} | {cells[1]} |")


if __name__ == "__main__":
    main()
