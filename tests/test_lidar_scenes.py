"""The proof: simulated harbour scenes, scored against the simulator's ground truth.

In every scene the vessel moves (1 m/s, some turning), floating objects sit 3.5–10 m from
its start, walls are on one or two sides and boats are moored. Per buffered cycle, at least
95 % of the floating objects the simulator hit (with enough returns in range to form a
cluster) must be detected, and no detection may come from a wall or a boat.
Run with `-s` to see the figures per scene.
"""

from __future__ import annotations

import pytest

from usvfast.lidar import LidarConfig, evaluate_scene, harbour_scene, straight_run

SCENES = {
    "two walls, 3 boats, 8 floats, straight": (
        {"seed": 0, "walls": 2, "boats": 3, "floats": 8},
        {"speed": 1.0},
    ),
    "one wall, 2 boats, 6 floats, turning": (
        {"seed": 1, "walls": 1, "boats": 2, "floats": 6},
        {"speed": 1.0, "yaw_rate": 0.08},
    ),
    "two walls, 4 boats, 10 floats, slow": (
        {"seed": 2, "walls": 2, "boats": 4, "floats": 10},
        {"speed": 0.5, "yaw_rate": -0.05},
    ),
    "one wall, 3 boats, 5 floats, wakes": (
        {"seed": 3, "walls": 1, "boats": 3, "floats": 5, "clutter_probability": 0.0003},
        {"speed": 1.5, "yaw_rate": -0.1},
    ),
}


@pytest.mark.parametrize("name", list(SCENES))
def test_harbour_scene_detection(name):
    scene_kw, run_kw = SCENES[name]
    scene = harbour_scene(**scene_kw)
    poses, stamps = straight_run(40, t0=1_700_000_000.0, **run_kw)
    score = evaluate_scene(scene, poses, stamps, config=LidarConfig(), seed=scene_kw["seed"])
    print(f"\n{name}: {score.summary()}")
    assert len(score.cycles) == 10
    assert score.detectable >= 3 * len(score.cycles)  # the scene really tests something
    assert score.detected >= 0.95 * score.detectable
    assert score.worst_cycle_rate >= 0.75  # at most one miss in a cycle of 4+ objects
    walls_boats = [f for c in score.cycles for f in c.false if f[0] in ("wall", "boat")]
    assert walls_boats == []
    if scene.clutter_probability == 0:
        assert score.false == 0
