"""Nested (inner leave-one-video-out) choice of the fine-tuned SSD's set-up for a held-out
video, so that no choice looks at that video's scores.

For held-out video H among the annotated videos V: every training recipe compared
(:data:`DEFAULT_RECIPES`, or any of :data:`RECIPES`) is fine-tuned on V − {H, W} for each
other video W (`PREFIX-without-A+B.onnx` in the models folder, trained when absent) and run
on W, a video it has not seen. The set-up (recipe, test-time views of
:mod:`usvfast.shore.ssd_tta`, confidence threshold, overlap and containment suppression of
:mod:`usvfast.shore.suppress`) with the highest pooled TPR at FAR ≤ 0.15 on those W (horizon
filter on; :func:`usvfast.shore.det_scoring.pick`, ties: the lower FAR, then the first in
grid order) is then applied to the recipe's model trained on V − {H}
(`PREFIX-without-H.onnx`) and H is scored. Every threshold is thus chosen on frames the
model that is scored there never saw, unlike the card's threshold (picked on the training
frames).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usvfast.shore.boxes import Detections
from usvfast.shore.det_scoring import VideoFrames, pick, score
from usvfast.shore.horizon import HorizonConfig
from usvfast.shore.pretrained import suppressed
from usvfast.shore.suppress import suppress

#: Training recipes compared: name -> (model-file prefix, `SsdTrainConfig` overrides).
RECIPES: dict[str, tuple[str, dict]] = {
    "default": ("shore-ssd", {}),
    "deep": ("shore-ssd-deep", {"unfrozen_before_tap": 7}),
}
#: Recipes compared unless told otherwise (each recipe costs 3 inner models per held-out video).
DEFAULT_RECIPES: tuple[str, ...] = ("default",)
#: Test-time views (:class:`usvfast.shore.ssd_tta.SsdTta`): name -> (flip, zoom).
VIEWS: dict[str, tuple[bool, float]] = {
    "plain": (False, 1.0),
    "flip": (True, 1.0),
    "zoom1.5": (False, 1.5),
    "flip+zoom1.5": (True, 1.5),
}
#: Confidence thresholds tried.
CONF_GRID: tuple[float, ...] = (0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8)
#: Lowest score kept in the cached candidates (below every grid value).
CANDIDATE_FLOOR = 0.05


@dataclass(frozen=True)
class SsdSetup:
    """A fine-tuned SSD's set-up: training `recipe` (:data:`RECIPES`), test-time `view`
    (:data:`VIEWS`), confidence threshold `conf` and whether the shipped suppression runs."""

    recipe: str = "default"
    view: str = "plain"
    conf: float = 0.2
    suppression: bool = False

    def __post_init__(self) -> None:
        if self.recipe not in RECIPES:
            raise ValueError(f"recipe: expected one of {sorted(RECIPES)}, got {self.recipe!r}")
        if self.view not in VIEWS:
            raise ValueError(f"view: expected one of {sorted(VIEWS)}, got {self.view!r}")
        if not 0.0 < self.conf < 1.0:
            raise ValueError(f"conf: expected in (0, 1), got {self.conf}")


def model_name(recipe: str, excluded: Sequence[str]) -> str:
    """File stem of `recipe`'s model trained without the videos `excluded` (sorted)."""
    if recipe not in RECIPES:
        raise ValueError(f"recipe: expected one of {sorted(RECIPES)}, got {recipe!r}")
    if not excluded:
        raise ValueError("excluded: at least one video expected")
    return f"{RECIPES[recipe][0]}-without-{'+'.join(sorted(excluded))}"


def fold_model(
    data: Path, models: Path, recipe: str, excluded: Sequence[str], log: Callable = print
) -> Path:
    """`recipe`'s model trained without `excluded` (trained and saved when absent)."""
    from usvfast.shore.ssd_train import SsdTrainConfig, train_and_export

    name = model_name(recipe, excluded)
    path = Path(models) / f"{name}.onnx"
    if not path.is_file():
        cfg = SsdTrainConfig(**RECIPES[recipe][1])
        train_and_export(data, models, cfg, exclude=list(excluded), name=name, log=log)
    return path


#: The views a candidate cache holds per frame.
CACHED_VIEWS: tuple[str, ...] = ("frame", "mirror", "zoom1.5")


class CandidateCache:
    """Per-frame candidates of every test-time view of a model on a video (computed once):
    `get(model, video_name, video)` -> list over frames of {"frame", "mirror", "zoom1.5"}
    -> (corners (n, 4) x1, y1, x2, y2 px, scores (n,)) above :data:`CANDIDATE_FLOOR`. With
    `folder`, they are also kept there as `MODEL.VIDEO.candidates.npz` (read back when newer
    than the model)."""

    def __init__(self, folder: Path | None = None) -> None:
        self.folder = None if folder is None else Path(folder)
        self._raw: dict[tuple[str, str], list[dict]] = {}
        self._merged: dict[tuple[str, str, str], list[Detections]] = {}

    def _file(self, model: Path, name: str) -> Path | None:
        if self.folder is None:
            return None
        return self.folder / f"{Path(model).stem}.{name}.candidates.npz"

    def get(self, model: Path, name: str, video: VideoFrames) -> list[dict]:
        """The candidates of `model` on `video` (named `name`)."""
        key = (str(model), name)
        if key in self._raw:
            return self._raw[key]
        f = self._file(model, name)
        if f is not None and f.is_file() and f.stat().st_mtime >= Path(model).stat().st_mtime:
            with np.load(f, allow_pickle=False) as z:
                out: list[dict] = [{} for _ in video.images]
                for v in CACHED_VIEWS:
                    cut = np.cumsum(z[f"{v}_counts"])[:-1]
                    boxes = np.split(z[f"{v}_boxes"], cut)
                    scores = np.split(z[f"{v}_scores"], cut)
                    for i, (b, sc) in enumerate(zip(boxes, scores, strict=True)):
                        out[i][v] = (b.reshape(-1, 4), sc)
            self._raw[key] = out
            return out
        out = self._compute(model, video)
        self._raw[key] = out
        if f is not None:
            f.parent.mkdir(parents=True, exist_ok=True)
            arrays = {}
            for v in CACHED_VIEWS:
                arrays[f"{v}_boxes"] = np.concatenate([fr[v][0].reshape(-1, 4) for fr in out])
                arrays[f"{v}_scores"] = np.concatenate([fr[v][1] for fr in out])
                arrays[f"{v}_counts"] = np.array([len(fr[v][1]) for fr in out], np.int64)
            np.savez(f, **arrays)
        return out

    @staticmethod
    def _compute(model: Path, video: VideoFrames) -> list[dict]:
        from usvfast.shore.pretrained import SsdDetector
        from usvfast.shore.ssd_tta import SsdTta

        det = SsdDetector(model, conf_threshold=CANDIDATE_FLOOR)
        out = []
        for im in video.images:
            a = SsdTta(det, flip=True, zoom=1.5).views(im)
            out.append({"frame": a["frame"], "mirror": a["mirror"], "zoom1.5": a["tiles"]})
        return out

    def detections(self, model: Path, name: str, video: VideoFrames, view: str, iou: float):
        """Per-frame detections of `view`: the views' candidates pooled, one NMS at `iou`."""
        key = (str(model), name, view)
        if key not in self._merged:
            flip, zoom = VIEWS[view]
            parts = ["frame", *(["mirror"] if flip else [])]
            parts += [f"zoom{zoom:g}"] if zoom > 1 else []
            out = []
            for fr in self.get(model, name, video):
                b = np.concatenate([fr[p][0].reshape(-1, 4) for p in parts])
                s = np.concatenate([fr[p][1] for p in parts]).astype(float)
                out.append(suppressed(b, s, iou, 100))
            self._merged[key] = out
        return self._merged[key]


def setup_detections(
    cache: CandidateCache, model: Path, name: str, video: VideoFrames, setup: SsdSetup
) -> list[Detections]:
    """Per-frame detections of `model` on `video` under `setup` (before the horizon filter)."""
    from usvfast.shore.pretrained import COCO_NMS_IOU

    dets = cache.detections(model, name, video, setup.view, COCO_NMS_IOU)
    dets = [d.subset(d.scores >= setup.conf) for d in dets]
    return [suppress(d) for d in dets] if setup.suppression else dets


def grid(recipes: Sequence[str] | None = None) -> list[SsdSetup]:
    """Every set-up tried, in order (recipe, view, threshold, suppression off then on)."""
    recipes = DEFAULT_RECIPES if recipes is None else tuple(recipes)
    return [
        SsdSetup(r, v, c, s)
        for r, v, c, s in itertools.product(recipes, VIEWS, CONF_GRID, (False, True))
    ]


def nested_choice(
    data: Path,
    models: Path,
    videos: dict[str, VideoFrames],
    held: str,
    hcfg: HorizonConfig,
    cache: CandidateCache,
    recipes: Sequence[str] | None = None,
    log: Callable = print,
) -> tuple[SsdSetup, dict]:
    """The set-up picked for held-out `held` by inner leave-one-video-out on the other videos
    (module doc), and its pooled inner TP, FP, FN. `recipes`: those compared (default
    :data:`DEFAULT_RECIPES`)."""
    recipes = DEFAULT_RECIPES if recipes is None else tuple(recipes)
    if not recipes or any(r not in RECIPES for r in recipes):
        raise ValueError(f"recipes: expected some of {sorted(RECIPES)}, got {list(recipes)}")
    inner = [v for v in videos if v != held]
    if len(inner) < 2:
        raise ValueError(f"videos: at least 3 videos expected, got {len(videos)}")
    paths = {(r, w): fold_model(data, models, r, [held, w], log) for r in recipes for w in inner}

    def pooled(s: object) -> dict:
        assert isinstance(s, SsdSetup)
        tot = {"tp": 0, "fp": 0, "fn": 0}
        for w in inner:
            d = setup_detections(cache, paths[(s.recipe, w)], w, videos[w], s)
            r = score(videos[w], d, hcfg, True)
            tot = {k: tot[k] + r[k] for k in tot}
        return tot

    best = pick(grid(recipes), pooled, low_far_ties=True)
    assert isinstance(best, SsdSetup)
    return best, pooled(best)
