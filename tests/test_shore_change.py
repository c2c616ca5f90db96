"""The temporal change detector of the shore chain and the frame registration under it."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.stats import median_abs_deviation

from usvfast.shore.boxes import iou_matrix
from usvfast.shore.change import ChangeConfig, ChangeDetector
from usvfast.shore.horizon import HorizonConfig, HorizonLine, horizon_keep
from usvfast.shore.register import RegisterConfig, register, warp_to

COAST_LINE = HorizonLine(
    rho=120.0, theta=np.pi / 2, kind="water-coast", differing=1.0, edge_density=0
)
MOVER = (30, 150, 36, 18)  # x, y, w, h in the first frame's pixels
STEP = 40  # the mover's image motion a frame (px; more than its length: no overlap, no ghost)
MOORED = (230, 200, 46, 20)  # fixed in the world (so it moves with the pan in the image)
PAN = 3  # the camera pans right 3 px a frame: the world moves 3 px left in the image


def world(seed: int = 0) -> np.ndarray:
    """A 240 × 420 BGR world: a textured coast above row 120 (smoothed noise: corners for
    ORB, gradients for ECC), noisy water under it, and the moored boat."""
    rng = np.random.default_rng(seed)
    img = np.empty((240, 420, 3), np.float32)
    coast = cv2.GaussianBlur(rng.uniform(60, 200, (120, 420)).astype(np.float32), (0, 0), 2.0)
    img[:120] = coast[..., None]
    img[120:] = (130, 90, 50)
    x, y, w, h = MOORED
    img[y : y + h, x : x + w] = (235, 235, 235)
    return img


def sequence(n: int = 6, seed: int = 0) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """n 320 × 240 frames of a panning camera over `world` with the moving boat, and the
    boats' true boxes per frame (mover first, then the moored one)."""
    rng = np.random.default_rng(seed + 1)
    base = world(seed)
    frames, truth = [], []
    for k in range(n):
        img = base.copy()
        x, y, w, h = MOVER
        wx = x + STEP * k + PAN * k  # world column of the mover
        img[y : y + h, wx : wx + w] = (25, 25, 30)
        img[120:] += rng.normal(0, 3, img[120:].shape)
        crop = img[:, PAN * k : PAN * k + 320]
        frames.append(np.clip(crop, 0, 255).astype(np.uint8))
        truth.append(
            np.array(
                [[x + STEP * k, y, w, h], [MOORED[0] - PAN * k, MOORED[1], MOORED[2], MOORED[3]]]
            )
        )
    return frames, truth


def test_registration_recovers_a_known_shift_small_and_large():
    frames, _ = sequence(2)
    ref = frames[0]
    for dx, dy in ((2.5, -1.5), (-37.0, 6.0)):  # ECC from the identity; ORB for the big pan
        moving = cv2.warpAffine(
            ref, np.float32([[1, 0, dx], [0, 1, dy]]), (320, 240), borderMode=cv2.BORDER_REFLECT
        )
        warp, method = register(ref, moving)  # moving -> reference: minus the shift
        assert method in ("ecc", "orb")
        assert np.allclose(warp[:, :2], np.eye(2), atol=0.01)
        assert np.allclose(warp[:, 2], [-dx, -dy], atol=0.3), (method, warp)
    blank = np.full((240, 320), 128, np.uint8)
    warp, method = register(blank, blank)  # nothing to register on
    assert method == "none" and np.array_equal(warp, np.eye(2, 3, dtype=np.float32))


def test_registration_ignores_the_boat_and_follows_the_pan():
    frames, _ = sequence(3)
    warp, _ = register(frames[1], frames[0])  # frame 0 -> 1: the world moves PAN px left
    assert np.allclose(warp[:, 2], [-PAN, 0], atol=0.3)
    out, inside = warp_to(frames[0], warp, (320, 240))
    diff = np.abs(out[:110].astype(int) - frames[1][:110].astype(int))  # the coast
    assert np.median(diff[inside[:110]]) < 3 and not inside[:, -1].any()


def test_change_z_is_the_robust_z_against_the_neighbours_median():
    rng = np.random.default_rng(3)
    base = rng.uniform(0, 255, (60, 80, 3)).astype(np.uint8)
    base = cv2.GaussianBlur(base, (0, 0), 2.0)
    frames = [
        np.clip(base + rng.normal(0, 6, base.shape), 0, 255).astype(np.uint8) for _ in range(6)
    ]
    cfg = ChangeConfig(history=5, blur=1, spread_floor=1.0, border_px=0, fallback=False)
    det = ChangeDetector(cfg)
    (z, scale) = det.change_maps(frames)[-1]
    assert scale == 1.0 and z is not None
    assert det.methods[0] == "first" and set(det.methods[1:]) <= {"ecc", "orb"}
    # registration of noise around one image is sub-pixel: compare away from edges
    stack = np.stack(frames[:5]).astype(np.float64)
    med = np.median(stack, axis=0)
    spread = np.maximum(median_abs_deviation(stack, axis=0, scale="normal"), 1.0)
    want = (np.abs(frames[5] - med) / spread).max(axis=2)
    inner = (slice(8, -8), slice(8, -8))
    assert np.corrcoef(z[inner].ravel(), want[inner].ravel())[0, 1] > 0.9
    assert abs(np.median(z[inner]) - np.median(want[inner])) < 0.2


def test_finds_the_moving_boat_and_not_the_moored_one():
    frames, truth = sequence(6)
    cfg = ChangeConfig(fallback=False)
    det = ChangeDetector(cfg)
    out = det.detect_sequence(frames, [COAST_LINE] * len(frames))
    assert [len(d) for d in out[:2]] == [0, 0]  # online: too few past neighbours
    for k in range(2, 6):
        d = out[k].subset(horizon_keep(out[k], COAST_LINE, 240, HorizonConfig()))
        assert len(d) == 1, (k, d.boxes)
        iou = iou_matrix(d.boxes, truth[k])[0]
        assert iou[0] > 0.6 and iou[1] == 0.0, (k, d.boxes, truth[k])
    online = ChangeDetector(cfg)
    steps = [online.step(f, COAST_LINE) for f in frames]
    for a, b in zip(steps, out, strict=True):  # step() is the online sequence
        assert np.allclose(a.boxes, b.boxes)


def test_online_uses_past_frames_only_offline_also_future_ones():
    frames, _ = sequence(6)
    changed = [*frames[:4], *[f[:, ::-1].copy() for f in frames[4:]]]  # a different future
    lines = [COAST_LINE] * 6
    for online, same in ((True, True), (False, False)):
        det = ChangeDetector(ChangeConfig(online=online, fallback=False))
        a = det.change_maps(frames)[3][0]
        b = det.change_maps(changed)[3][0]
        assert a is not None and b is not None
        assert np.array_equal(a, b) == same
    off = ChangeDetector(ChangeConfig(online=False, fallback=False)).detect_sequence(frames, lines)
    assert all(len(d) == 1 for d in off)  # offline: the first frames have a background too


def test_fallback_is_the_contrast_detector_where_no_background():
    from usvfast.shore.contrast import ContrastDetector

    frames, _ = sequence(3)
    out = ChangeDetector(ChangeConfig(fallback=True)).detect_sequence(frames, [COAST_LINE] * 3)
    want = ContrastDetector().detect(frames[0], COAST_LINE)
    assert np.allclose(out[0].boxes, want.boxes) and len(want) > 0


def test_bad_input_is_a_clear_error():
    frames, _ = sequence(3)
    for kw, name in (
        ({"history": 0}, "history"),
        ({"min_neighbours": 5}, "min_neighbours"),
        ({"blur": 4}, "blur"),
        ({"threshold": -1.0}, "threshold"),
        ({"relative": 1.5}, "relative"),
        ({"online": 1}, "online"),
        ({"close": 3}, "close"),
        ({"register": 3}, "register"),
    ):
        with pytest.raises((ValueError, TypeError), match=name):
            ChangeConfig(**kw)  # pyright: ignore[reportArgumentType]
    det = ChangeDetector()
    with pytest.raises(TypeError, match="images"):
        det.change_maps(np.stack(frames))
    with pytest.raises(ValueError, match="size"):
        det.change_maps([frames[0], frames[1][:200]])
    with pytest.raises(ValueError, match="horizons"):
        det.detect_sequence(frames, [COAST_LINE])
    with pytest.raises(TypeError, match="image"):
        det.step(frames[0].astype(np.float32))
    with pytest.raises(ValueError, match="moving"):
        register(frames[0], frames[1][:100])
    with pytest.raises((TypeError, ValueError), match="reference"):
        register(frames[0].astype(np.float64), frames[1])
    with pytest.raises(TypeError, match="config"):
        register(frames[0], frames[1], config=3)  # pyright: ignore[reportArgumentType]
    with pytest.raises(ValueError, match="min_ecc"):
        RegisterConfig(min_ecc=2.0)
    with pytest.raises(ValueError, match="warp"):
        warp_to(frames[0], np.full((2, 3), np.nan), (320, 240))


def test_shore_chain_and_command_run_the_change_detector(tmp_path):
    from typer.testing import CliRunner

    from usvfast.cli import app
    from usvfast.shore.mot import read_mot

    folder = tmp_path / "frames"
    folder.mkdir()
    frames, truth = sequence(6)
    for k, f in enumerate(frames):
        cv2.imwrite(str(folder / f"f_{k:03d}.png"), f)
    out = tmp_path / "out"
    args = ["shore", str(folder), "--out", str(out), "--no-progress", "--no-video"]
    res = CliRunner().invoke(app, [*args, "--detector", "change", "--tracker", "sort"])
    assert res.exit_code == 0, res.output
    det = read_mot(out / "detections.txt")
    late = det[det[:, 0] >= 4]  # frames 4–6 have at least two past neighbours
    assert len(late) >= 3
    for row in late:
        k = int(row[0]) - 1
        assert iou_matrix(row[None, 2:6], truth[k][:1])[0, 0] > 0.5


def test_video3_scores_of_the_change_detector(mardct_annotations):
    """Nothing is learnt: MarDCT's video3 (a camera panning after a harbour boat,
    320×240, 103 annotated frames 5–500 frames apart), online, default parameters, horizon
    filter on."""
    from usvfast.shore.horizon import detect_horizon
    from usvfast.shore.mardct import load_mardct
    from usvfast.shore.scores import DetectionCounts

    frames = load_mardct(mardct_annotations)["video3"]
    images = [cv2.imread(str(f.path), cv2.IMREAD_COLOR) for f in frames]
    lines = [detect_horizon(im) for im in images]
    out = ChangeDetector().detect_sequence(images, lines)
    c, hcfg = DetectionCounts(), HorizonConfig()
    for f, im, hz, d in zip(frames, images, lines, out, strict=True):
        c.add(f.boxes, d.subset(horizon_keep(d, hz, im.shape[0], hcfg)).boxes)
    # measured 0.410 / 0.612 (57 TP, 90 FP, 82 FN of 139 boxes); the contrast detector
    # alone scores 0.295 / 0.839 there
    assert c.tp + c.fn == 139
    assert c.tpr > 0.38 and c.far < 0.65
