"""Leave-one-video-out evaluation of the shore chain on the MarDCT annotated frames.

    python -m usvfast.shore.evaluate [--data DIR] [--json OUT.json]

For each video, the detector's one trained parameter, the EO binary threshold (Kim, Chung and
Lee store "the optimal threshold" per frame class; eq. 4), is chosen on the three other videos
(the grid value with the best F1 of TP/FP/FN at IoU ≥ 0.5, horizon filter on) and the video is
scored with it. Reported per video (Bloisi et al.'s Tables I–II layout): TPR and FAR with and
without the horizon filter for the paper's fixed thresholds (23/203, one box per frame from the
keypoints' extent) and for the held-out-tuned threshold with one box per keypoint cluster;
and for the Haar cascade (`usvfast.shore.cascade`) trained on the three other videos; then
CLEAR MOT with IoU (MOTA, MOTP as mean IoU, IDF1, precision, recall; `usvfast.metrics`, equal
to py-motmetrics) of the SORT-like and the adaptive Kalman trackers on each detector's
detections (horizon filter on). `--no-cascade` skips the cascade.

    python -m usvfast.shore.evaluate --detector cnn --models DIR [--videos video3 regDTV9]

scores the CNN instead (or beside the Bayes detector: `--detector bayes cnn`): for each video,
the model of `DIR` trained without it (`shore-cnn-hn-without-VIDEO.onnx`, the hard-negative
round of :mod:`usvfast.shore.cnn_mining`, else `shore-cnn-without-VIDEO.onnx`; train them with
`python -m usvfast.shore.evaluate_det --detectors cnn [--hard-negatives] --models DIR`) at its
card's confidence threshold (chosen on the training videos), detection and tracking rows.
`--detector contrast` scores the training-free detector of :mod:`usvfast.shore.contrast`
and `--detector fused` the fold's CNN rescored by it (:mod:`usvfast.shore.fused`, its
default thresholds; `fused-nms` then also the overlap and containment suppression of
:mod:`usvfast.shore.suppress`). `--detector change` scores the temporal change detector of
:mod:`usvfast.shore.change` (online: each annotated frame against the registered median of
the previous ones; default parameters). `--detector ssd` scores the COCO-pretrained SSD
fine-tuned without the video (`shore-ssd-without-VIDEO.onnx` of `--models`, from
`python -m usvfast.shore.evaluate_det --detectors ssd --models DIR`) at its card's threshold,
alone and after the suppression of :mod:`usvfast.shore.suppress` (its shipped pair).
`--detector ssd-nested` scores the fine-tuned SSD whose recipe, test-time views, threshold
and suppression, and then the SORT and particle trackers' settings, are all picked by inner
leave-one-video-out on the three other videos (:mod:`usvfast.shore.ssd_nested`,
:mod:`usvfast.shore.ssd_nested_track`; its inner models are trained into `--models` when
absent). Without `bayes` in `--detector` only.

MarDCT boxes carry no identities: the ground-truth ids are derived by linking the boxes of
consecutive annotated frames (optimal assignment on centre distance, gated at two box
diagonals); this is stated with the results.

    python -m usvfast.shore.evaluate ... --sort-high-score 0.45 --sort-low-score 0

runs the SORT-like tracker of every tracking row with ByteTrack's two-stage association
(:class:`usvfast.shore.sort.SortConfig` `high_score`, `low_score`; default 0 and 0: one
stage). The values are not tuned here: pick them on other videos.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
from rich.console import Console
from rich.table import Table

from usvfast._files import read_image
from usvfast._validate import instance
from usvfast.shore.bayes import BayesDetector, BayesDetectorConfig
from usvfast.shore.boxes import Detections
from usvfast.shore.cascade import CascadeConfig, train_detector
from usvfast.shore.daynight import DayNightClassifier
from usvfast.shore.horizon import HorizonConfig, HorizonLine, detect_horizon, horizon_keep
from usvfast.shore.mardct import AnnotatedFrame, load_mardct
from usvfast.shore.mot_eval import (  # noqa: F401  (derive_truth_ids: public here too)
    derive_truth_ids,
    tracking_rows,
    truth_detections,
)
from usvfast.shore.scores import DetectionCounts
from usvfast.shore.sort import SortConfig, sort_config_from_options

#: EO thresholds tried when tuning (8-bit levels).
THRESHOLD_GRID: tuple[float, ...] = (40, 60, 80, 100, 120, 140, 160, 180, 200, 220)


def default_data() -> Path:
    """MarDCT's annotations under the data folder named by $USVFAST_SHARED_DATA (MarDCT is GPL
    and not shipped: pass --data, or set the variable). Raises ValueError when neither is."""
    root = os.environ.get("USVFAST_SHARED_DATA")
    if not root:
        raise ValueError(
            "data: pass --data DIR (MarDCT training/annotations) or set USVFAST_SHARED_DATA"
        )
    return Path(root) / "mardct" / "training" / "annotations"


@dataclass
class FrameCache:
    """Per-frame detections of each detector setting and the frame's horizon."""

    horizon: list[HorizonLine | None] = field(default_factory=list)
    raw: dict[str, list[Detections]] = field(default_factory=dict)


def run_detectors(
    frames: Sequence[AnnotatedFrame], settings: dict[str, BayesDetectorConfig], horizon_cfg
) -> FrameCache:
    """Detections of every setting and the horizon of every frame of one video."""
    cache = FrameCache(raw={k: [] for k in settings})
    detectors = {k: BayesDetector(c) for k, c in settings.items()}
    classifier = DayNightClassifier.default()
    for f in frames:
        image = read_image(f.path, cv2.IMREAD_COLOR)
        infrared = classifier.classify(image) == "ir"
        cache.horizon.append(detect_horizon(image, infrared=infrared, config=horizon_cfg))
        for k, det in detectors.items():
            cache.raw[k].append(det.detect(image))
    return cache


def kept(
    frames: Sequence[AnnotatedFrame], cache: FrameCache, key: str, use_horizon: bool, cfg
) -> list[Detections]:
    """The detections of setting `key` after the horizon filter (or all of them)."""
    out = []
    for f, det, hz in zip(frames, cache.raw[key], cache.horizon, strict=True):
        if use_horizon:
            h = read_image(f.path, cv2.IMREAD_UNCHANGED).shape[0]
            det = det.subset(horizon_keep(det, hz, h, cfg))
        out.append(det)
    return out


def count(frames: Sequence[AnnotatedFrame], dets: Sequence[Detections]) -> DetectionCounts:
    """TP/FP/FN of detections against the annotations at IoU ≥ 0.5."""
    c = DetectionCounts()
    for f, d in zip(frames, dets, strict=True):
        c.add(f.boxes, d.boxes)
    return c


def f1(c: DetectionCounts) -> float:
    """2 TP / (2 TP + FP + FN) (0 without any box)."""
    n = 2 * c.tp + c.fp + c.fn
    return 2 * c.tp / n if n else 0.0


def cnn_fold_model(models: Path, held: str) -> Path:
    """The CNN trained without video `held` in `models` (hard-negative round first)."""
    for name in (f"shore-cnn-hn-without-{held}", f"shore-cnn-without-{held}"):
        path = Path(models) / f"{name}.onnx"
        if path.is_file():
            return path
    raise ValueError(
        f"models: no shore-cnn-hn-without-{held}.onnx or shore-cnn-without-{held}.onnx in "
        f"{models} (python -m usvfast.shore.evaluate_det --detectors cnn --models {models})"
    )


def counts_dict(c: DetectionCounts) -> dict:
    """TPR, FAR, TP, FP, FN of detection counts."""
    return {"tpr": c.tpr, "far": c.far, "tp": c.tp, "fp": c.fp, "fn": c.fn}


def cnn_row(
    frames: Sequence[AnnotatedFrame],
    cache: FrameCache,
    models: Path,
    held: str,
    sort: SortConfig | None = None,
) -> dict:
    """The CNN's detection and tracking rows of held-out video `held` (model trained
    without it; its card's confidence threshold; `sort`: the SORT-like tracker's
    parameters). Adds the detections to `cache`."""
    from usvfast.shore.cnn import CnnDetector

    path = cnn_fold_model(models, held)
    det = CnnDetector(path)
    cache.raw["cnn"] = [det.detect(read_image(f.path, cv2.IMREAD_COLOR)) for f in frames]
    hcfg = HorizonConfig()
    row: dict = {"cnn_model": path.name, "cnn_conf": float(det.grid.conf_threshold)}
    for use_h in (False, True):
        c = count(frames, kept(frames, cache, "cnn", use_h, hcfg))
        row[f"cnn_{'horizon' if use_h else 'no_horizon'}"] = counts_dict(c)
    row["tracking"] = {
        "cnn": tracking_rows(frames, kept(frames, cache, "cnn", True, hcfg), sort=sort),
        "cnn no horizon": tracking_rows(frames, kept(frames, cache, "cnn", False, hcfg), sort=sort),
    }
    return row


class _Suppressed:
    """A detector's boxes after the overlap and containment suppression of
    :mod:`usvfast.shore.suppress` (its shipped IoU and containment)."""

    def __init__(self, det) -> None:
        self.det = det

    def detect(self, image, horizon=None) -> Detections:
        from usvfast.shore.suppress import suppress

        return suppress(self.det.detect(image, horizon))


def ssd_row(
    frames: Sequence[AnnotatedFrame],
    cache: FrameCache,
    models: Path,
    held: str,
    sort: SortConfig | None = None,
) -> dict:
    """The fine-tuned SSD's detection and tracking rows of held-out video `held` (model
    `shore-ssd-without-HELD.onnx` of `models`, its card's threshold; :mod:`usvfast.shore.
    ssd_train`), alone and after the overlap and containment suppression of
    :mod:`usvfast.shore.suppress` (its shipped pair). Adds the detections to `cache`."""
    from usvfast.shore.pretrained import SsdDetector
    from usvfast.shore.ssd_nested import model_name
    from usvfast.shore.suppress import suppress

    path = Path(models) / f"{model_name('default', [held])}.onnx"
    if not path.is_file():
        raise ValueError(
            f"models: no {path.name} in {models} "
            f"(python -m usvfast.shore.evaluate_det --detectors ssd --models {models})"
        )
    det = SsdDetector(path)
    cache.raw["ssd"] = [det.detect(read_image(f.path, cv2.IMREAD_COLOR)) for f in frames]
    cache.raw["ssd-nms"] = [suppress(d) for d in cache.raw["ssd"]]
    hcfg = HorizonConfig()
    row: dict = {"ssd_model": path.name, "ssd_conf": det.conf_threshold, "tracking": {}}
    for key in ("ssd", "ssd-nms"):
        for use_h in (False, True):
            c = count(frames, kept(frames, cache, key, use_h, hcfg))
            row[f"{key}_{'horizon' if use_h else 'no_horizon'}"] = counts_dict(c)
        dets = kept(frames, cache, key, True, hcfg)
        row["tracking"][key] = tracking_rows(frames, dets, sort=sort)
    return row


def cue_row(
    frames: Sequence[AnnotatedFrame],
    cache: FrameCache,
    name: str,
    models: Path | None = None,
    held: str = "",
    sort: SortConfig | None = None,
) -> dict:
    """Detection and tracking rows of the training-free contrast detector (`name`
    'contrast', :mod:`usvfast.shore.contrast`, default parameters), of the temporal change
    detector ('change', :mod:`usvfast.shore.change`, online, default parameters) or of the
    fused CNN +
    contrast score ('fused', :mod:`usvfast.shore.fused`, its default thresholds; the CNN of
    `models` trained without `held`, see :func:`cnn_fold_model`). `sort`: the SORT-like
    tracker's parameters. Adds the detections to `cache` under `name`."""
    from usvfast.shore.contrast import ContrastDetector

    det: object
    row: dict = {}
    if name in ("fused", "fused-nms"):
        from usvfast.shore.cnn import CnnDetector
        from usvfast.shore.fused import FUSED_CNN_FLOOR, FusedDetector

        path = cnn_fold_model(models or Path(), held)
        det = FusedDetector(CnnDetector(path, conf_threshold=FUSED_CNN_FLOOR))
        row["fused_model"] = path.name
        if name == "fused-nms":
            det = _Suppressed(det)
    else:
        det = ContrastDetector()
    if name == "change":
        from usvfast.shore.change import ChangeDetector

        images = [read_image(f.path, cv2.IMREAD_COLOR) for f in frames]
        cache.raw[name] = ChangeDetector().detect_sequence(images, cache.horizon)
    else:
        cache.raw[name] = [
            det.detect(read_image(f.path, cv2.IMREAD_COLOR), hz)  # pyright: ignore[reportAttributeAccessIssue]
            for f, hz in zip(frames, cache.horizon, strict=True)
        ]
    hcfg = HorizonConfig()
    for use_h in (False, True):
        c = count(frames, kept(frames, cache, name, use_h, hcfg))
        row[f"{name}_{'horizon' if use_h else 'no_horizon'}"] = counts_dict(c)
    row["tracking"] = {
        name: tracking_rows(frames, kept(frames, cache, name, True, hcfg), sort=sort),
        f"{name} no horizon": tracking_rows(
            frames, kept(frames, cache, name, False, hcfg), sort=sort
        ),
    }
    return row


def evaluate(
    data: Path,
    grid: Sequence[float] = THRESHOLD_GRID,
    videos: Sequence[str] | None = None,
    cascade: CascadeConfig | None = None,
    detectors: Sequence[str] = ("bayes",),
    models: Path | None = None,
    sort: SortConfig | None = None,
    ssd_recipes: Sequence[str] | None = None,
) -> dict:
    """Leave-one-video-out results per video (module doc); a JSON-ready dict. With `cascade`,
    a Haar cascade is also trained on the three other videos and scored. `detectors`:
    'bayes' and/or 'cnn' (the latter needs `models`, see :func:`cnn_fold_model`). `sort`:
    the SORT-like tracker's parameters in every tracking row (default :class:`SortConfig`);
    `ssd_recipes`: the training recipes 'ssd-nested' compares (default: 'default')."""
    if sort is not None:
        instance("sort", sort, SortConfig)
    known = {"bayes", "cnn", "contrast", "fused", "fused-nms", "change", "ssd", "ssd-nested"}
    unknown = set(detectors) - known
    if unknown or not detectors:
        raise ValueError(f"detectors: expected some of {sorted(known)}, got {list(detectors)}")
    if {"cnn", "fused", "fused-nms", "ssd", "ssd-nested"} & set(detectors) and models is None:
        raise ValueError("models: the cnn detector needs the folder of its fold models")
    if "ssd-nested" in detectors and "bayes" in detectors:
        raise ValueError("detectors: 'ssd-nested' runs without 'bayes'")
    all_videos = load_mardct(data)
    names = list(videos) if videos else list(all_videos)
    hcfg = HorizonConfig()
    results = {}
    shared: dict = {}
    if "bayes" not in detectors:
        for v in names:
            frames = all_videos[v]
            cache = run_detectors(frames, {}, hcfg)
            row = {"frames": len(frames), "boxes": int(sum(len(f.boxes) for f in frames))}
            row["tracking"] = {}
            if "cnn" in detectors:
                extra = cnn_row(frames, cache, models or Path(), v, sort)
                row["tracking"].update(extra.pop("tracking"))
                row.update(extra)
            if "ssd" in detectors:
                extra = ssd_row(frames, cache, models or Path(), v, sort)
                row["tracking"].update(extra.pop("tracking"))
                row.update(extra)
            if "ssd-nested" in detectors:
                from usvfast.shore.ssd_nested_track import evaluate_row

                extra = evaluate_row(data, models or Path(), v, shared, recipes=ssd_recipes)
                row["tracking"].update(extra.pop("tracking"))
                row.update(extra)
            for name in ("contrast", "fused", "fused-nms", "change"):
                if name in detectors:
                    extra = cue_row(frames, cache, name, models, v, sort)
                    row["tracking"].update(extra.pop("tracking"))
                    row.update(extra)
            row["tracking"]["truth boxes"] = tracking_rows(
                frames, truth_detections(frames), sort=sort
            )
            results[v] = row
        return results
    settings = {"paper": BayesDetectorConfig()}
    for thr in grid:
        settings[f"t{thr:g}"] = BayesDetectorConfig(
            thresholds={"eo": float(thr), "ir": 203.0}, grouping="clusters"
        )
    caches = {v: run_detectors(all_videos[v], settings, hcfg) for v in all_videos}
    for v in names:
        train = [u for u in all_videos if u != v]
        scores = {}
        for thr in grid:
            total = DetectionCounts()
            for u in train:
                c = count(all_videos[u], kept(all_videos[u], caches[u], f"t{thr:g}", True, hcfg))
                total.tp, total.fp, total.fn = total.tp + c.tp, total.fp + c.fp, total.fn + c.fn
            scores[thr] = f1(total)
        best = max(grid, key=lambda t: (scores[t], -t))
        frames = all_videos[v]
        row: dict = {"frames": len(frames), "boxes": int(sum(len(f.boxes) for f in frames))}
        row["tuned_threshold"] = float(best)
        for key, label in (("paper", "paper"), (f"t{best:g}", "tuned")):
            for use_h in (False, True):
                c = count(frames, kept(frames, caches[v], key, use_h, hcfg))
                row[f"{label}_{'horizon' if use_h else 'no_horizon'}"] = {
                    "tpr": c.tpr,
                    "far": c.far,
                    "tp": c.tp,
                    "fp": c.fp,
                    "fn": c.fn,
                }
        row["tracking"] = {
            "truth boxes": tracking_rows(frames, truth_detections(frames), sort=sort),
            "bayes": tracking_rows(
                frames, kept(frames, caches[v], f"t{best:g}", True, hcfg), sort=sort
            ),
            "bayes no horizon": tracking_rows(
                frames, kept(frames, caches[v], f"t{best:g}", False, hcfg), sort=sort
            ),
        }
        if cascade:
            t0 = time.perf_counter()
            detector, report = train_detector([f for u in train for f in all_videos[u]], cascade)
            row["cascade_train_s"] = time.perf_counter() - t0
            row["cascade_stages"] = len(report["stages"])
            caches[v].raw["cascade"] = [
                detector.detect(read_image(f.path, cv2.IMREAD_COLOR)) for f in frames
            ]
            for use_h in (False, True):
                c = count(frames, kept(frames, caches[v], "cascade", use_h, hcfg))
                row[f"cascade_{'horizon' if use_h else 'no_horizon'}"] = {
                    "tpr": c.tpr,
                    "far": c.far,
                    "tp": c.tp,
                    "fp": c.fp,
                    "fn": c.fn,
                }
            dets = kept(frames, caches[v], "cascade", True, hcfg)
            row["tracking"]["cascade"] = tracking_rows(frames, dets, sort=sort)
        if "cnn" in detectors:
            extra = cnn_row(frames, caches[v], models or Path(), v, sort)
            row["tracking"].update(extra.pop("tracking"))
            row.update(extra)
        if "ssd" in detectors:
            extra = ssd_row(frames, caches[v], models or Path(), v, sort)
            row["tracking"].update(extra.pop("tracking"))
            row.update(extra)
        results[v] = row
    return results


def print_tables(results: dict, console: Console | None = None) -> None:
    """Tables I–II layout (detection) and Table III layout (tracking)."""
    console = console or Console(width=max(Console().width, 170))
    t = Table(title="Detection (MarDCT, leave one video out, IoU ≥ 0.5)")
    for col in ("video", "detector", "horizon", "TPR", "FAR", "TP", "FP", "FN"):
        t.add_column(col)
    for v, r in results.items():
        rows = []
        if "tuned_threshold" in r:
            rows += [
                ("paper", "bayes 23/203 extent"),
                ("tuned", f"bayes {r['tuned_threshold']:g} clusters"),
            ]
        if "cnn_horizon" in r:
            rows.append(("cnn", f"{r['cnn_model']} (confidence {r['cnn_conf']:g})"))
        if "ssd_horizon" in r:
            name = f"{r['ssd_model']} (confidence {r['ssd_conf']:g})"
            rows += [("ssd", name), ("ssd-nms", f"{name} + suppression")]
        if "ssd-nested_horizon" in r:
            u = r["ssd_nested_setup"]
            rows.append(("ssd-nested", f"ssd nested ({u['recipe']}, {u['view']}, ≥ {u['conf']:g})"))
        if "cascade_horizon" in r:
            rows.append(("cascade", f"cascade ({r['cascade_stages']} stages)"))
        if "contrast_horizon" in r:
            rows.append(("contrast", "contrast (training-free)"))
        if "fused_horizon" in r:
            rows.append(("fused", f"fused ({r['fused_model']} + contrast)"))
        if "fused-nms_horizon" in r:
            rows.append(("fused-nms", f"fused ({r['fused_model']} + contrast) + suppression"))
        if "change_horizon" in r:
            rows.append(("change", "change (online, registered median of the previous frames)"))
        for label, name in rows:
            for h in ("no_horizon", "horizon"):
                s = r[f"{label}_{h}"]
                t.add_row(
                    v,
                    name,
                    "YES" if h == "horizon" else "NO",
                    f"{s['tpr']:.3f}",
                    f"{s['far']:.3f}",
                    str(s["tp"]),
                    str(s["fp"]),
                    str(s["fn"]),
                )
    console.print(t)
    m = Table(title="Tracking (Table III layout; CLEAR MOT with IoU ≥ 0.5)")
    for col in (
        "video",
        "detections",
        "tracker",
        "MOTA",
        "MOTA log10",
        "MOTP (IoU)",
        "precision",
        "recall",
        "FP share",
        "IDF1",
        "HOTA",
        "IDsw",
    ):
        m.add_column(col)
    for v, r in results.items():
        for det, per in r["tracking"].items():
            for tr, s in per.items():
                m.add_row(
                    v,
                    det,
                    tr,
                    *(
                        f"{s[k]:.3f}"
                        for k in (
                            "mota",
                            "mota_log10",
                            "motp_iou",
                            "precision",
                            "recall",
                            "fp_share",
                            "idf1",
                            "hota",
                        )
                    ),
                    str(s["switches"]),
                )
    console.print(m)


def main(argv: Sequence[str] | None = None) -> None:
    """Command-line entry point (module doc)."""
    p = argparse.ArgumentParser(
        prog="python -m usvfast.shore.evaluate", description=(__doc__ or "").partition("\n")[0]
    )
    p.add_argument("--data", type=Path, default=None, help="MarDCT training/annotations folder")
    p.add_argument("--json", type=Path, default=None, help="Write the results as JSON here")
    p.add_argument("--videos", nargs="*", default=None, help="Score only these videos")
    p.add_argument("--no-cascade", action="store_true", help="Skip the cascade detector")
    p.add_argument(
        "--detector",
        nargs="+",
        default=["bayes"],
        choices=["bayes", "cnn", "contrast", "fused", "fused-nms", "change", "ssd", "ssd-nested"],
        help="Detectors",
    )
    p.add_argument("--models", type=Path, default=None, help="CNN fold models (evaluate_det)")
    p.add_argument(
        "--sort-high-score",
        type=float,
        default=SortConfig.high_score,
        help="SORT two-stage association (ByteTrack): score from which a detection is "
        "associated first and may start a track (0: one stage, the default)",
    )
    p.add_argument(
        "--sort-low-score",
        type=float,
        default=SortConfig.low_score,
        help="SORT two-stage association: least score of a second-stage detection "
        "(at most --sort-high-score)",
    )
    p.add_argument(
        "--ssd-recipes",
        nargs="*",
        default=None,
        help="ssd-nested: training recipes compared: default (the default) and/or deep",
    )
    a = p.parse_args(argv)
    if {"cnn", "fused", "fused-nms", "ssd", "ssd-nested"} & set(a.detector) and a.models is None:
        p.error("--models: the cnn, fused and ssd detectors need the folder of their fold models")
    try:
        sort = sort_config_from_options(a.sort_high_score, a.sort_low_score)
    except ValueError as exc:
        p.error(str(exc))
    cascade = None if a.no_cascade or "bayes" not in a.detector else CascadeConfig()
    results = evaluate(
        a.data or default_data(),
        videos=a.videos,
        cascade=cascade,
        detectors=a.detector,
        models=a.models,
        sort=sort,
        ssd_recipes=a.ssd_recipes,
    )
    print_tables(results)
    if a.json:
        a.json.write_text(json.dumps(results, indent=2, default=float), encoding="utf-8")


if __name__ == "__main__":
    main()
