"""Nested choice of the tracker set-up on the fine-tuned SSD's boxes (:mod:`usvfast.shore.
ssd_nested`), so that no choice looks at the held-out video.

For held-out video H: the recipe and test-time views are those
:func:`usvfast.shore.ssd_nested.nested_choice` picked; every confidence threshold of its grid,
with and without the suppression, together with every tracker setting of :data:`SORT_GRID`
(the SORT-like tracker of :mod:`usvfast.shore.sort`, with and without ByteTrack's two-stage
association) or of :data:`PARTICLE_GRID` (:mod:`usvfast.shore.particle`) runs on each other
video W with the boxes of the model trained without H and W (horizon filter on), and the
combination with the highest pooled MOTA on those W (errors summed over the videos over
their boxes; ties: the first, the lowest threshold and the trackers' defaults come first;
MOTA weighs a miss and a false box alike, unlike the detection pick's TPR at FAR ≤ 0.15) is
run on H with the boxes of the model trained without H. Scores:
:func:`usvfast.shore.mot_eval.mot_scores` (CLEAR MOT at IoU ≥ 0.5).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, replace
from pathlib import Path

from usvfast.shore.boxes import Detections
from usvfast.shore.det_scoring import VideoFrames
from usvfast.shore.horizon import HorizonConfig, horizon_keep
from usvfast.shore.mot_eval import mot_scores, run_tracker
from usvfast.shore.particle import ParticleConfig
from usvfast.shore.sort import SortConfig
from usvfast.shore.ssd_nested import (
    CONF_GRID,
    CandidateCache,
    SsdSetup,
    fold_model,
    nested_choice,
    setup_detections,
)

#: Score floor of the second-stage (low-score) detections when two-stage association is on.
LOW_SCORE = 0.1
#: SORT settings tried: (two-stage, min_hits, max_age, iou_threshold); the default first.
SORT_GRID: tuple[tuple[bool, int, int, float], ...] = tuple(
    (two, hits, age, iou)
    for two in (False, True)
    for hits in (2, 1)
    for age in (3, 6)
    for iou in (0.3, 0.1)
)
#: Particle settings tried: (confirm_hits, max_age); the default first.
PARTICLE_GRID: tuple[tuple[int, int], ...] = ((2, 3), (2, 6), (1, 3), (1, 6))


def sort_config(setting: tuple[bool, int, int, float], conf: float) -> SortConfig:
    """The SortConfig of a :data:`SORT_GRID` setting for detections thresholded at `conf`
    (two-stage: `conf` is the first stage's score, :data:`LOW_SCORE` the second's floor)."""
    two, hits, age, iou = setting
    kw: dict = {"min_hits": hits, "max_age": age, "iou_threshold": iou}
    if two:
        kw.update(high_score=conf, low_score=min(LOW_SCORE, conf))
    return SortConfig(**kw)


def _horizon(video: VideoFrames, dets: Sequence[Detections], hcfg: HorizonConfig) -> list:
    return [
        d.subset(horizon_keep(d, hz, im.shape[0], hcfg))
        for d, hz, im in zip(dets, video.horizons, video.images, strict=True)
    ]


def run(
    video: VideoFrames, dets: Sequence[Detections], tracker: SortConfig | ParticleConfig
) -> dict:
    """mot_scores of a SortConfig or ParticleConfig `tracker` over a video's detections."""
    return mot_scores(video.frames, track(video, dets, tracker))


def track(
    video: VideoFrames, dets: Sequence[Detections], tracker: SortConfig | ParticleConfig
) -> tuple:
    """(frame numbers from 1, ids, boxes (n, 4) px) of a SortConfig or ParticleConfig
    `tracker` over a video's detections (:func:`usvfast.shore.mot_eval.run_tracker`)."""
    if isinstance(tracker, SortConfig):
        return run_tracker(video.frames, dets, "sort", video.images, sort=tracker)
    return run_tracker(video.frames, dets, "particle", video.images, particle=tracker)


def _make(tracker: str, setting: tuple, setup: SsdSetup) -> SortConfig | ParticleConfig:
    """The tracker config of a grid `setting`."""
    if tracker == "sort":
        return sort_config(setting, setup.conf)
    return replace(ParticleConfig(), confirm_hits=setting[0], max_age=setting[1])


def _floor(tracker: str, setting: tuple, setup: SsdSetup) -> float:
    """Least detection score a tracker setting is given (lower for two-stage SORT)."""
    return min(LOW_SCORE, setup.conf) if tracker == "sort" and setting[0] else setup.conf


def pooled_mota(rows: Sequence[dict]) -> float:
    """1 − (misses + false positives + switches) / boxes, summed over videos."""
    errors = sum(r["misses"] + r["false_positives"] + r["switches"] for r in rows)
    return 1.0 - errors / max(sum(r["n_truth"] for r in rows), 1)


def nested_tracking(
    data: Path,
    models: Path,
    videos: dict[str, VideoFrames],
    held: str,
    hcfg: HorizonConfig,
    cache: CandidateCache,
    setup: SsdSetup | None = None,
    log: Callable = print,
    recipes: Sequence[str] | None = None,
) -> dict:
    """Per tracker ('sort', 'particle'): the setting, confidence threshold and suppression
    picked together on the other videos (module doc), its pooled inner MOTA, and its
    mot_scores on `held`; also 'setup', the detection set-up whose recipe and views are kept
    (`setup`, else :func:`usvfast.shore.ssd_nested.nested_choice` among `recipes`)."""
    if setup is None:
        setup, _ = nested_choice(data, models, videos, held, hcfg, cache, recipes, log)
    inner = [v for v in videos if v != held]

    def boxes(video: str, excluded: list[str], floor: float, d: SsdSetup) -> list[Detections]:
        path = fold_model(data, models, d.recipe, excluded, log)
        found = setup_detections(cache, path, video, videos[video], replace(d, conf=floor))
        return _horizon(videos[video], found, hcfg)

    out: dict = {"setup": asdict(setup)}
    dets = [replace(setup, conf=c, suppression=s) for c in CONF_GRID for s in (False, True)]
    for name, grid in (("sort", SORT_GRID), ("particle", PARTICLE_GRID)):
        scored = []
        for d in dets:
            for g in grid:
                rows = [
                    run(videos[w], boxes(w, [held, w], _floor(name, g, d), d), _make(name, g, d))
                    for w in inner
                ]
                scored.append((pooled_mota(rows), d, g))
        best_m = max(m for m, _, _ in scored)
        _, d, best = next(x for x in scored if x[0] == best_m)
        found = boxes(held, [held], _floor(name, best, d), d)
        outer = run(videos[held], found, _make(name, best, d))
        out[name] = {
            "setting": list(best),
            "conf": d.conf,
            "suppression": d.suppression,
            "inner_mota": best_m,
            "scores": outer,
        }
    return out


def evaluate_row(
    data: Path,
    models: Path,
    held: str,
    shared: dict,
    log: Callable = print,
    recipes: Sequence[str] | None = None,
) -> dict:
    """The `python -m usvfast.shore.evaluate --detector ssd-nested` row of `held`: detection
    counts of the nested set-up (horizon off and on) and the nested trackers' scores.
    `shared` keeps the videos and candidates between held-out videos; `recipes`: those
    compared (default every one)."""
    from usvfast.shore.det_scoring import load_video, score
    from usvfast.shore.mardct import load_mardct

    hcfg = HorizonConfig()
    if "videos" not in shared:
        shared["videos"] = {v: load_video(f, hcfg) for v, f in load_mardct(data).items()}
        shared["cache"] = CandidateCache(Path(models) / "candidates")
    videos, cache = shared["videos"], shared["cache"]
    setup, _ = nested_choice(data, models, videos, held, hcfg, cache, recipes, log)
    tr = nested_tracking(data, models, videos, held, hcfg, cache, setup, log)
    path = fold_model(data, models, setup.recipe, [held], log)
    dets = setup_detections(cache, path, held, videos[held], setup)
    row: dict = {"ssd_nested_setup": asdict(setup)}
    for use_h in (False, True):
        s = score(videos[held], dets, hcfg, use_h)
        row[f"ssd-nested_{'horizon' if use_h else 'no_horizon'}"] = {
            k: s[k] for k in ("tpr", "far", "tp", "fp", "fn")
        }
    row["tracking"] = {}
    for name in ("sort", "particle"):
        t = tr[name]
        label = f"ssd nested ({setup.recipe}, {setup.view}, ≥ {t['conf']:g}" + (
            ", suppression)" if t["suppression"] else ")"
        )
        row["tracking"][f"{label}, {name} {tuple(t['setting'])}"] = {name: t["scores"]}
    row["ssd_nested_inner_mota"] = {k: tr[k]["inner_mota"] for k in ("sort", "particle")}
    return row
