"""Leave-one-video-out detection scores of every shore detector on the MarDCT annotated
frames, in the layout of Bloisi et al.'s Tables I–II (per video: horizon filter NO/YES, TPR,
FAR, real and detection size).

    python -m usvfast.shore.evaluate_det [--data DIR]
        [--detectors bayes cnn contrast fused change verified verified-contrast cascade
                     ssd-coco ssd ssd-nested]
        [--models DIR] [--steps N] [--hard-negatives] [--json OUT.json]
        [--ssd-runtime opencv|openvino|openvino-bf16|openvino-int8]

For each video, every trained part is fitted on the three other videos only:

* bayes (Kim, Chung and Lee): the paper's fixed 23/203 thresholds with one box from the
  keypoints' extent; the data-driven Otsu threshold per frame (one box per keypoint cluster);
  the EO threshold fitted on the three other videos (grid value of best F1, horizon on).
* cnn: HarbourNet trained by :mod:`usvfast.shore.cnn_train` on the three other videos
  (cached as `shore-cnn-without-VIDEO.onnx` in `--models`, trained when absent); scored at
  its card's confidence threshold, then with the reflection filter (ORB keypoints), the wake
  filter (a boosted stage trained on the three other videos) and both. With
  `--hard-negatives`, the second round of :mod:`usvfast.shore.cnn_mining` on that model's
  false alarms (`shore-cnn-hn-without-VIDEO.onnx`, `--steps` of it, default 2,000), scored
  at the threshold its inner validation on the three other videos chose.
* contrast: the training-free "object on the water" detector of
  :mod:`usvfast.shore.contrast` (nothing learnt); its contrast threshold is picked on the
  three other videos (:func:`pick`), and every grid value is scored (horizon on).
* fused: the CNN trained without the video (as above), its boxes rescored by the contrast
  cue (:mod:`usvfast.shore.fused`); the fused threshold and the share of each frame's best
  score are picked on the three other videos (:func:`pick`; the CNN has seen those frames,
  so this validation is optimistic), and a few grid values are scored beside.
* change: the temporal change detector of :mod:`usvfast.shore.change` (nothing learnt):
  each frame against the registered per-pixel median of its neighbouring annotated frames,
  online (the previous frames only) and offline (previous and next); its change threshold,
  share of the frame's best score and contrast fallback are picked on the three other
  videos (:func:`pick`), for each of the two, and the default parameters scored beside.
* verified / verified-contrast: every detector's candidates (the fold's CNN and contrast, or
  contrast alone), each also re-fitted to the boat by the frame's contrast, rescored by a
  boosted box verifier fitted on the three other videos, NMS across detectors; selection
  picked by inner leave-one-video-out on those three (:mod:`usvfast.shore.verify_eval`).
* cnn and fused, also after the overlap and containment suppression of
  :mod:`usvfast.shore.suppress` (its pair picked on the three other videos).
* cascade: the Haar cascade of :mod:`usvfast.shore.cascade` trained on the three other
  videos with 4 jittered copies of every boat as extra positives (slow: minutes per video),
  with and without the reflection filter.
* ssd-coco / ssd: the COCO-pretrained SSD-MobileNetV2 (:mod:`usvfast.shore.pretrained`),
  zero-shot (class "boat", threshold picked on the three other videos) and fine-tuned on the
  three other videos (:mod:`usvfast.shore.ssd_train`, `shore-ssd-without-VIDEO.onnx` in
  `--models`, trained when absent; its card's threshold), rows of :mod:`usvfast.shore.ssd_eval`;
  `--ssd-runtime` picks what runs it (openvino-int8: the fold model quantised on its own
  training videos by :mod:`usvfast.shore.ssd_quant`, cached as `...-int8.onnx` beside it).
* ssd-nested: the fine-tuned SSD with its recipe (frozen depth), test-time views, threshold
  and suppression picked by inner leave-one-video-out on the three other videos (models
  trained on two of them, scored on the third; :mod:`usvfast.shore.ssd_nested`).

Scores (eqs. 4–5 of Bloisi et al.): TPR = TP/(TP+FN), FAR = FP/(TP+FP), one-to-one matching
at IoU ≥ 0.5 per frame.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence
from pathlib import Path

from usvfast.shore.bayes import BayesDetector, BayesDetectorConfig
from usvfast.shore.det_scoring import (  # noqa: F401  (re-exported)
    FAR_AIM,
    VideoFrames,
    both_horizons,
    f1,
    load_video,
    pick,
    pooled_score,
    score,
)
from usvfast.shore.det_tables import print_breakdown, print_tables
from usvfast.shore.filters import ReflectionFilter, WakeFilter
from usvfast.shore.horizon import HorizonConfig
from usvfast.shore.mardct import AnnotatedFrame, load_mardct

#: CNN confidence thresholds also scored (horizon on, no filter) beside the card's own.
CNN_SWEEP: tuple[float, ...] = (0.2, 0.3, 0.4)

#: Share of the second round's training views centred on a hard negative, and its steps.
HARD_NEGATIVE_SHARE = 0.35
HN_STEPS = 2000

#: Contrast thresholds (robust z) tried for the training-free detector.
CONTRAST_GRID: tuple[float, ...] = (2.5, 3.0, 4.0, 5.0)

#: Fused (threshold, share of the frame's best score) pairs tried.
FUSED_GRID: tuple[tuple[float, float], ...] = tuple(
    (t, r) for t in (0.1, 0.2, 0.3, 0.4) for r in (0.0, 0.5, 0.7, 0.8, 0.9)
)

#: Change detector (threshold, share of the frame's best score, contrast fallback) tried.
CHANGE_GRID: tuple[tuple[float, float, bool], ...] = tuple(
    (t, r, f) for t in (4.0, 5.0, 7.0) for r in (0.0, 0.8) for f in (True, False)
)

#: Overlap suppression (IoU, share of the smaller box inside the other) pairs tried; a
#: containment above 1 never fires (plain NMS).
SUPPRESS_GRID: tuple[tuple[float, float], ...] = (
    (1.0, 1.01),
    (0.45, 1.01),
    (0.3, 1.01),
    (0.2, 1.01),
    (0.45, 0.7),
    (0.3, 0.7),
    (0.3, 0.5),
    (0.2, 0.5),
)


#: EO thresholds tried when fitting the Bayes detector's level on the training videos.
THRESHOLD_GRID: tuple[float, ...] = (40, 60, 80, 100, 120, 140, 160, 180, 200, 220)


def contrast_rows(
    videos: dict[str, VideoFrames], held: str, hcfg: HorizonConfig, cache: dict
) -> list[dict]:
    """The training-free contrast detector's rows for held-out video `held`."""
    from usvfast.shore.contrast import ContrastConfig, ContrastDetector

    for k in CONTRAST_GRID:
        key = f"contrast {k:g}"
        if key not in cache:
            det = ContrastDetector(ContrastConfig(threshold=k, horizon=hcfg))
            cache[key] = {
                v: [det.detect(im, hz) for im, hz in zip(vf.images, vf.horizons, strict=True)]
                for v, vf in videos.items()
            }
    train = [v for v in videos if v != held]
    best = pick(
        CONTRAST_GRID, lambda k: pooled_score(videos, train, cache[f"contrast {k:g}"], hcfg)
    )
    name = f"contrast z>{best:g} (picked on the others)"
    rows = [
        {"detector": name, **r}
        for r in both_horizons(videos[held], cache[f"contrast {best:g}"][held], hcfg)
    ]
    for k in CONTRAST_GRID:
        rows.append(
            {
                "detector": f"contrast z>{k:g}",
                "horizon": True,
                "filters": "",
                **score(videos[held], cache[f"contrast {k:g}"][held], hcfg, True),
            }
        )
    return rows


def fused_rows(
    data: Path,
    videos: dict[str, VideoFrames],
    held: str,
    hcfg: HorizonConfig,
    models: Path,
    steps: int | None,
    log,
    cache: dict,
) -> tuple[list[dict], dict]:
    """The fused detector's rows for held-out video `held` (CNN trained without it)."""
    from usvfast.shore.cnn import CnnDetector
    from usvfast.shore.contrast import ContrastConfig
    from usvfast.shore.fused import FUSED_CNN_FLOOR, FusedDetector, fused_keep

    path = cnn_model(data, held, models, steps, log)
    cnn = CnnDetector(path, conf_threshold=FUSED_CNN_FLOOR)
    fused = FusedDetector(cnn, ContrastConfig(horizon=hcfg))
    scored = {
        v: [fused.score(im, hz) for im, hz in zip(vf.images, vf.horizons, strict=True)]
        for v, vf in videos.items()
    }

    def kept(t: float, r: float) -> dict:
        return {v: [d.subset(fused_keep(d.scores, t, r)) for d in ds] for v, ds in scored.items()}

    train = [v for v in videos if v != held]
    t, r = pick(FUSED_GRID, lambda tr: pooled_score(videos, train, kept(*tr), hcfg))  # pyright: ignore[reportGeneralTypeIssues]
    rows = [
        {"detector": f"fused ≥ {t:g}, ≥ {r:g} × best (picked on the others)", **row}
        for row in both_horizons(videos[held], kept(t, r)[held], hcfg)
    ]
    fused_t = {v: kept(t, r)[v] for v in videos}
    sup, sup_rows = suppression_rows(videos, held, fused_t, hcfg, f"fused ≥ {t:g}, ≥ {r:g} × best")
    rows += sup_rows
    for tt, rr in ((0.2, 0.0), (0.3, 0.0), (0.1, 0.9), (0.2, 0.8), (0.2, 0.9)):
        rows.append(
            {
                "detector": f"fused ≥ {tt:g}, ≥ {rr:g} × best",
                "horizon": True,
                "filters": "",
                **score(videos[held], kept(tt, rr)[held], hcfg, True),
            }
        )
    return rows, {
        "fused_threshold": t,
        "fused_relative": r,
        "fused_suppression": list(sup),
        "cnn_model": path.name,
    }


def suppression_rows(
    videos: dict[str, VideoFrames],
    held: str,
    dets: dict,
    hcfg: HorizonConfig,
    label: str,
) -> tuple[tuple[float, float], list[dict]]:
    """Rows of per-video detections `dets[v]` after the overlap and containment suppression
    of :mod:`usvfast.shore.suppress`, its (IoU, containment) pair picked on the three other
    videos (:func:`pick`, equal TPRs: lowest FAR), with both horizon settings; then the
    shipped pair."""
    from usvfast.shore.suppress import SUPPRESS_CONTAIN, SUPPRESS_NMS, suppress

    cache: dict = {}

    def sup(nc: tuple[float, float]) -> dict:
        if nc not in cache:
            cache[nc] = {v: [suppress(d, *nc) for d in ds] for v, ds in dets.items()}
        return cache[nc]

    train = [v for v in videos if v != held]
    nc = pick(SUPPRESS_GRID, lambda c: pooled_score(videos, train, sup(c), hcfg), True)  # pyright: ignore[reportArgumentType]
    n, c = nc  # pyright: ignore[reportGeneralTypeIssues]
    rows = [
        {"detector": f"{label} + suppression IoU {n:g}, inside {c:g} (picked)", **row}
        for row in both_horizons(videos[held], sup((n, c))[held], hcfg)
    ]
    shipped = (SUPPRESS_NMS, SUPPRESS_CONTAIN)
    rows.append(
        {
            "detector": f"{label} + suppression IoU {shipped[0]:g}, inside {shipped[1]:g}",
            "horizon": True,
            "filters": "",
            **score(videos[held], sup(shipped)[held], hcfg, True),
        }
    )
    return (n, c), rows


def change_rows(
    videos: dict[str, VideoFrames], held: str, hcfg: HorizonConfig, cache: dict
) -> list[dict]:
    """The temporal change detector's rows for held-out video `held`: online and offline,
    each with the grid setting picked on the other videos, then the default setting."""
    from dataclasses import replace

    from usvfast.shore.change import ChangeConfig, ChangeDetector
    from usvfast.shore.contrast import ContrastConfig

    base = ChangeConfig(contrast=ContrastConfig(horizon=hcfg))
    rows = []
    train = [v for v in videos if v != held]
    for online in (True, False):
        mode = "online" if online else "offline"
        cfg0 = replace(base, online=online)
        key = f"change maps {mode}"
        if key not in cache:
            cache[key] = {
                v: ChangeDetector(cfg0).change_maps(vf.images) for v, vf in videos.items()
            }

        def dets(t: float, r: float, f: bool, cfg0=cfg0, key=key) -> dict:
            name = f"{key} {t:g} {r:g} {f}"
            if name not in cache:
                det = ChangeDetector(replace(cfg0, threshold=t, relative=r, fallback=f))
                cache[name] = {
                    v: det.detect_maps(cache[key][v], vf.images, vf.horizons)
                    for v, vf in videos.items()
                }
            return cache[name]

        t, r, f = pick(CHANGE_GRID, lambda c: pooled_score(videos, train, dets(*c), hcfg))  # pyright: ignore[reportGeneralTypeIssues]
        label = f"change {mode} z>{t:g}, ≥ {r:g} × best, fallback {'on' if f else 'off'}"
        rows += [
            {"detector": f"{label} (picked on the others)", **row}
            for row in both_horizons(videos[held], dets(t, r, f)[held], hcfg)
        ]
        d = (base.threshold, base.relative, base.fallback)
        rows.append(
            {
                "detector": f"change {mode} defaults (z>{d[0]:g}, ≥ {d[1]:g} × best, fallback)",
                "horizon": True,
                "filters": "",
                **score(videos[held], dets(*d)[held], hcfg, True),
            }
        )
    return rows


def bayes_rows(
    videos: dict[str, VideoFrames], held: str, hcfg: HorizonConfig, cache: dict
) -> list[dict]:
    """The Bayes detector's rows for held-out video `held` (paper, Otsu, fitted level)."""
    settings = {
        "bayes 23/203 extent (paper)": BayesDetectorConfig(),
        "bayes Otsu clusters": BayesDetectorConfig(threshold_mode="otsu", grouping="clusters"),
    }
    for thr in THRESHOLD_GRID:
        settings[f"t{thr:g}"] = BayesDetectorConfig(
            thresholds={"eo": float(thr), "ir": 203.0}, grouping="clusters"
        )
    for name, cfg in settings.items():
        if name not in cache:
            det = BayesDetector(cfg)
            cache[name] = {v: [det.detect(im) for im in vf.images] for v, vf in videos.items()}
    train = [v for v in videos if v != held]

    def train_f1(thr: float) -> float:
        tot = {"tp": 0, "fp": 0, "fn": 0}
        for v in train:
            s = score(videos[v], cache[f"t{thr:g}"][v], hcfg, True)
            tot = {k: tot[k] + s[k] for k in tot}
        return f1(tot)

    best = max(THRESHOLD_GRID, key=lambda t: (train_f1(t), -t))
    rows = []
    for name in ("bayes 23/203 extent (paper)", "bayes Otsu clusters"):
        rows += [
            {"detector": name, **r} for r in both_horizons(videos[held], cache[name][held], hcfg)
        ]
    fitted = f"bayes {best:g} clusters (fitted)"
    rows += [
        {"detector": fitted, **r}
        for r in both_horizons(videos[held], cache[f"t{best:g}"][held], hcfg)
    ]
    return rows


def cnn_model(
    data: Path, held: str, models: Path, steps: int | None, log, hard_negatives: bool = False
) -> Path:
    """The ONNX model trained without `held` (trained and saved when absent). With
    `hard_negatives`, the second round of :mod:`usvfast.shore.cnn_mining` on the first
    model's false alarms (threshold by inner validation on the training videos)."""
    from usvfast.shore.cnn_train import CnnTrainConfig, train_and_export

    name = f"shore-cnn-without-{held}"
    path = models / f"{name}.onnx"
    if not path.is_file():
        cfg = CnnTrainConfig() if steps is None else CnnTrainConfig(steps=steps)
        train_and_export(data, models, cfg, exclude=[held], name=name, log=log)
    if not hard_negatives:
        return path
    from usvfast.shore.cnn_mining import train_hard_negative_round

    name2 = f"shore-cnn-hn-without-{held}"
    path2 = models / f"{name2}.onnx"
    if not path2.is_file():
        cfg = CnnTrainConfig(hard_negative=HARD_NEGATIVE_SHARE, steps=steps or HN_STEPS)
        train_hard_negative_round(data, path, models, cfg, exclude=[held], name=name2, log=log)
    return path2


def cnn_rows(
    data: Path,
    videos: dict[str, VideoFrames],
    mardct: dict[str, list[AnnotatedFrame]],
    held: str,
    hcfg: HorizonConfig,
    models: Path,
    steps: int | None,
    log,
    hard_negatives: bool = False,
) -> tuple[list[dict], dict]:
    """The CNN's rows for held-out video `held`, with and without the filters."""
    from usvfast.shore.cnn import CnnDetector

    path = cnn_model(data, held, models, steps, log, hard_negatives)
    card = json.loads(path.with_suffix(".json").read_text(encoding="utf-8"))
    conf = float(card.get("conf_threshold", 0.3))
    low = CnnDetector(path, conf_threshold=min(*CNN_SWEEP, conf))
    swept = [low.detect(im) for im in videos[held].images]
    det = CnnDetector(path)
    dets = [d.subset(d.scores >= conf) for d in swept]
    train_frames = [f for v in mardct if v != held for f in mardct[v]]
    t0 = time.perf_counter()
    wake = WakeFilter.train(train_frames, det.detect)
    wake_s = time.perf_counter() - t0
    refl = ReflectionFilter()

    def both(image, d):
        return refl.keep(image, d) & wake.keep(image, d)

    rows = []
    for label, extra in (
        ("", None),
        ("reflection", refl.keep),
        ("wake", wake.keep),
        ("reflection+wake", both),
    ):
        rows += [
            {"detector": f"cnn (confidence {conf:g})", **r}
            for r in both_horizons(videos[held], dets, hcfg, extra, label)
        ]
    per_video = {
        v: (dets if v == held else [d.subset(d.scores >= conf) for d in map(low.detect, vf.images)])
        for v, vf in videos.items()
    }
    sup, sup_rows = suppression_rows(videos, held, per_video, hcfg, f"cnn (confidence {conf:g})")
    rows += sup_rows
    for c in CNN_SWEEP:
        if c != conf:
            sub = [d.subset(d.scores >= c) for d in swept]
            rows.append(
                {
                    "detector": f"cnn (confidence {c:g})",
                    "horizon": True,
                    "filters": "",
                    **score(videos[held], sub, hcfg, True),
                }
            )
    info = {
        "cnn_model": path.name,
        "cnn_conf": conf,
        "cnn_train_s": card.get("train_seconds"),
        "wake_train_s": round(wake_s, 1),
        "cnn_suppression": list(sup),
    }
    return rows, info


def cascade_rows(
    videos: dict[str, VideoFrames],
    mardct: dict[str, list[AnnotatedFrame]],
    held: str,
    hcfg: HorizonConfig,
    augment: int = 4,
) -> tuple[list[dict], dict]:
    """The Haar cascade's rows for held-out video `held` (trained on the other videos)."""
    from usvfast.shore.cascade import CascadeConfig, train_detector

    t0 = time.perf_counter()
    train_frames = [f for v in mardct if v != held for f in mardct[v]]
    detector, report = train_detector(train_frames, CascadeConfig(augment_copies=augment))
    seconds = time.perf_counter() - t0
    dets = [detector.detect(im) for im in videos[held].images]
    refl = ReflectionFilter()
    name = f"cascade (+{augment} jittered copies per boat)"
    rows = [{"detector": name, **r} for r in both_horizons(videos[held], dets, hcfg)]
    rows += [
        {"detector": name, **r}
        for r in both_horizons(videos[held], dets, hcfg, refl.keep, "reflection")
    ]
    return rows, {"cascade_train_s": round(seconds, 1), "cascade_stages": len(report["stages"])}


def evaluate(
    data: Path,
    detectors: Sequence[str] = ("bayes", "cnn"),
    models: Path | None = None,
    steps: int | None = None,
    held_out: Sequence[str] | None = None,
    log=print,
    hard_negatives: bool = False,
    ssd_recipes: Sequence[str] | None = None,
    ssd_runtime: str = "opencv",
) -> dict:
    """Leave-one-video-out rows per video (module doc); a JSON-ready dict. `ssd_recipes`:
    the training recipes ssd-nested compares (default
    :data:`usvfast.shore.ssd_nested.DEFAULT_RECIPES`); `ssd_runtime`: what runs the ssd rows'
    network (:data:`usvfast.shore.ssd_eval.RUNTIMES`)."""
    mardct = load_mardct(data)
    hcfg = HorizonConfig()
    videos = {v: load_video(f, hcfg) for v, f in mardct.items()}
    models = models or Path("shore-models")
    out: dict = {}
    cache: dict = {}
    for held in held_out or list(mardct):
        vf = videos[held]
        h, w = vf.images[0].shape[:2]
        entry: dict = {
            "frames": len(vf.frames),
            "boxes": int(sum(len(f.boxes) for f in vf.frames)),
            "size": [w, h],
            "rows": [],
        }
        if "bayes" in detectors:
            entry["rows"] += bayes_rows(videos, held, hcfg, cache)
        if "cnn" in detectors:
            rows, info = cnn_rows(
                data, videos, mardct, held, hcfg, models, steps, log, hard_negatives
            )
            entry["rows"] += rows
            entry.update(info)
        if "contrast" in detectors:
            entry["rows"] += contrast_rows(videos, held, hcfg, cache)
        if "fused" in detectors:
            rows, info = fused_rows(data, videos, held, hcfg, models, steps, log, cache)
            entry["rows"] += rows
            entry.update(info)
        if "change" in detectors:
            entry["rows"] += change_rows(videos, held, hcfg, cache)
        if "verified" in detectors or "verified-contrast" in detectors:
            from usvfast.shore.verify_eval import verified_rows

            for kind in ("verified", "verified-contrast"):
                if kind in detectors:
                    path = cnn_model(data, held, models, steps, log) if kind == "verified" else None
                    rows, info = verified_rows(videos, held, hcfg, path)
                    entry["rows"] += rows
                    entry.update(info)
        if "cascade" in detectors:
            rows, info = cascade_rows(videos, mardct, held, hcfg)
            entry["rows"] += rows
            entry.update(info)
        if "ssd-coco" in detectors:
            from usvfast.shore.ssd_eval import coco_rows

            rows, info = coco_rows(videos, held, hcfg, cache)
            entry["rows"] += rows
            entry.update(info)
        if "ssd" in detectors:
            from usvfast.shore.ssd_eval import ssd_rows

            rows, info = ssd_rows(data, videos, held, hcfg, models, log, ssd_runtime)
            entry["rows"] += rows
            entry.update(info)
        if "ssd-nested" in detectors:
            from usvfast.shore.ssd_eval import nested_rows

            rows, info = nested_rows(data, videos, held, hcfg, models, cache, log, ssd_recipes)
            entry["rows"] += rows
            entry.update(info)
        out[held] = entry
        log(f"{held}: done")
    return out


def main(argv: Sequence[str] | None = None) -> None:
    """Command-line entry point (module doc)."""
    from usvfast.shore.evaluate import default_data
    from usvfast.shore.ssd_eval import RUNTIMES

    p = argparse.ArgumentParser(
        prog="python -m usvfast.shore.evaluate_det", description=(__doc__ or "").split("\n")[0]
    )
    p.add_argument("--data", type=Path, default=None, help="MarDCT training/annotations folder")
    p.add_argument("--detectors", nargs="*", default=["bayes", "cnn"])
    p.add_argument("--models", type=Path, default=Path("shore-models"), help="CNN model cache")
    p.add_argument("--steps", type=int, default=None, help="CNN training steps")
    p.add_argument("--videos", nargs="*", default=None, help="Score only these videos")
    p.add_argument(
        "--hard-negatives",
        action="store_true",
        help="CNN: second training round on the first model's false alarms",
    )
    p.add_argument("--json", type=Path, default=None, help="Write the results as JSON here")
    p.add_argument(
        "--ssd-recipes",
        nargs="*",
        default=None,
        help="ssd-nested: training recipes compared: default (the default) and/or deep",
    )
    p.add_argument(
        "--breakdown", action="store_true", help="Also print where each row's errors are"
    )
    p.add_argument("--ssd-runtime", default="opencv", choices=RUNTIMES, help="ssd: what runs it")
    a = p.parse_args(argv)
    unknown = set(a.detectors) - {
        "bayes",
        "cnn",
        "contrast",
        "fused",
        "change",
        "cascade",
        "verified",
        "verified-contrast",
        "ssd-coco",
        "ssd",
        "ssd-nested",
    }
    if unknown:
        p.error(f"--detectors: unknown {sorted(unknown)}")
    results = evaluate(
        a.data or default_data(),
        a.detectors,
        a.models,
        a.steps,
        a.videos,
        hard_negatives=a.hard_negatives,
        ssd_recipes=a.ssd_recipes,
        ssd_runtime=a.ssd_runtime,
    )
    print_tables(results)
    if a.breakdown:
        print_breakdown(results)
    if a.json:
        a.json.write_text(json.dumps(results, indent=2, default=float), encoding="utf-8")


if __name__ == "__main__":
    main()
