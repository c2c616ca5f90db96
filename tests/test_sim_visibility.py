"""visibility.csv of a simulated recording against independent counts: the LiDAR returns on
each object per rotation equal the points of the decoded bag (velodyne-decoder) that fall
inside the object's box once placed in the world with the true pose at their firing time;
the camera's box sizes agree with OpenCV's projection of the object's corners. Writing it
changes no other file of the recording."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from usvfast.frames import rotation_matrix
from usvfast.lidar.readers import BagReader
from usvfast.sim.camera import WATERLINE_HEIGHT, camera_pose, default_camera
from usvfast.sim.recording import EPOCH, TOPICS, SimulationOptions, simulate
from usvfast.sim.scene import FLOAT_KINDS, place_body
from usvfast.sim.velodyne import LIDAR_LEVER_ARM
from usvfast.sim.visibility import VISIBILITY_COLUMNS, VisibilityLog

SEED, DURATION = 1, 3.0
_FLU_FRD = np.diag([1.0, -1.0, -1.0])


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    out = tmp_path_factory.mktemp("vis") / "rec"
    res = simulate(out, SimulationOptions(seed=SEED, duration=DURATION, lidar_buildings=False))
    with open(out / "visibility.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return res, rows


def _world_points(world, frame) -> np.ndarray:
    """The decoded points of a rotation in the world (north, east, down), each placed with
    the USV's true pose and wave attitude at its firing time (the simulator's mount)."""
    p = frame.points
    t = frame.stamp + p["time"].astype(np.float64) - EPOCH
    n, e, heading = world.usv.pose(t)
    roll, pitch, heave = world.waves.at(t)
    r = np.stack([rotation_matrix(a, b, c) for a, b, c in zip(roll, pitch, heading, strict=True)])
    frd = np.column_stack([p["x"], p["y"], p["z"]]).astype(np.float64) @ _FLU_FRD.T
    body = np.column_stack([n, e, -(WATERLINE_HEIGHT + heave)])
    lever = np.asarray(LIDAR_LEVER_ARM, dtype=np.float64)
    return body + np.einsum("kij,j->ki", r, lever) + np.einsum("kij,kj->ki", r, frd)


def test_lidar_returns_per_rotation_equal_the_decoded_cloud(rec):
    res, rows = rec
    world = res.world
    ids = world.truth_ids()
    kinds = {ids[m.object_id]: m.kind for m in world.movers}
    counts = {
        (round(float(r["time"]), 6), int(r["object_id"])): int(r["count"])
        for r in rows
        if r["sensor"] == "lidar"
    }
    frames = list(BagReader(res.out / "bag", topic=TOPICS["lidar"][0]))
    assert len(frames) >= 28
    tol = 0.06  # m around each box: 3 sigma of the simulated range noise
    compared, floats = 0, set()
    for frame in frames:
        w = _world_points(world, frame)
        t_mid = float(np.mean(frame.stamp + frame.points["time"].astype(np.float64))) - EPOCH
        inside: dict[int, np.ndarray] = {}
        for body in world.bodies_at(t_mid):
            if body.object_id not in ids:
                continue
            box = body.box
            c, s = np.cos(box.yaw), np.sin(box.yaw)
            dn, de = w[:, 0] - box.center[0], w[:, 1] - box.center[1]
            x, y, up = c * dn + s * de, -s * dn + c * de, -w[:, 2]
            hit = (
                (np.abs(x) <= box.length / 2 + tol)
                & (np.abs(y) <= box.width / 2 + tol)
                & (up >= box.bottom - tol)
                & (up <= box.top + tol)
            )
            oid = ids[body.object_id]
            inside[oid] = inside.get(oid, np.zeros(len(w), bool)) | hit
        for oid, hit in inside.items():
            logged = counts.pop((round(frame.stamp, 6), oid), 0)
            assert int(hit.sum()) == logged, (frame.stamp - EPOCH, oid)
            compared += logged > 0
            if logged and kinds.get(oid) in FLOAT_KINDS:
                floats.add(oid)
    assert not counts  # every logged rotation was a decoded one
    assert compared > 100 and len(floats) >= 3


def test_camera_boxes_agree_with_the_projected_corners(rec):
    res, rows = rec
    world = res.world
    names = {v: k for k, v in world.truth_ids().items()}
    movers = {m.object_id: m for m in world.movers}
    cam = default_camera()
    checked = 0
    for r in rows:
        m = movers.get(names[int(r["object_id"])])
        if r["sensor"] != "camera" or m is None or m.kind not in FLOAT_KINDS:
            continue
        if float(r["visible_fraction"]) < 1.0:
            continue
        t = float(r["time"]) - EPOCH
        pose = camera_pose(world, t)
        n, e, yaw = (float(v) for v in m.motion.pose(np.asarray(t)))
        box = place_body(m.bodies[0], n, e, yaw).box
        c, s = np.cos(box.yaw), np.sin(box.yaw)
        corners = np.array(
            [
                [box.center[0] + c * dx - s * dy, box.center[1] + s * dx + c * dy, -z]
                for dx in (-box.length / 2, box.length / 2)
                for dy in (-box.width / 2, box.width / 2)
                for z in (box.bottom, box.top)
            ]
        )
        px = cam.project((corners - pose.position) @ pose.rotation)
        lo, hi = px.min(axis=0), px.max(axis=0)
        if lo.min() < 5 or hi[0] > cam.image_size[0] - 5 or hi[1] > cam.image_size[1] - 5:
            continue  # near the edge the box may be cut
        # the rendered pixels' centres lie within the projected extent, and fill it
        for size, extent in (
            (float(r["width_px"]), hi[0] - lo[0]),
            (float(r["height_px"]), hi[1] - lo[1]),
        ):
            assert size - 1 <= extent + 0.5 and extent <= size + 1.5, (t, r["object_id"])
        assert int(r["count"]) >= 1
        checked += 1
    assert checked > 50


def test_visibility_log_rows_and_format(tmp_path):
    log = VisibilityLog({"bottle0": 0, "vessel1": 3})
    log.lidar(10.25, np.array(["bottle0", "", "water", "bottle0", "vessel1", "moored9"]))

    class Box:
        object_id, x0, y0, x1, y1, pixels, visible_fraction = "bottle0", 3, 4, 7, 6, 6, 0.75

    log.camera(10.2, [Box()])
    assert log.write(tmp_path / "v.csv") == 3
    with open(tmp_path / "v.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert tuple(rows[0]) == VISIBILITY_COLUMNS
    assert rows[1:] == [
        ["10.200000", "0", "camera", "6", "4.0", "2.0", "0.75"],
        ["10.250000", "0", "lidar", "2", "", "", ""],
        ["10.250000", "3", "lidar", "1", "", "", ""],
    ]
    with pytest.raises(TypeError, match="ids"):
        VisibilityLog(["bottle0"])  # type: ignore[arg-type]
