"""Rows of the COCO-pretrained SSD detectors for the leave-one-video-out detection evaluation
(:mod:`usvfast.shore.evaluate_det`): zero-shot (`ssd-coco`: COCO's "boat" class, nothing
learnt on MarDCT; its confidence threshold picked on the three other videos) and fine-tuned
(`ssd`: :mod:`usvfast.shore.ssd_train` on the three other videos, cached as
`shore-ssd-without-VIDEO.onnx` in the models folder and trained when absent; scored at its
card's threshold, picked on those three videos)."""

from __future__ import annotations

import json
from pathlib import Path

from usvfast.shore.det_scoring import VideoFrames, both_horizons, pick, pooled_score, score
from usvfast.shore.horizon import HorizonConfig

#: Zero-shot confidence thresholds tried (COCO's boat scores run lower than a fine-tuned one).
COCO_GRID: tuple[float, ...] = (0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6)
#: Fine-tuned confidence thresholds also scored (horizon on) beside the card's own.
SSD_SWEEP: tuple[float, ...] = (0.3, 0.5, 0.7, 0.9)


def _rows_at(name: str, videos, held, low, grid, hcfg, picked: float | None = None):
    """Rows of thresholded detections `low[v]` (every score ≥ min(grid)): the threshold
    `picked` (else the pick on the other videos), both horizons, then each grid value."""
    train = [v for v in videos if v != held]

    def at(c: float) -> dict:
        return {v: [d.subset(d.scores >= c) for d in ds] for v, ds in low.items()}

    if picked is None:
        picked = float(pick(grid, lambda c: pooled_score(videos, train, at(c), hcfg)))  # pyright: ignore[reportArgumentType]
        label = f"{name} ≥ {picked:g} (picked on the others)"
    else:
        label = f"{name} ≥ {picked:g} (card: picked on the others)"
    rows = [{"detector": label, **r} for r in both_horizons(videos[held], at(picked)[held], hcfg)]
    for c in grid:
        if c != picked:
            rows.append(
                {
                    "detector": f"{name} ≥ {c:g}",
                    "horizon": True,
                    "filters": "",
                    **score(videos[held], at(c)[held], hcfg, True),
                }
            )
    return picked, rows


def coco_rows(
    videos: dict[str, VideoFrames], held: str, hcfg: HorizonConfig, cache: dict
) -> tuple[list[dict], dict]:
    """Zero-shot COCO SSD rows for held-out video `held` (300 × 300 stretched, the graph's
    own set-up; boxes of class "boat")."""
    from usvfast.shore.pretrained import SsdDetector, coco_network

    if "ssd-coco" not in cache:
        det = SsdDetector(coco_network(), conf_threshold=min(COCO_GRID))
        cache["ssd-coco"] = {v: [det.detect(im) for im in vf.images] for v, vf in videos.items()}
    picked, rows = _rows_at("ssd COCO zero-shot", videos, held, cache["ssd-coco"], COCO_GRID, hcfg)
    return rows, {"ssd_coco_conf": picked}


#: Run-times of the fine-tuned SSD rows: OpenCV DNN, OpenVINO float32 / bfloat16, and the
#: fold model quantised to int8 on its training videos (:mod:`usvfast.shore.ssd_quant`).
RUNTIMES: tuple[str, ...] = ("opencv", "openvino", "openvino-bf16", "openvino-int8")


def runtime_options(name: str) -> tuple[str, str, bool]:
    """(backend, precision, int8) of a run-time name of :data:`RUNTIMES`."""
    if name not in RUNTIMES:
        raise ValueError(f"runtime: expected one of {RUNTIMES}, got {name!r}")
    backend, _, precision = name.partition("-")
    return backend, "f32" if precision in ("", "int8") else precision, precision == "int8"


def ssd_rows(
    data: Path,
    videos: dict[str, VideoFrames],
    held: str,
    hcfg: HorizonConfig,
    models: Path,
    log,
    runtime: str = "opencv",
) -> tuple[list[dict], dict]:
    """Fine-tuned SSD rows for held-out video `held` (model trained without it), then with
    the overlap and containment suppression of :mod:`usvfast.shore.suppress` (its pair picked
    on the three other videos, which the model was trained on: an optimistic choice). The
    network runs on `runtime` (:data:`RUNTIMES`)."""
    from usvfast.shore.evaluate_det import suppression_rows
    from usvfast.shore.pretrained import SsdDetector
    from usvfast.shore.ssd_nested import fold_model

    backend, precision, int8 = runtime_options(runtime)
    path = fold_model(data, models, "default", [held], log)
    card = json.loads(path.with_suffix(".json").read_text(encoding="utf-8"))
    conf = float(card["conf_threshold"])
    if int8:
        from usvfast.shore.ssd_quant import int8_model

        if held in card.get("videos", [held]):  # calibration = the card's training videos
            raise ValueError(f"model: {path.name} was trained on the held-out video {held}")

        path = int8_model(path, data, log)
    det = SsdDetector(
        path, conf_threshold=min(conf, *SSD_SWEEP), backend=backend, precision=precision
    )
    low = {v: [det.detect(im) for im in vf.images] for v, vf in videos.items()}
    sweep = tuple(sorted({conf, *SSD_SWEEP}))
    only = {held: low[held]}
    _, rows = _rows_at("ssd fine-tuned", {held: videos[held]}, held, only, sweep, hcfg, conf)
    at_conf = {v: [d.subset(d.scores >= conf) for d in ds] for v, ds in low.items()}
    sup, sup_rows = suppression_rows(videos, held, at_conf, hcfg, f"ssd fine-tuned ≥ {conf:g}")
    info = {"ssd_model": path.name, "ssd_conf": conf, "ssd_train_s": card["train_seconds"]}
    info["ssd_runtime"] = runtime
    return rows + sup_rows, {**info, "ssd_suppression": list(sup)}


def nested_rows(
    data: Path,
    videos: dict[str, VideoFrames],
    held: str,
    hcfg: HorizonConfig,
    models: Path,
    cache: dict,
    log,
    recipes=None,
) -> tuple[list[dict], dict]:
    """Rows of the fine-tuned SSD whose whole set-up (recipe, test-time views, threshold,
    suppression) is picked by inner leave-one-video-out on the other videos
    (:mod:`usvfast.shore.ssd_nested`; nothing chosen on `held` or on frames a model saw):
    the picked set-up with both horizons, and the pick with its pooled inner TPR / FAR. Needs
    3 inner models per recipe of `recipes` (default
    :data:`usvfast.shore.ssd_nested.DEFAULT_RECIPES`) and the held-out model of the recipe
    picked (trained when absent in `models`)."""
    from usvfast.shore.ssd_nested import (
        CandidateCache,
        fold_model,
        nested_choice,
        setup_detections,
    )

    cc = cache.setdefault("ssd-nested", CandidateCache(Path(models) / "candidates"))
    setup, inner = nested_choice(data, models, videos, held, hcfg, cc, recipes, log)
    path = fold_model(data, models, setup.recipe, [held], log)
    dets = setup_detections(cc, path, held, videos[held], setup)
    label = (
        f"ssd nested: {setup.recipe}, {setup.view}, ≥ {setup.conf:g}"
        f"{', suppression' if setup.suppression else ''} (picked by inner LOVO)"
    )
    rows = [{"detector": label, **r} for r in both_horizons(videos[held], dets, hcfg)]
    tp, fp, fn = inner["tp"], inner["fp"], inner["fn"]
    info = {
        "ssd_nested": {
            "recipe": setup.recipe,
            "view": setup.view,
            "conf": setup.conf,
            "suppression": setup.suppression,
            "model": path.name,
            "inner_tpr": tp / max(tp + fn, 1),
            "inner_far": fp / max(tp + fp, 1),
        }
    }
    return rows, info
