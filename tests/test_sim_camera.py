"""The harbour renderer: pixel boxes against the lens projection of the true objects, and
occlusion by a wall."""

from __future__ import annotations

import numpy as np
import pytest

from usvfast.lidar.simulator import Box, Wall
from usvfast.sim.camera import HarbourRenderer, camera_pose, default_camera, render_frame
from usvfast.sim.motion import DriftMotion, PathMotion, Waves
from usvfast.sim.scene import Body, Mover, World, make_world


def _still(n: float, e: float) -> DriftMotion:
    return DriftMotion(np.array([n, n]), np.array([e, e]), np.array([0.3, 0.3]), 100.0)


def _float(k: int, n: float, e: float) -> Mover:
    body = Body(Box((0.0, 0.0), 0.4, 0.3, 0.0, 0.0, 0.15), f"box{k}", "box", (60, 60, 200), 40.0)
    return Mover(f"box{k}", "box", _still(n, e), [body], (0.4, 0.3, 0.15))


def _tiny_world(walls: list[Body]) -> World:
    """A USV parked at the origin heading north on a calm sea, two boxes ahead of it."""
    usv = PathMotion(np.array([[0.0, 0.0], [1.0, 0.0]]), speed=0.0, closed=False)
    calm = Waves(np.zeros((3, 1)), np.ones((3, 1)), np.zeros((3, 1)))
    movers = [_float(0, 8.0, -1.0), _float(1, 12.0, 2.0)]
    return World(0, 10.0, walls, [], movers, usv, calm, [])


def _corner_box(world: World, renderer: HarbourRenderer, mover: Mover, t: float):
    """Bounding box (x0, y0, x1, y1) of the lens projection of the mover's box corners."""
    pose = camera_pose(world, t)
    n, e, yaw = (float(v) for v in mover.motion.pose(np.asarray(t)))
    s = mover.bodies[0].shape
    c, si = np.cos(yaw + s.yaw), np.sin(yaw + s.yaw)
    pts = []
    for a in (-0.5, 0.5):
        for b in (-0.5, 0.5):
            for z in (s.bottom, s.top):
                pn = n + a * s.length * c - b * s.width * si
                pe = e + a * s.length * si + b * s.width * c
                pts.append([pn, pe, -z])
    cam = (np.array(pts) - pose.position) @ pose.rotation
    px = renderer.camera.project(cam)
    # pixel centres are at integers; a box's pixel squares reach half a pixel further
    return px[:, 0].min() + 0.5, px[:, 1].min() + 0.5, px[:, 0].max() + 0.5, px[:, 1].max() + 0.5


def test_boxes_match_the_projected_objects():
    world = _tiny_world([])
    renderer = HarbourRenderer(world, noise=0.0, blur_sigma=0.0)
    image, boxes = renderer.render(1.0)
    assert image.shape == (360, 640, 3) and image.dtype == np.uint8
    assert sorted(b.object_id for b in boxes) == ["box0", "box1"]
    for b in boxes:
        mover = next(m for m in world.movers if m.object_id == b.object_id)
        ref = _corner_box(world, renderer, mover, 1.0)
        assert b.visible_fraction == 1.0
        assert np.allclose(b.xyxy, ref, atol=1.0), (b, ref)
        # the object is drawn in its own colour (red-ish BGR (60, 60, 200), shaded)
        patch = image[int(b.y0) : int(b.y1), int(b.x0) : int(b.x1)].reshape(-1, 3)
        assert (patch[:, 2].astype(int) - patch[:, 0] > 40).any()


def test_a_wall_hides_the_object_behind_it():
    # a 1 m wall at 10 m north across east 1..3 m hides box1 (12 m north, 2 m east) only
    wall = Body(Wall(np.array([[10.0, 1.0], [10.0, 3.0]]), 1.0), "", "wall", (150, 150, 150), 60)
    _, boxes = HarbourRenderer(_tiny_world([wall]), noise=0.0).render(1.0)
    assert [b.object_id for b in boxes] == ["box0"]
    # half as high, it hides only the lower part of box1: a box remains, partly visible
    low = Body(Wall(np.array([[10.0, 1.0], [10.0, 3.0]]), 0.25), "", "wall", (150, 150, 150), 60)
    _, boxes = HarbourRenderer(_tiny_world([low]), noise=0.0).render(1.0)
    part = {b.object_id: b.visible_fraction for b in boxes}
    assert part["box0"] == 1.0 and 0.0 < part.get("box1", 0.0) < 1.0


def test_render_frame_of_a_harbour_has_trash_boxes_at_true_positions():
    world = make_world(3, 20.0)
    camera = default_camera()
    _image, boxes = render_frame(3, 6.0, world=world, camera=camera)
    trash = [b for b in boxes if b.kind in ("bottle", "bag", "box")]
    assert trash, "the harbour of seed 3 has trash in view at 6 s"
    renderer = HarbourRenderer(world, camera)
    for b in trash:
        if b.visible_fraction < 1.0:
            continue
        mover = next(m for m in world.movers if m.object_id == b.object_id)
        ref = _corner_box(world, renderer, mover, 6.0)
        assert np.allclose(b.xyxy, ref, atol=1.0), (b, ref)


def test_bad_camera_size():
    with pytest.raises(ValueError, match="width, height"):
        default_camera(8, 8)
