"""Shore CNN second round: the inner split keeps each video's last frames out, hard negatives
are the detector's boxes off every boat, training views land on them, the threshold is the
highest-TPR value within the FAR bound (checked against a hand count); and the horizon's
batched pair test equals the per-line definition on real MarDCT frames."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from usvfast.shore.boxes import Detections
from usvfast.shore.cnn_mining import choose_threshold, inner_split, mine_negatives
from usvfast.shore.cnn_train import CnnTrainConfig, TrainFrame, augment
from usvfast.shore.horizon import HorizonConfig, _pairs_differ_many
from usvfast.shore.mardct import load_mardct


def test_inner_split_holds_out_each_videos_last_frames(mardct_annotations):
    videos = load_mardct(mardct_annotations)
    fit, val = inner_split(videos, 0.25)
    assert len(fit) + len(val) == sum(len(v) for v in videos.values())
    for name, frames in videos.items():
        held = [f for f in val if f.video == name]
        assert len(held) == int(np.ceil(0.25 * len(frames)))
        last_fit = max(f.index for f in fit if f.video == name)
        assert min(f.index for f in held) > last_fit  # the tail in time
    with pytest.raises(ValueError, match="val_fraction"):
        inner_split(videos, 1.0)


def test_mined_negatives_are_the_boxes_off_every_boat():
    img = np.zeros((100, 200, 3), np.uint8)
    frame = TrainFrame(img, np.array([[10.0, 10, 50, 40]]))
    # x, y, w, h: one on the boat, one overlapping it slightly, one far away
    boxes = np.array([[12.0, 10, 38, 30], [30, 10, 40, 30], [150, 60, 20, 10]])

    def detect(image):
        return Detections(boxes, np.array([0.9, 0.5, 0.3]), np.full(3, -1))

    (out,) = mine_negatives([frame], detect, max_iou=0.1)
    np.testing.assert_array_equal(out.negatives, [[150.0, 60, 170, 70]])
    (out,) = mine_negatives([frame], detect, max_iou=0.5)
    assert len(out.negatives) == 2  # the partial overlap (IoU 1/3) counts as free now


def test_views_centre_on_hard_negatives():
    img = np.full((240, 320, 3), 120, np.uint8)
    neg = np.array([[250.0, 200, 270, 210]])
    frame = TrainFrame(img, np.array([[10.0, 10, 60, 40]]), neg)
    cfg = CnnTrainConfig(hard_negative=1.0, scale_range=(1.0, 1.0), input_size=(320, 240),
                         crop_size=(96, 96))  # fmt: skip
    rng = np.random.default_rng(0)
    for _ in range(20):
        _, boxes = augment(frame, cfg, rng)
        # the negative's centre lands within the crop (±0.35 of the crop size from its
        # centre), so the boat box at the far corner never does
        assert len(boxes) == 0
    # without hard negatives the random stream is the one of the first round
    a = augment(TrainFrame(img, frame.boxes), CnnTrainConfig(), np.random.default_rng(3))
    b = augment(frame, CnnTrainConfig(), np.random.default_rng(3))
    np.testing.assert_array_equal(a[0], b[0])
    with pytest.raises(ValueError, match="hard_negative"):
        CnnTrainConfig(hard_negative=1.5)


def test_threshold_is_the_highest_tpr_within_the_far_bound():
    truth = [np.array([[0.0, 0, 10, 10]]), np.array([[50.0, 50, 10, 10]])]
    d1 = Detections(
        np.array([[0.0, 0, 10, 10], [80, 80, 5, 5], [90, 0, 5, 5]]),
        np.array([0.6, 0.35, 0.15]),
        np.full(3, -1),
    )
    d2 = Detections(np.array([[50.0, 50, 10, 10]]), np.array([0.32]), np.full(1, -1))
    conf, rows = choose_threshold(truth, [d1, d2], max_far=0.15, grid=(0.1, 0.3, 0.4, 0.7))
    by = {r["conf"]: r for r in rows}
    # 0.1: 2 TP, 2 FP (FAR 0.5); 0.3: 2 TP, 1 FP (1/3); 0.4: 1 TP, 0 FP; 0.7: nothing
    assert (by[0.1]["tp"], by[0.1]["fp"]) == (2, 2)
    assert by[0.3]["far"] == pytest.approx(1 / 3)
    assert conf == 0.4
    # no value meets the bound: best F1 (0.3: 4/5 vs 0.4: 2/3 vs 0.1: 2/3)
    conf, _ = choose_threshold(truth, [d1, d2], max_far=0.0, grid=(0.1, 0.3, 0.7))
    assert conf == 0.3


def _pairs_reference(gray, rho, theta, cfg):
    """The pair test of one line, written from its definition."""
    h, w = gray.shape
    differ = inside = 0
    for x in np.linspace(0.02 * w, 0.98 * w, cfg.samples):
        y = (rho - x * np.cos(theta)) / np.sin(theta)
        ax, ay = x - cfg.offset_px * np.cos(theta), y - cfg.offset_px * np.sin(theta)
        bx, by = x + cfg.offset_px * np.cos(theta), y + cfg.offset_px * np.sin(theta)
        if not (ay >= 0 and by < h - 1 and ax >= 0 and bx < w - 1 and ax < w and bx >= 0):
            continue
        inside += 1
        a = float(gray[round(ay), round(ax)])
        b = float(gray[round(by), round(bx)])
        differ += abs(a - b) > cfg.intensity_tolerance
    return (differ / inside if inside >= cfg.samples // 2 else 0.0), inside


def test_batched_pair_test_equals_the_per_line_definition(mardct_annotations):
    cfg = HorizonConfig()
    files = sorted(mardct_annotations.glob("*.png"))[::24]
    checked = 0
    for f in files:
        gray = cv2.medianBlur(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE), 5)
        lines = cv2.HoughLines(
            cv2.Canny(gray, 50, 70), 1, np.pi / 360, 40, min_theta=1.2, max_theta=1.9
        )
        if lines is None:
            continue
        cand = lines[:30, 0].astype(float)
        share, n = _pairs_differ_many(gray, cand[:, 0], cand[:, 1], cfg)
        for k, (rho, theta) in enumerate(cand):
            ref_share, ref_n = _pairs_reference(gray, rho, theta, cfg)
            assert n[k] == ref_n and share[k] == pytest.approx(ref_share, abs=1e-12)
            checked += 1
    assert checked > 100


def test_evaluate_scores_the_fold_cnn_and_tracks_its_detections(tmp_path, mardct_annotations):
    import json

    import torch

    from usvfast.camera.harbour_net import HarbourNet
    from usvfast.shore.cnn import CnnDetector
    from usvfast.shore.cnn_train import export_model, model_card
    from usvfast.shore.evaluate import evaluate
    from usvfast.shore.horizon import detect_horizon, horizon_keep
    from usvfast.shore.mot_eval import tracking_rows
    from usvfast.shore.scores import DetectionCounts

    with pytest.raises(ValueError, match="models"):
        evaluate(mardct_annotations, videos=["3"], detectors=["cnn"], models=tmp_path)
    cfg = CnnTrainConfig()
    torch.manual_seed(0)
    net = HarbourNet(1, cfg.input_size, cfg.width).eval()
    card = model_card(cfg, [], 0.0, net)
    card["conf_threshold"] = 0.005  # an untrained net scores ≈ 0.01 everywhere: many boxes
    export_model(net, tmp_path, card, name="shore-cnn-without-3")
    (tmp_path / "shore-cnn-hn-without-3.json").write_text(json.dumps(card), encoding="utf-8")
    res = evaluate(mardct_annotations, videos=["3"], detectors=["cnn"], models=tmp_path)["3"]
    assert res["cnn_model"] == "shore-cnn-without-3.onnx"  # the hn card alone is no model
    assert res["cnn_conf"] == 0.005
    frames = load_mardct(mardct_annotations)["3"]
    det = CnnDetector(tmp_path / "shore-cnn-without-3.onnx")
    # (the untrained net's ≈ 300 equal-score boxes fill the image from the top down, so the
    # horizon filter may drop them all: the unfiltered rows are the ones that must be busy)
    counts = {True: DetectionCounts(), False: DetectionCounts()}
    kept: dict[bool, list[Detections]] = {True: [], False: []}
    for f in frames:
        im = cv2.imread(str(f.path))
        d = det.detect(im)
        for use_h in (True, False):
            k = d.subset(horizon_keep(d, detect_horizon(im), im.shape[0], HorizonConfig()))
            k = k if use_h else d
            kept[use_h].append(k)
            counts[use_h].add(f.boxes, k.boxes)
    assert counts[False].fp > 100
    for use_h, key in ((True, "cnn_horizon"), (False, "cnn_no_horizon")):
        assert (res[key]["tp"], res[key]["fp"]) == (counts[use_h].tp, counts[use_h].fp)
    same = json.dumps(tracking_rows(frames, kept[False]), sort_keys=True)  # (NaN MOTP: no TP)
    assert json.dumps(res["tracking"]["cnn no horizon"], sort_keys=True) == same
    assert res["tracking"]["cnn no horizon"]["sort"]["false_positives"] > 0
    assert set(res["tracking"]) == {"cnn", "cnn no horizon", "truth boxes"}


def test_shore_train_hard_negatives_writes_both_rounds(tmp_path):
    import json

    from typer.testing import CliRunner

    from usvfast.cli import app

    ann = tmp_path / "ann"
    ann.mkdir()
    rng = np.random.default_rng(5)
    for k in range(6):
        img = np.full((120, 160, 3), (170, 150, 130), np.uint8)
        img[60:] = (110, 80, 50)
        img[40:, :] += rng.integers(0, 20, (80, 160, 1), dtype=np.uint8)
        x = 20 + 15 * k
        img[50:66, x : x + 40] = 20
        cv2.imwrite(str(ann / f"sea_{10 * k}.png"), img)
        (ann / f"sea_{10 * k}.txt").write_text(f"boat {x} 50 40 16\n")
    models = tmp_path / "models"
    args = ["shore-train", str(ann), "--out", str(models), "--steps", "3", "--hard-negatives"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    first = json.loads((models / "shore-cnn-round1.json").read_text())
    card = json.loads((models / "shore-cnn.json").read_text())
    assert first["train"]["hard_negative"] == 0.0 and card["train"]["hard_negative"] == 0.35
    assert card["hard_negatives"]["base_model"] == "shore-cnn-round1.onnx"
    # the last 2 of 6 frames chose the threshold and were not trained on
    assert card["inner_validation"]["frames"] == ["sea_40.png", "sea_50.png"]
    assert card["hard_negatives"]["training_frames"] == 4
    assert card["conf_threshold"] == card["inner_validation"]["chosen"]
    assert card["conf_threshold"] in [r["conf"] for r in card["inner_validation"]["sweep"]]
    assert (models / "shore-cnn.onnx").is_file()
