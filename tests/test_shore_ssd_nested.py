"""Nested (inner leave-one-video-out) choice of the fine-tuned SSD's set-up and of the
trackers' settings (usvfast.shore.ssd_nested, ssd_nested_track), on four synthetic videos
whose "models" are stand-ins with known behaviour: no model is ever run on a video it was
trained on, the held-out video is never looked at while choosing, the choice is the one the
stand-ins' design makes best (worked out by hand below), the pooled inner MOTA equals the
figure recomputed from py-motmetrics, and bad input raises."""

from __future__ import annotations

from pathlib import Path

import motmetrics as mm
import numpy as np
import pytest

from usvfast.shore.det_scoring import VideoFrames
from usvfast.shore.horizon import HorizonConfig
from usvfast.shore.mardct import AnnotatedFrame
from usvfast.shore.ssd_nested import (
    RECIPES,
    CandidateCache,
    SsdSetup,
    model_name,
    nested_choice,
)
from usvfast.shore.ssd_nested_track import SORT_GRID, nested_tracking, pooled_mota, track

VIDEOS = ("a", "b", "c", "d")
BOX = np.array([60.0, 40.0, 30.0, 16.0])  # x, y, w, h px; moves 4 px right per frame
FRAMES = 8
FALSE_BOX = np.array([[5.0, 5.0, 9.0, 9.0]])


def _video(name: str, rng: np.random.Generator) -> VideoFrames:
    frames = [
        AnnotatedFrame(name, i, Path(f"{name}_{i}.png"), (BOX + np.array([4.0 * i, 0, 0, 0]))[None])
        for i in range(FRAMES)
    ]
    images = [rng.integers(0, 255, (120, 200, 3), dtype=np.uint8) for _ in frames]
    return VideoFrames(frames, images, [None] * FRAMES)


def _excluded(model: str) -> set[str]:
    return set(Path(model).stem.rsplit("-without-", 1)[1].split("+"))


class StandInCache(CandidateCache):
    """Candidates of stand-in models, by design: a 'deep' model finds the boat in every frame
    (score 0.9) plus a false box (score 0.35); a 'default' model finds it in even frames
    only (0.9). On the held-out video `twist` the roles swap (which must not matter)."""

    def __init__(self, twist: str) -> None:
        super().__init__()
        self.twist = twist
        self.calls: list[tuple[str, str]] = []

    def get(self, model, name, video):
        self.calls.append((Path(model).stem, name))
        deep = Path(model).stem.startswith(RECIPES["deep"][0] + "-")
        if name == self.twist:
            deep = not deep
        out = []
        for f in video.frames:
            b, s = np.zeros((0, 4)), np.zeros(0)
            truth = np.concatenate([f.boxes[:, :2], f.boxes[:, :2] + f.boxes[:, 2:]], axis=1)
            if deep or f.index % 2 == 0:
                b, s = truth, np.array([0.9])
            if deep:
                b = np.concatenate([b, [[150.0, 90.0, 170.0, 100.0]]])
                s = np.append(s, 0.35)
            empty = (np.zeros((0, 4)), np.zeros(0))
            out.append({"frame": (b, s), "mirror": empty, "zoom1.5": empty})
        return out


@pytest.fixture()
def world(tmp_path):
    rng = np.random.default_rng(0)
    videos = {v: _video(v, rng) for v in VIDEOS}
    for r in RECIPES:
        for i, v in enumerate(VIDEOS):
            (tmp_path / f"{model_name(r, [v])}.onnx").write_bytes(b"")
            for w in VIDEOS[i + 1 :]:
                (tmp_path / f"{model_name(r, [v, w])}.onnx").write_bytes(b"")
    return videos, tmp_path


def test_the_choice_never_sees_the_held_out_video_and_is_the_designed_best(world):
    videos, models = world
    held = "c"
    cache = StandInCache(twist=held)
    setup, inner = nested_choice(
        Path("unused"), models, videos, held, HorizonConfig(), cache, ("default", "deep")
    )
    for stem, video in cache.calls:
        assert video != held
        assert video in _excluded(stem) and held in _excluded(stem)  # never a training video
    # deep: TPR 1, FAR 0.5 below 0.35 and 0 from 0.4 up; default: TPR 0.5. Highest TPR at
    # FAR <= 0.15 is deep from 0.4; equal TPRs and FARs keep the first in grid order.
    assert setup == SsdSetup("deep", "plain", 0.4, False)
    assert inner == {"tp": 3 * FRAMES, "fp": 0, "fn": 0}


def test_the_tracker_choice_never_sees_the_held_out_video(world):
    videos, models = world
    held = "b"
    cache = StandInCache(twist=held)
    out = nested_tracking(
        Path("unused"), models, videos, held, HorizonConfig(), cache, recipes=("default", "deep")
    )
    held_calls = [stem for stem, v in cache.calls if v == held]
    assert set(held_calls) == {model_name(out["setup"]["recipe"], [held])}  # the outer model
    for stem, video in cache.calls:
        assert video in _excluded(stem)
    assert tuple(out["sort"]["setting"]) in SORT_GRID
    assert out["sort"]["inner_mota"] == pytest.approx(1.0)  # clean boxes, one boat
    # the outer run is on the swapped (default-like) boxes: every other frame missed
    assert out["sort"]["scores"]["recall"] < 1.0


def test_pooled_mota_is_py_motmetrics_over_the_concatenated_videos(world):
    videos, _ = world
    from trackeval.datasets._base_dataset import _BaseDataset

    from usvfast.shore.boxes import Detections
    from usvfast.shore.mot_eval import derive_truth_ids, mot_scores
    from usvfast.shore.sort import SortConfig

    rows, acc, offset = [], mm.MOTAccumulator(auto_id=True), 0
    for k, v in enumerate(("a", "d")):
        frames = videos[v].frames
        dets = [  # a missed frame in three, a false box in video d
            Detections(
                np.concatenate([f.boxes + np.array([k * 3.0, 0, 0, 0]), FALSE_BOX[:k]]),
                np.array([0.9, 0.8][: 1 + k]),
                np.array([-1, -1][: 1 + k]),
            )
            if f.index % 3
            else Detections()
            for f in frames
        ]
        tracks = track(videos[v], dets, SortConfig(min_hits=1))
        rows.append(mot_scores(frames, tracks))
        tf, ti, tb = tracks
        for n, (f, gid) in enumerate(zip(frames, derive_truth_ids(frames), strict=True), 1):
            hyp = tb[tf == n]
            # TrackEval's IoU (py-motmetrics' iou_matrix needs numpy < 2)
            d = 1 - _BaseDataset._calculate_box_ious(f.boxes, hyp, box_format="xywh")
            d[d > 0.5] = np.nan
            acc.update(list(gid + offset), list(ti[tf == n] + offset), d)
        offset += 1000
    m = mm.metrics.create().compute(acc, metrics=["mota"], name="all")
    assert pooled_mota(rows) == pytest.approx(float(m["mota"].iloc[0]), abs=1e-12)
    assert pooled_mota(rows) < 1.0  # the misses and the false box count


def test_bad_input_raises(world):
    videos, models = world
    with pytest.raises(ValueError, match="recipe"):
        SsdSetup(recipe="deeper")
    with pytest.raises(ValueError, match="view"):
        SsdSetup(view="zoom9")
    with pytest.raises(ValueError, match="conf"):
        SsdSetup(conf=1.0)
    with pytest.raises(ValueError, match="excluded"):
        model_name("default", [])
    with pytest.raises(ValueError, match="recipes"):
        nested_choice(Path("x"), models, videos, "a", HorizonConfig(), CandidateCache(), ["no"])
    two = {v: videos[v] for v in ("a", "b")}
    with pytest.raises(ValueError, match="videos"):
        nested_choice(Path("x"), models, two, "a", HorizonConfig(), CandidateCache())


def test_the_candidate_cache_reads_back_what_it_wrote(world, tmp_path, monkeypatch):
    videos, models = world
    model = models / f"{model_name('default', ['a'])}.onnx"
    made = StandInCache(twist="none").get(model, "a", videos["a"])
    calls = []

    def compute(m, v):
        calls.append(m)
        return made

    monkeypatch.setattr(CandidateCache, "_compute", staticmethod(compute))
    first = CandidateCache(tmp_path / "cache").get(model, "a", videos["a"])
    again = CandidateCache(tmp_path / "cache").get(model, "a", videos["a"])  # from disk
    assert len(calls) == 1
    for x, y in zip(first, again, strict=True):
        assert x.keys() == y.keys()
        for k in x:
            np.testing.assert_array_equal(x[k][0].reshape(-1, 4), y[k][0])
            np.testing.assert_array_equal(x[k][1], y[k][1])


def test_the_evaluation_refuses_ssd_nested_beside_bayes(tmp_path):
    from usvfast.shore.evaluate import evaluate

    with pytest.raises(ValueError, match="ssd-nested"):
        evaluate(tmp_path, detectors=["bayes", "ssd-nested"], models=tmp_path)
