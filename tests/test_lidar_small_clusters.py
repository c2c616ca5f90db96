"""The LiDAR chain's small-cluster rule (`lidar.small_cluster_points`, `small_cluster_radius`) on
the simulator's own VLP-16 rotations: a held-out harbour (seed 9, never a scored seed), the
chain fed the true poses, so whatever it adds is the rule's doing. Every detection of the
chain without the rule is still there, and every detection the rule adds lies on a floating
object of the truth."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from usvfast.frames import Mount
from usvfast.lidar.frame import LidarFrame
from usvfast.lidar.pipeline import LidarDetection
from usvfast.pipeline import ConfigError, load_config
from usvfast.pipeline.config import SCHEMA
from usvfast.pipeline.lidar_chain import LidarChain
from usvfast.pipeline.pose import VesselPose
from usvfast.pipeline.timing import StageTimer
from usvfast.sim.camera import WATERLINE_HEIGHT
from usvfast.sim.configs import _SENSOR_MODELS
from usvfast.sim.recording import EPOCH
from usvfast.sim.scene import FLOAT_KINDS, make_world
from usvfast.sim.velodyne import LIDAR_LEVER_ARM, Vlp16Recorder

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

SEED, DURATION = 9, 30.0


def _chain(model: dict, **changes) -> LidarChain:
    settings = {k: v for k, (_, v) in SCHEMA["lidar"].items()}
    settings.update(waterline_height=WATERLINE_HEIGHT, **model)
    settings.update(changes)
    return LidarChain(settings, Mount(lever_arm=LIDAR_LEVER_ARM), StageTimer())


def test_small_compact_clusters_on_simulated_rotations():
    world = make_world(SEED, DURATION)

    def pose_at(t: float) -> VesselPose:
        rel = np.asarray(t - EPOCH)
        n, e, h = (float(v) for v in world.usv.pose(rel))
        roll, pitch, _ = (float(v) for v in world.waves.at(rel))
        return VesselPose(t, n, e, h, roll, pitch)

    model = tomllib.loads(_SENSOR_MODELS["lidar"])
    keys = ("small_cluster_points", "small_cluster_radius", "small_cluster_variance")
    rule = {k: model.pop(k) for k in keys}
    chains = {
        "plain": _chain(model),
        "small": _chain(model, **{**rule, "small_cluster_variance": 1.0}),
        "inflated": _chain(model, **rule),
    }
    recorder = Vlp16Recorder(world, start=EPOCH + 0.0123, seed=SEED, buildings=False)
    found: dict[str, dict[tuple, LidarDetection]] = {name: {} for name in chains}
    while (scan := recorder.next_scan()).stamp <= EPOCH + DURATION:
        pose = pose_at(scan.stamp)
        for name, chain in chains.items():
            dets = chain.process(LidarFrame(scan.stamp, scan.points, "sim"), pose, pose_at)
            for d in dets or []:
                if not d.extended:
                    key = (round(scan.stamp, 6), *(round(float(v), 9) for v in d.position))
                    found[name][key] = d
    plain, small = found["plain"], found["small"]
    assert len(plain) > 50 and not any(d.small for d in plain.values())
    assert set(plain) <= set(small)
    added = {k: d for k, d in small.items() if k not in plain}
    assert len(added) >= 3 and all(d.small for d in added.values())
    for (t, n, e), d in added.items():
        assert rule["small_cluster_points"] <= d.n_points < model["min_cluster_points"]
        objects = world.truth_at(np.array([t - EPOCH]))
        dist, kind = min((float(np.hypot(on[0] - n, oe[0] - e)), k) for _, k, on, oe in objects)
        assert dist < 0.3 and kind in FLOAT_KINDS, (t - EPOCH, dist, kind)
    # small_cluster_variance scales the small detections' covariance, and only theirs
    assert set(found["inflated"]) == set(small)
    for key, d in found["inflated"].items():
        factor = rule["small_cluster_variance"] if key in added else 1.0
        np.testing.assert_allclose(d.covariance, small[key].covariance * factor, rtol=1e-12)


def test_small_cluster_settings_reach_the_chain():
    from importlib import resources

    path = resources.files("usvfast") / "data" / "harbour" / "recording.toml"
    changes = {"lidar.small_cluster_points": 5, "lidar.small_cluster_radius": 0.07}
    cfg = load_config(path, {**changes, "lidar.small_cluster_variance": 2.5})
    chain = LidarChain(cfg.lidar, Mount(), StageTimer())
    assert (chain.config.small_cluster_points, chain.config.small_cluster_radius) == (5, 0.07)
    assert chain.small_cluster_variance == 2.5
    off = LidarChain({**cfg.lidar, "small_cluster_points": None}, Mount(), StageTimer())
    assert off.config.small_cluster_points is None
    for value in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match=r"lidar\.small_cluster_variance"):
            LidarChain({**cfg.lidar, "small_cluster_variance": value}, Mount(), StageTimer())
    for value in (0.0, float("nan")):
        with pytest.raises(ValueError, match=r"small_cluster_radius"):
            LidarChain({**cfg.lidar, "small_cluster_radius": value}, Mount(), StageTimer())
    # the rule's earlier spread parameter is gone: a config naming it fails on that key
    with pytest.raises(ConfigError, match=r"lidar\.small_cluster_std"):
        load_config(path, {"lidar.small_cluster_std": 0.1})
