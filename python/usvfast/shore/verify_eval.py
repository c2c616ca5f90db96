"""Leave-one-video-out rows of the verified detector (:mod:`usvfast.shore.verify`) for
:mod:`usvfast.shore.evaluate_det` (`--detectors verified`).

For a held-out video, the candidates of every video are proposed by the CNN trained without
it (the fold's model) and the contrast detector; the verifier is fitted on the three other
videos' candidates. Its selection (score threshold, share of the frame's best score, NMS IoU)
is picked on those three videos from inner leave-one-video-out scores (each training video
scored by a verifier fitted on the two others), never on the held-out video. The CNN has
seen the training videos, so its boxes there are better than on a new video: the inner
validation stays optimistic for the CNN-proposed variant; the contrast-only variant has no
such bias (nothing in it saw any frame but the verifier's training videos).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from usvfast.shore.boxes import Detections
from usvfast.shore.contrast import ContrastConfig
from usvfast.shore.det_scoring import both_horizons, pick, score
from usvfast.shore.horizon import HorizonConfig
from usvfast.shore.verify import BoxVerifier, Candidates, best_iou, candidates, select

#: Selection settings (score threshold, share of the frame's best score, NMS IoU) tried.
SELECT_GRID: tuple[tuple[float, float, float], ...] = tuple(
    (t, r, n)
    for t in (0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5)
    for r in (0.0, 0.5, 0.7, 0.9)
    for n in (0.2, 0.4)
)

#: CNN proposals' confidence floor and NMS IoU.
CNN_FLOOR = 0.05
CNN_NMS = 0.6


def fold_candidates(
    videos: dict, held: str, cnn, hcfg: HorizonConfig
) -> dict[str, list[Candidates]]:
    """Candidates of every frame of every video (the CNN `cnn` trained without `held`, or
    None for contrast proposals only)."""
    cfg = ContrastConfig(horizon=hcfg)
    out = {}
    for v, vf in videos.items():
        out[v] = [
            candidates(im, hz, cnn.detect(im) if cnn is not None else None, cfg)
            for im, hz in zip(vf.images, vf.horizons, strict=True)
        ]
    return out


def _stack(videos: dict, cands: dict, names: Sequence[str]):
    x, y, g = [], [], []
    for v in names:
        for f, c in zip(videos[v].frames, cands[v], strict=True):
            if len(c.boxes):
                x.append(c.features)
                y.append(best_iou(f.boxes, c.boxes))
                g += [v] * len(c.boxes)
    return np.concatenate(x), np.concatenate(y), g


def _fit(videos: dict, cands: dict, names: Sequence[str]) -> BoxVerifier:
    x, y, g = _stack(videos, cands, names)
    return BoxVerifier().fit(x, y, g)


def _dets(cands: list[Candidates], scores: list[np.ndarray], setting) -> list[Detections]:
    t, r, n = setting
    out = []
    for c, s in zip(cands, scores, strict=True):
        k = select(c.boxes, s, t, r, n)
        out.append(Detections(c.boxes[k], s[k], np.full(len(k), -1, dtype=np.int64)))
    return out


def verified_rows(
    videos: dict, held: str, hcfg: HorizonConfig, cnn_path: Path | None
) -> tuple[list[dict], dict]:
    """Rows for held-out video `held` (module doc). `videos`: every video's
    :class:`usvfast.shore.det_scoring.VideoFrames`; `cnn_path`: the fold's ONNX model (None:
    contrast proposals only)."""
    from usvfast.shore.cnn import CnnDetector

    cnn = (
        CnnDetector(cnn_path, conf_threshold=CNN_FLOOR, iou_threshold=CNN_NMS)
        if cnn_path is not None
        else None
    )
    cands = fold_candidates(videos, held, cnn, hcfg)
    train = [v for v in videos if v != held]
    inner: dict[str, list[np.ndarray]] = {}
    for v in train:
        model = _fit(videos, cands, [u for u in train if u != v])
        inner[v] = [model.predict(c.features) for c in cands[v]]

    def pooled(setting) -> dict:
        tot = {"tp": 0, "fp": 0, "fn": 0}
        for v in train:
            s = score(videos[v], _dets(cands[v], inner[v], setting), hcfg, True)
            tot = {k: tot[k] + s[k] for k in tot}
        return tot

    setting: tuple[float, float, float] = pick(SELECT_GRID, pooled)  # pyright: ignore[reportAssignmentType]
    model = _fit(videos, cands, train)
    held_scores = [model.predict(c.features) for c in cands[held]]
    src = "cnn+contrast" if cnn is not None else "contrast only"
    t, r, n = setting
    name = f"verified {src} ≥ {t:g}, ≥ {r:g} × best, NMS {n:g} (picked on the others)"
    rows = [
        {"detector": name, **row}
        for row in both_horizons(videos[held], _dets(cands[held], held_scores, setting), hcfg)
    ]
    # the candidate pool's ceiling: every candidate kept (no verifier)
    pool = [
        Detections(c.boxes, np.ones(len(c.boxes)), np.full(len(c.boxes), -1)) for c in cands[held]
    ]
    rows.append(
        {
            "detector": f"candidates {src} (all, ceiling)",
            "horizon": True,
            "filters": "",
            **score(videos[held], pool, hcfg, True),
        }
    )
    for alt in ((0.3, 0.0, 0.4), (0.4, 0.5, 0.4), (0.5, 0.8, 0.4)):
        if alt != setting:
            rows.append(
                {
                    "detector": f"verified {src} ≥ {alt[0]:g}, ≥ {alt[1]:g} × best, NMS {alt[2]:g}",
                    "horizon": True,
                    "filters": "",
                    **score(videos[held], _dets(cands[held], held_scores, alt), hcfg, True),
                }
            )
    return rows, {f"verified_{src}": list(setting)}
