"""Bow waves and wakes of vessels under way in the rendered harbour frames."""

import numpy as np

from usvfast.sim import HarbourRenderer, make_world
from usvfast.sim.wake import foam, mover_speed, splash_boxes


def test_foam_lies_behind_and_beside_a_moving_hull_and_grows_with_speed():
    length, beam = 6.0, 2.2
    # points on the track behind the transom, far ahead, and far abeam
    behind = foam(np.array([-4.0, -5.0]), np.array([0.0, 0.3]), length=6, beam=2.2, speed=2.0)
    assert (behind > 0.2).all()
    ahead = foam(np.array([8.0, 0.0, 1e4]), np.array([0.0, 6.0, 0.0]), length=6, beam=2.2, speed=2)
    assert (ahead == 0).all()
    assert (foam(np.array([-4.0]), np.array([0.0]), length=6, beam=2.2, speed=0.0) == 0).all()
    # 7 m behind the transom: beyond a 1 m/s trail (3 m), inside a 2.5 m/s one (7.5 m)
    x, y = np.array([-10.0]), np.array([0.0])
    assert foam(x, y, length=length, beam=beam, speed=1.0)[0] == 0
    assert foam(x, y, length=length, beam=beam, speed=2.5)[0] > 0
    # brighter when faster
    near = np.array([-3.5]), np.array([0.0])
    assert foam(*near, length=6, beam=2.2, speed=2.0) > foam(*near, length=6, beam=2.2, speed=0.8)


def test_a_vessel_under_way_leaves_foam_and_moored_boats_none():
    world = make_world(1002, 60.0)
    (vessel,) = [m for m in world.movers if m.kind == "vessel"][:1]
    t = 16.0  # the vessel about 15 m ahead, broadside
    assert mover_speed(vessel, t) > 1.4
    assert len(splash_boxes(vessel, t)) == 2
    with_wake, boxes = HarbourRenderer(world).render(t)
    plain, boxes_plain = HarbourRenderer(world, wakes=False).render(t)
    assert [b.object_id for b in boxes] == [b.object_id for b in boxes_plain]
    diff = with_wake.astype(int) - plain.astype(int)
    changed = np.abs(diff).max(axis=2) > 30
    assert changed.sum() > 50
    assert diff[changed].mean() > 30  # white water: brighter than the sea and the hull
    rows, cols = np.nonzero(changed)
    (vbox,) = [b for b in boxes if b.object_id == vessel.object_id]
    # all of it at the vessel: within its box widened by its 0.8 x speed m wash
    assert cols.min() >= vbox.x0 - 40 and cols.max() <= vbox.x1 + 40
    assert rows.min() >= vbox.y0 and rows.max() <= vbox.y1 + 15
    # a harbour of moored boats only renders the same with and without wakes
    still = make_world(1002, 60.0, vessels=0)
    for tt in (4.0, 30.0):
        a, seen = HarbourRenderer(still).render(tt)
        b, _ = HarbourRenderer(still, wakes=False).render(tt)
        assert sum(s.kind == "moored_boat" for s in seen) >= 3
        assert np.array_equal(a, b)
