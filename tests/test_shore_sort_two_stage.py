"""Two-stage (ByteTrack) association of the shore SORT-like tracker: low-score detections keep
tracks alive but never start one; the defaults are the one-stage tracker; bad values raise."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from usvfast.cli import app
from usvfast.shore.boxes import Detections, iou_matrix
from usvfast.shore.evaluate import main as evaluate_main
from usvfast.shore.pipeline import ShoreConfig
from usvfast.shore.sort import SortConfig, SortTracker


def _frame(boxes: np.ndarray) -> np.ndarray:
    """A grey 320 × 240 frame with a red hull in every box."""
    img = np.full((240, 320, 3), 90, np.uint8)
    for x, y, w, h in boxes.astype(int):
        img[y : y + h, x : x + w] = (0, 0, 255)
    return img


def _run(config: SortConfig | None, frames) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    tracker = SortTracker(config)
    return [tracker.step(img, d) for img, d in frames]


def _fading_boat(n: int = 14, faded: range = range(4, 10)):
    """One boat moving right 5 px per frame; its detector score is 0.9, except 0.3 in the
    `faded` frames (a glare, a wake)."""
    out = []
    for k in range(n):
        box = np.array([[30.0 + 5 * k, 100, 40, 20]])
        score = 0.3 if k in faded else 0.9
        out.append((_frame(box), box, score))
    return out


def test_low_score_detections_keep_the_track_the_one_stage_tracker_loses():
    boat = _fading_boat()
    cfg = SortConfig(high_score=0.5, low_score=0.1)
    assert cfg.two_stage
    # a one-stage tracker behind a detector thresholded at 0.5 sees nothing while faded
    one = _run(
        None,
        [(img, Detections(b, np.array([s])) if s >= 0.5 else Detections()) for img, b, s in boat],
    )
    two = _run(cfg, [(img, Detections(b, np.array([s]))) for img, b, s in boat])
    one_ids = {int(i) for ids, _, _ in one for i in ids}
    two_ids = {int(i) for ids, _, _ in two for i in ids}
    assert len(one_ids) == 2  # lost after max_age unseen frames, a new id on return
    assert len(two_ids) == 1  # one track throughout
    for k, ((ids, out, scores), (_, truth, s)) in enumerate(zip(two, boat, strict=True)):
        assert len(ids) == 1, k  # reported in the faded frames too
        assert iou_matrix(out, truth)[0, 0] > 0.7
        assert scores[0] == pytest.approx(s)
    assert all(len(ids) == 0 for ids, _, _ in one[4:10])


def test_a_low_score_detection_never_starts_a_track():
    cfg = SortConfig(high_score=0.6, low_score=0.1)
    tracker = SortTracker(cfg)
    for k in range(8):
        boat = np.array([[30.0 + 5 * k, 60, 40, 20]])  # a tracked boat (high score)
        ghost = np.array([[200.0, 170, 50, 25]])  # a steady low-score box elsewhere
        boxes = np.vstack([boat, ghost])
        ids, out, _ = tracker.step(_frame(boxes), Detections(boxes, np.array([0.9, 0.4])))
        assert len(tracker.tracks) == 1
        assert len(ids) <= 1
        if len(ids):
            assert iou_matrix(out, boat)[0, 0] > 0.7
    # only low-score boxes from the first frame: nothing at all
    tracker = SortTracker(cfg)
    for _ in range(6):
        box = np.array([[100.0, 100, 40, 20]])
        ids, _, _ = tracker.step(_frame(box), Detections(box, np.array([0.59])))
        assert len(ids) == 0 and not tracker.tracks


def _cluttered_sequence(seed: int = 3, n: int = 40):
    """Three boats crossing, missed detections and random clutter, random scores."""
    rng = np.random.default_rng(seed)
    starts = np.array([[20.0, 40], [280, 120], [60, 190]])
    vel = np.array([[4.0, 0.5], [-5, 0], [3, -1]])
    frames = []
    for k in range(n):
        boats = np.column_stack([starts + k * vel, np.tile([36.0, 18], (3, 1))])
        boats = boats[rng.random(3) > 0.2]  # missed detections
        jitter = rng.normal(0, 1.5, boats.shape) * [1, 1, 0.5, 0.5]
        clutter = np.column_stack(
            [rng.uniform(0, 280, (2, 2)), rng.uniform(10, 40, (2, 1)), rng.uniform(8, 20, (2, 1))]
        )[: rng.integers(0, 3)]
        boxes = np.vstack([boats + jitter, clutter])
        scores = rng.uniform(0.2, 1.0, len(boxes))
        frames.append((_frame(boats), Detections(boxes, scores, np.full(len(boxes), -1))))
    return frames


def _same(a, b) -> None:
    assert len(a) == len(b)
    for (ia, ba, sa), (ib, bb, sb) in zip(a, b, strict=True):
        np.testing.assert_array_equal(ia, ib)
        np.testing.assert_array_equal(ba, bb)
        np.testing.assert_array_equal(sa, sb)


def test_defaults_are_the_one_stage_tracker():
    frames = _cluttered_sequence()
    default = _run(None, frames)
    assert not SortConfig().two_stage
    assert len({int(i) for ids, _, _ in default for i in ids}) >= 3
    # every score is ≥ 0.2: a split at 0.2 leaves no low-score box, so the two-stage code
    # path must give exactly the one-stage tracks
    _same(default, _run(SortConfig(high_score=0.2, low_score=0.2), frames))
    _same(default, _run(SortConfig(high_score=0.2, low_score=0.0), frames))
    _same(default, _run(SortConfig(high_score=0.0, low_score=0.0), frames))
    # a score threshold equals a one-stage run on the thresholded detections
    kept = [(img, d.subset(d.scores >= 0.5)) for img, d in frames]
    _same(_run(None, kept), _run(SortConfig(high_score=0.5, low_score=0.5), frames))
    # and the second stage does change this sequence (the comparison above can fail)
    two = _run(SortConfig(high_score=0.5, low_score=0.2), frames)
    assert sum(len(i) for i, _, _ in two) > sum(len(i) for i, _, _ in _run(None, kept))


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"high_score": 0.2, "low_score": 0.5}, "low_score"),
        ({"high_score": -0.1}, "high_score"),
        ({"high_score": 0.5, "low_score": -0.1}, "low_score"),
        ({"high_score": math.nan}, "high_score"),
        ({"high_score": 0.5, "low_score": math.nan}, "low_score"),
        ({"high_score": 1.5}, "high_score"),
        ({"low_iou_threshold": math.inf}, "low_iou_threshold"),
    ],
)
def test_bad_two_stage_values_raise_naming_the_field(kwargs, name):
    with pytest.raises(ValueError, match=f"^{name}:"):
        SortConfig(**kwargs)


def test_bad_types_raise():
    with pytest.raises(TypeError, match=r"^high_score:"):
        SortConfig(high_score="0.5")  # pyright: ignore[reportArgumentType]
    with pytest.raises(TypeError, match=r"^sort:"):
        ShoreConfig(detector="bayes", sort=0.5)  # pyright: ignore[reportArgumentType]


def test_evaluate_cli_rejects_bad_scores(capsys):
    for args, flag in (
        (["--sort-high-score", "0.2", "--sort-low-score", "0.5"], "--sort-low-score"),
        (["--sort-high-score", "nan"], "--sort-high-score"),
        (["--sort-high-score", "-1"], "--sort-high-score"),
    ):
        with pytest.raises(SystemExit):
            evaluate_main(["--data", "/nonexistent", *args])
        assert flag in capsys.readouterr().err


def test_shore_cli_rejects_bad_scores(tmp_path):
    for args, flag in (
        (["--sort-high-score", "0.2", "--sort-low-score", "0.5"], "--sort-low-score"),
        (["--sort-high-score", "nan"], "--sort-high-score"),
        (["--sort-low-score", "-0.5"], "--sort-low-score"),
    ):
        out = str(tmp_path / "o")
        res = CliRunner().invoke(
            app, ["shore", str(tmp_path), "--out", out, "--detector", "bayes", *args]
        )
        assert res.exit_code != 0
        assert flag in res.output


def test_the_evaluation_passes_the_sort_config_on(mardct_annotations):
    from usvfast.shore.evaluate import evaluate
    from usvfast.shore.mardct import load_mardct
    from usvfast.shore.mot_eval import run_tracker, truth_detections

    frames = load_mardct(mardct_annotations)["2"]
    dets = truth_detections(frames)
    for k, d in enumerate(dets):  # every other frame's boxes weak
        d.scores[:] = 0.3 if k % 2 else 0.9
    one = run_tracker(frames, dets, "sort")
    cfg = SortConfig(high_score=0.5, low_score=0.5)  # a threshold: weak frames unseen
    thr = run_tracker(frames, dets, "sort", sort=cfg)
    two = run_tracker(frames, dets, "sort", sort=SortConfig(high_score=0.5, low_score=0.1))
    assert len(thr[0]) < len(one[0])
    assert set(two[0].tolist()) > set(thr[0].tolist())  # weak frames reported again
    with pytest.raises(TypeError, match=r"^sort:"):
        run_tracker(frames, dets, "sort", sort=0.5)  # pyright: ignore[reportArgumentType]
    with pytest.raises(TypeError, match=r"^sort:"):
        evaluate(mardct_annotations, detectors=["contrast"], sort={"high_score": 0.5})  # pyright: ignore[reportArgumentType]
