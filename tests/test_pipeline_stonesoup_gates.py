"""The Stone Soup backend with `initiate_in_gates = false`: Stone Soup's own
MultiTargetMixtureTracker / MultiTargetTracker with its MultiMeasurementInitiator wrapped in
usvfast.pipeline.stonesoup_gates.InGateInitiator gives the native tracker's tracks — on a
synthetic two-sensor scenario (to 1e-9) and on the whole bundled harbour recording with the
camera and the committed demo network (to 1e-6)."""

from __future__ import annotations

import hashlib
import warnings
from importlib import resources

import numpy as np
import pytest

from usvfast.pipeline import Pipeline, load_config
from usvfast.pipeline.camera_chain import load_detector
from usvfast.pipeline.config import SCHEMA
from usvfast.pipeline.tracker import make_tracker


def _settings(**kw) -> dict:
    s = {k: v for k, (_, v) in SCHEMA["tracker"].items()}
    s.update({"initiate_in_gates": False, **kw})
    return s


def _scans(seed: int = 3):
    """Four targets seen by a LiDAR (0, σ 0.15 m, 10 Hz) and a camera (1, σ 0.4 m and 0.9 m
    off along a biased line of sight, 10 Hz between the LiDAR scans), with misses, clutter and
    a second camera return near some targets: camera detections fall in LiDAR tracks' gates
    (with weights below the missed one) or just outside, and start duplicates in Stone
    Soup's plain initiator."""
    rng = np.random.default_rng(seed)
    x0 = np.array([[2.0, 0.3, -3.0, 0.1], [6.0, -0.2, 4.0, 0.0], [-4.0, 0.0, 1.0, 0.25]])
    x0 = np.vstack([x0, [[0.0, 0.1, 7.0, -0.3]]])
    out = []
    for k in range(80):
        t = 0.05 * k
        sensor = k % 2
        truth = x0[:, [0, 2]] + t * x0[:, [1, 3]]
        seen = truth[rng.random(len(truth)) < (0.8 if sensor == 0 else 0.6)]
        std = 0.15 if sensor == 0 else 0.4
        z = seen + rng.normal(0.0, std, seen.shape) + (0.9 if sensor else 0.0)
        near = truth[rng.random(len(truth)) < (0.4 if sensor else 0.0)]
        z = np.vstack([z, near + rng.normal(0.0, 0.5, near.shape)])
        z = np.vstack([z, rng.uniform(-8.0, 10.0, (rng.poisson(0.3), 2))])
        rot = rng.normal(0.0, 0.3, (len(z), 2, 2))
        covs = np.eye(2) * std**2 + 0.01 * std**2 * (rot @ rot.transpose(0, 2, 1))
        out.append((round(t, 6), z, np.full(len(z), sensor, dtype=np.int64), covs))
    return out


def _run(settings: dict, scans) -> list:
    tr = make_tracker(settings)
    return [tr.step(t, z, s, c) for t, z, s, c in scans], tr


def _compare(a, b, atol: float) -> tuple[int, float]:
    seen_a: set[int] = set()
    seen_b: set[int] = set()
    worst = 0.0
    for x, y in zip(a, b, strict=True):
        # Same births and deaths: the same number of tracks after every scan, new ones together.
        assert len(x.ids) == len(y.ids)
        assert len(set(x.ids.tolist()) - seen_a) == len(set(y.ids.tolist()) - seen_b)
        seen_a |= set(x.ids.tolist())
        seen_b |= set(y.ids.tolist())
        oa, ob = np.lexsort(x.states.T[::-1]), np.lexsort(y.states.T[::-1])
        np.testing.assert_allclose(x.states[oa], y.states[ob], atol=atol, rtol=0)
        np.testing.assert_allclose(x.covariances[oa], y.covariances[ob], atol=atol, rtol=0)
        if len(x.ids):
            worst = max(worst, float(np.abs(x.states[oa] - y.states[ob]).max()))
    return len(seen_a), worst


@pytest.mark.parametrize("association", ["jpda", "gnn"])
def test_stone_soup_in_gate_initiator_equals_the_native_tracker(association):
    scans = _scans()
    settings = _settings(association=association, delete_steps=10, clutter_density=1.0)
    native, _ = _run(settings, scans)
    stone, tr = _run({**settings, "backend": "stonesoup"}, scans)
    births, worst = _compare(native, stone, 1e-9)
    assert births >= 4 and worst < 1e-9
    ini = tr.tracker.initiator
    assert ini.dropped > 0  # duplicates were suppressed, not merely absent
    if association == "jpda":
        assert ini.withheld > 0
    # Stone Soup's plain initiator (initiate_in_gates = true) starts the duplicates.
    plain, _ = _run({**settings, "backend": "stonesoup", "initiate_in_gates": True}, scans)
    assert len({i for s in plain for i in s.ids.tolist()}) > births


class _Memo:
    """The demo network's boxes of each frame computed once, reused by the second backend."""

    def __init__(self, detector) -> None:
        self.detector, self.seen = detector, {}

    def __call__(self, images):
        key = hashlib.sha1(images[0].tobytes()).hexdigest()
        if key not in self.seen:
            self.seen[key] = self.detector(images)
        return self.seen[key]


def test_bundled_recording_same_tracks_through_stone_soup():
    # The bundled config unchanged (camera on, initiate_in_gates = false, per-detection
    # covariances, camera boxes under start_confidence starting no track, the committed ONNX
    # demo network), the whole 30 s.
    cfg = load_config(resources.files("usvfast") / "data" / "harbour" / "recording.toml")
    assert cfg.tracker["initiate_in_gates"] is False and cfg.camera["enabled"]
    assert cfg.path is not None
    memo = _Memo(load_detector(cfg.detector, cfg.path.parent))
    runs = []
    for backend in ("native", "stonesoup"):
        pipe = Pipeline(cfg.with_options(tracker={"backend": backend}), detector=memo)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            runs.append(list(pipe.run()))
    a, b = runs
    assert [u.time for u in a] == [u.time for u in b] and len(a) > 300
    assert cfg.camera["start_confidence"] is not None
    assert {u.sensor for u in a} == {"lidar", "camera"}
    births, worst = _compare([u.tracks for u in a], [u.tracks for u in b], 1e-6)
    assert births >= 10 and worst < 1e-6
    assert pipe.tracker.tracker.initiator.dropped > 0


@pytest.mark.parametrize("association", ["jpda", "gnn"])
@pytest.mark.parametrize("in_gates", [False, True])
def test_non_starting_detections_same_tracks_through_stone_soup(association, in_gates):
    # Half the camera's detections may not start tracks (camera.start_confidence): Stone
    # Soup's initiator wrapped in StartingInitiator gives the native tracker's tracks.
    rng = np.random.default_rng(11)
    scans = [(t, z, s, c, (s == 0) | (rng.random(len(z)) < 0.5)) for t, z, s, c in _scans(seed=5)]
    settings = _settings(
        association=association, delete_steps=10, clutter_density=1.0, initiate_in_gates=in_gates
    )
    runs = []
    for backend in ("native", "stonesoup"):
        tr = make_tracker({**settings, "backend": backend})
        runs.append([tr.step(*scan) for scan in scans])
    births, worst = _compare(runs[0], runs[1], 1e-9)
    assert births >= 3 and worst < 1e-9
    # The mask matters: with every detection starting, the tracks are not the same.
    every, _ = _run(settings, [scan[:4] for scan in scans])
    assert any(
        len(a.ids) != len(b.ids) or not np.allclose(a.states, b.states)
        for a, b in zip(runs[0], every, strict=True)
    )
