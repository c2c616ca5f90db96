"""The training-free contrast detector and the fused CNN + contrast score of the shore chain."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import median_abs_deviation

from usvfast.shore.boxes import Detections, iou_matrix
from usvfast.shore.contrast import ContrastConfig, ContrastDetector, _row_models, contrast_map
from usvfast.shore.fused import FusedDetector, box_support, fused_keep
from usvfast.shore.horizon import HorizonConfig, HorizonLine, horizon_keep


def scene(seed: int = 0, ship: tuple[int, int, int, int] | None = (100, 96, 90, 36)):
    """A 320×240 BGR frame: noisy grey sky above row 120, noisy blue water under it, and an
    optional dark ship (x, y, w, h) across the line."""
    rng = np.random.default_rng(seed)
    img = np.empty((240, 320, 3), np.float64)
    img[:120] = (200, 195, 190)
    img[120:] = (120, 80, 40)
    img += rng.normal(0, 4, img.shape)
    if ship is not None:
        x, y, w, h = ship
        img[y : y + h, x : x + w] = (60, 60, 65)
    return np.clip(img, 0, 255).astype(np.uint8)


SKY_LINE = HorizonLine(rho=120.0, theta=np.pi / 2, kind="water-sky", differing=1.0, edge_density=0)


def test_row_models_equal_scipy_median_and_scaled_mad():
    rng = np.random.default_rng(1)
    plane = rng.normal(100, 7, (12, 50)).astype(np.float32)
    mask = np.ones((12, 50), bool)
    mask[5, :20] = False  # a partial row, done on its own
    mask[7, :40] = False  # under 30 % of the row: no model
    med, mad = _row_models(plane, mask)
    for r in range(12):
        v = plane[r, mask[r]]
        if r == 7:
            assert np.isnan(med[r]) and np.isnan(mad[r])
            continue
        assert med[r] == pytest.approx(np.median(v), abs=1e-4)
        # scipy's "normal" scale is 1 / Φ⁻¹(3/4) = 1.482602...; ours 1.4826
        assert mad[r] == pytest.approx(median_abs_deviation(v, scale="normal"), rel=1e-4)


def test_contrast_of_a_pixel_is_its_robust_z_in_its_row():
    img = scene(2, ship=None)
    img[150, 200] = (250, 250, 250)
    cfg = ContrastConfig(blur=1)
    z, line, s = contrast_map(img, SKY_LINE, cfg)
    assert s == 1.0 and np.allclose(line, 120.0)
    row = img[150].astype(float)
    med = np.median(row[::3], axis=0)
    mad = np.maximum(1.4826 * np.median(np.abs(row[::3] - med), axis=0), cfg.mad_floor)
    expect = (np.abs(row[200] - med) / mad).max()
    assert z[150, 200] == pytest.approx(expect, rel=1e-4)
    assert z[150, 200] > 20 and np.median(z[125:235]) < 1.5


def test_finds_a_ship_across_the_sea_horizon_and_nothing_on_empty_sea():
    det = ContrastDetector()
    ship = np.array([[100.0, 96, 90, 36]])
    for seed in range(3):
        d = det.detect(scene(seed), SKY_LINE)
        assert len(d) == 1
        assert iou_matrix(d.boxes, ship)[0, 0] > 0.8
        assert 0 < d.scores[0] <= 1
        assert len(det.detect(scene(seed, ship=None), SKY_LINE)) == 0


def test_a_blob_away_from_the_line_is_no_ship_at_sea_and_a_quay_blob_no_boat():
    # a dark blob high in the sky (a cloud) does not reach the water-sky line
    d = ContrastDetector().detect(scene(4, ship=(100, 20, 90, 36)), SKY_LINE)
    assert len(d) == 0
    coast = HorizonLine(rho=120.0, theta=np.pi / 2, kind="water-coast", differing=1, edge_density=1)
    # at a water-coast line: a boat floating in the harbour is kept, a blob on the quay is not
    boat = ContrastDetector().detect(scene(5, ship=(100, 150, 90, 40)), coast)
    quay = ContrastDetector().detect(scene(5, ship=(100, 70, 90, 40)), coast)
    assert len(boat) == 1 and iou_matrix(boat.boxes, [[100, 150, 90, 40]])[0, 0] > 0.8
    assert len(quay) == 0


def test_bad_input_is_a_clear_error():
    with pytest.raises(ValueError, match="threshold"):
        ContrastConfig(threshold=-1)
    with pytest.raises(ValueError, match="blur"):
        ContrastConfig(blur=4)
    with pytest.raises(ValueError, match="close"):
        ContrastConfig(close=(1.5, 0.1))
    with pytest.raises((ValueError, TypeError), match="image"):
        ContrastDetector().detect(np.zeros((20, 20, 3), np.float32))
    with pytest.raises(TypeError, match="cnn"):
        FusedDetector(object())
    with pytest.raises(ValueError, match="relative"):
        FusedDetector(ContrastDetector(), relative=2)


def test_box_support_equals_the_brute_force_share():
    rng = np.random.default_rng(3)
    z = rng.uniform(0, 6, (60, 80))
    boxes = np.array([[0, 0, 80, 60], [10.2, 5.7, 20, 11], [70, 50, 30, 30], [5, 5, 0, 4]])
    got = box_support(z, boxes, 0.5, 3.0)
    for b, g in zip(boxes, got, strict=True):
        x0, y0 = int(np.floor(b[0] * 0.5)), int(np.floor(b[1] * 0.5))
        x1 = min(int(np.ceil((b[0] + b[2]) * 0.5)), 80)
        y1 = min(int(np.ceil((b[1] + b[3]) * 0.5)), 60)
        patch = z[y0:y1, x0:x1]
        assert g == pytest.approx((patch > 3).mean() if patch.size else 0.0)


class FixedCnn:
    """A stand-in network: the same boxes and confidences on every frame."""

    def __init__(self, boxes, scores):
        self.d = Detections(np.asarray(boxes, float), np.asarray(scores, float), -np.ones(2, int))

    def detect(self, image):
        return self.d


def test_fused_score_prefers_the_box_on_the_ship_over_a_confident_box_on_water():
    cnn = FixedCnn([[100, 96, 90, 36], [150, 170, 90, 36]], [0.5, 0.8])
    fused = FusedDetector(cnn, threshold=0.1, relative=0.0)
    d = fused.score(scene(6), SKY_LINE)
    assert d.scores[0] > 0.5 > 0.1 > d.scores[1]
    kept = fused.detect(scene(6), SKY_LINE)
    assert len(kept) == 1 and np.array_equal(kept.boxes[0], [100, 96, 90, 36])


def test_fused_keep_by_threshold_and_share_of_the_frame_best():
    s = np.array([0.9, 0.75, 0.5, 0.05])
    assert fused_keep(s, 0.1, 0.0).tolist() == [True, True, True, False]
    assert fused_keep(s, 0.1, 0.8).tolist() == [True, True, False, False]
    assert fused_keep(np.zeros(0), 0.1, 0.8).shape == (0,)


def test_shore_chain_runs_the_contrast_detector(monkeypatch, tmp_path):
    from usvfast.shore.pipeline import ShoreChain, ShoreConfig

    chain = ShoreChain(ShoreConfig(detector="contrast"))
    ship = (100, 100, 60, 28)  # its hull ends above the pair test's lower samples
    r = chain.step(scene(7, ship))
    assert r.horizon is not None and abs(r.horizon.y_at(160.0) - 120) < 3
    assert len(r.kept) == 1 and iou_matrix(r.kept.boxes, [ship])[0, 0] > 0.7
    monkeypatch.setenv("USVFAST_MODELS", str(tmp_path))
    monkeypatch.delenv("USVFAST_SHORE_MODEL", raising=False)
    with pytest.raises(ValueError, match="cnn_model"):
        ShoreConfig(detector="fused")


def test_pick_maximises_tpr_under_the_far_aim_else_f1():
    from usvfast.shore.evaluate_det import pick

    scores = {
        "a": {"tp": 90, "fp": 30, "fn": 10},  # TPR 0.9, FAR 0.25
        "b": {"tp": 70, "fp": 10, "fn": 30},  # TPR 0.7, FAR 0.125
        "c": {"tp": 50, "fp": 2, "fn": 50},  # TPR 0.5, FAR 0.04
    }
    assert pick(list(scores), scores.__getitem__) == "b"
    high = {"a": {"tp": 90, "fp": 60, "fn": 10}, "b": {"tp": 20, "fp": 20, "fn": 80}}
    assert pick(list(high), high.__getitem__) == "a"  # no FAR ≤ 0.15: best F1


def test_regdtv9_scores_of_the_training_free_detector(mardct_annotations):
    """Nothing is learnt, so every MarDCT video is held out: regDTV9 (ferries at the sea
    horizon, 704×576) at the default threshold, horizon filter on."""
    import cv2

    from usvfast.shore.horizon import detect_horizon
    from usvfast.shore.mardct import load_mardct
    from usvfast.shore.scores import DetectionCounts

    frames = load_mardct(mardct_annotations)["regDTV9"]
    det, hcfg, c = ContrastDetector(), HorizonConfig(), DetectionCounts()
    for f in frames:
        im = cv2.imread(str(f.path), cv2.IMREAD_COLOR)
        hz = detect_horizon(im)
        d = det.detect(im, hz)
        c.add(f.boxes, d.subset(horizon_keep(d, hz, im.shape[0], hcfg)).boxes)
    # measured 0.448 / 0.325 (56 TP, 27 FP, 69 FN of 125 boxes)
    assert c.tp + c.fn == 125
    assert c.tpr > 0.4 and c.far < 0.36


def test_shore_command_with_the_contrast_detector(tmp_path):
    import cv2
    from typer.testing import CliRunner

    from usvfast.cli import app
    from usvfast.shore.mot import read_mot

    frames = tmp_path / "frames"
    frames.mkdir()
    for k in range(4):
        cv2.imwrite(str(frames / f"f_{k:03d}.png"), scene(10 + k, (90 + 8 * k, 100, 60, 28)))
    out = tmp_path / "out"
    args = ["shore", str(frames), "--out", str(out), "--no-progress", "--no-video"]
    res = CliRunner().invoke(app, [*args, "--detector", "contrast", "--tracker", "sort"])
    assert res.exit_code == 0, res.output
    det = read_mot(out / "detections.txt")
    assert det[:, 0].tolist() == [1, 2, 3, 4]
    assert np.allclose(det[:, 2], [90 + 8 * k for k in range(4)], atol=3)
    bad = CliRunner().invoke(app, [*args, "--detector", "nope"])
    assert bad.exit_code != 0 and "detector" in bad.output
