"""16-bit and float frames (thermal cameras) to 8 bits: equal to the plain numpy stretch,
robust to hot pixels, clear errors; and the pipeline runs a mono16 camera as its 8-bit one."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from usvfast.camera.agc import to_uint8
from usvfast.nav.replay import Replay
from usvfast.pipeline import ConfigError, Pipeline, load_config

import pipeline_recording as pr


def reference(image: np.ndarray, low: float, high: float) -> np.ndarray:
    """The plain numpy version: percentiles of the finite values, stretch, clip, round."""
    lo, hi = np.percentile(image[np.isfinite(image)], [low, high])
    if not hi > lo:
        return np.zeros(image.shape, np.uint8)
    out = np.clip((image.astype(np.float64) - lo) * (255.0 / (hi - lo)), 0.0, 255.0)
    return np.rint(np.where(np.isnan(out), 0.0, out)).astype(np.uint8)


@pytest.mark.parametrize("dtype", [np.uint16, np.int32, np.float32, np.float64])
def test_equals_the_numpy_stretch(dtype):
    rng = np.random.default_rng(3)
    for _ in range(40):
        shape = tuple(int(v) for v in rng.integers(1, 70, size=int(rng.integers(2, 4))))
        top = int(rng.choice([4, 300, 65535]))
        image = rng.integers(0, top, shape).astype(dtype)
        low, high = np.sort(rng.uniform(0, 100, 2))
        np.testing.assert_array_equal(to_uint8(image, (low, high)), reference(image, low, high))
    frame = rng.integers(0, 256, (8, 9), dtype=np.uint8)
    assert to_uint8(frame) is frame


def test_hot_pixels_do_not_set_the_scale():
    rng = np.random.default_rng(5)
    scene = rng.normal(24000, 800, (256, 320)).astype(np.uint16)
    hot = scene.copy()
    hot.flat[rng.choice(hot.size, 60, replace=False)] = 65535  # 0.07 % stuck pixels
    a, b = to_uint8(scene), to_uint8(hot)
    same = hot == scene
    # the 99th percentile moves by 0.07 % of the pixels: at most 2 grey levels anywhere
    assert np.abs(a[same].astype(int) - b[same]).max() <= 2
    assert a.min() == 0 and a.max() == 255 and 120 < a.mean() < 135
    # a min-max stretch (0, 100) lets the stuck pixels squash the scene into a third
    assert to_uint8(hot, (0.0, 100.0))[same].max() < 90


def test_flat_non_finite_and_bad_input():
    assert not to_uint8(np.full((4, 4), 700, np.uint16)).any()
    f = np.array([[0.0, 1.0, np.nan], [np.inf, -np.inf, 0.5]])
    np.testing.assert_array_equal(to_uint8(f, (0, 100)), [[0, 255, 0], [255, 0, 128]])
    assert not to_uint8(np.full((2, 2), np.nan)).any()
    with pytest.raises(ValueError, match="percentiles: expected 0 <= low < high <= 100"):
        to_uint8(np.zeros((2, 2), np.uint16), (50, 50))
    with pytest.raises(ValueError, match=r"percentiles: expected \(low, high\)"):
        to_uint8(np.zeros((2, 2), np.uint16), (1,))
    for bad in (np.zeros((2, 2), complex), np.zeros(2, object), [[1, 2]]):
        with pytest.raises(TypeError, match="image: expected an integer or float array"):
            to_uint8(bad)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    return pr.build(tmp_path_factory.mktemp("rec"), duration=6.0)


def test_a_mono16_camera_runs_as_its_8_bit_frames(rec):
    """Each BGR frame as 16-bit counts (× 257) with the stretch from its minimum to its
    maximum: where a float (an orange disc) is in view the frame spans 0–255, so the stretch
    gives the 8-bit frame back and every update is the same."""
    cfg8, cfg16 = load_config(rec.config), load_config(rec.config)
    cfg16.camera["agc_percentiles"] = (0.0, 100.0)
    eight, sixteen = (
        Pipeline(cfg8, detector=pr.disc_detector),
        Pipeline(cfg16, detector=pr.disc_detector),
    )
    a, b = [], []
    for item in Replay(cfg8.recording, end=pr.EPOCH + 6.0):
        a += eight.process(item)
        data = item.data
        if item.stream == "camera":
            data = data.astype(np.uint16) * 257
        b += sixteen.process(SimpleNamespace(time=item.time, stream=item.stream, data=data))
    assert sixteen.timer.calls["camera.agc"] > 20
    assert sum(u.detections for u in a if u.sensor == "camera") > 20
    assert [(u.time, u.sensor, u.detections) for u in a] == [
        (u.time, u.sensor, u.detections) for u in b
    ]
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.tracks.states, y.tracks.states)


def test_agc_percentiles_are_checked(rec, tmp_path):
    text = rec.config.read_text().replace("[camera]", "[camera]\nagc_percentiles = [99, 1]", 1)
    bad = rec.config.parent / "bad_agc.toml"
    bad.write_text(text)
    with pytest.raises(ConfigError, match=r"camera.agc_percentiles': expected 0 <= low < high"):
        load_config(bad)
