"""The demo network's options for floats of a few pixels: the tiny-box assignment (up to four
stride-8 cells around a 2 px box instead of one), the per-box loss balance (every box the same
total weight), crops centred on small boxes, and the centre-distance recall of small floats."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from usvfast.camera.detect import Detections
from usvfast.camera.harbour_net import HarbourNet, assign, loss
from usvfast.camera.train_demo import Frame, Sample, random_crop, small_recall


@pytest.fixture(scope="module")
def net():
    return HarbourNet(3, (160, 96), width=4)


def test_tiny_box_takes_the_cells_within_one_stride(net):
    centres, strides = net.grids()
    box = torch.tensor([[100.0, 50.0, 102.0, 52.0]])  # 2 x 2 px, centre (101, 51)
    _, _, pos1, _ = assign(net, [box], [torch.tensor([1])])
    _, box_t, pos4, w = assign(net, [box], [torch.tensor([1])], tiny_px=8.0)
    assert int(pos1.sum()) == 1  # only the cell holding the centre
    cells = centres[:, pos4[0]].T.tolist()
    # stride-8 centres at 4 + 8k: x 100 and 108, y 44 and 52 are within 8 px of (101, 51)
    assert sorted(map(tuple, cells)) == [(100, 44), (100, 52), (108, 44), (108, 52)]
    assert bool((strides[pos4[0]] == 8).all())
    torch.testing.assert_close(box_t[0][:, pos4[0]], box.T.expand(4, 4))
    assert torch.equal(w, pos4.float())  # no balance: weight 1 at every positive
    # a box longer than tiny_px keeps the central-region assignment
    long = torch.tensor([[90.0, 50.0, 102.0, 52.0]])
    a = assign(net, [long], [torch.tensor([0])])[2]
    b = assign(net, [long], [torch.tensor([0])], tiny_px=8.0)[2]
    assert torch.equal(a, b)


def test_balance_gives_every_box_the_same_weight(net):
    boxes = torch.tensor([[10.0, 10.0, 60.0, 40.0], [120.0, 60.0, 122.0, 62.0]])
    _, _, pos, w = assign(net, [boxes], [torch.tensor([0, 2])], tiny_px=8.0, balance=True)
    assert torch.allclose(w[pos].mean(), torch.tensor(1.0))
    centres, _ = net.grids()
    tiny = pos[0] & (centres[0] > 100)
    big = pos[0] & (centres[0] < 100)
    assert int(big.sum()) == 6 and int(tiny.sum()) == 4
    torch.testing.assert_close(w[0, tiny].sum(), w[0, big].sum())
    assert float(w[~pos].abs().sum()) == 0.0


def test_loss_options_change_the_loss_and_backpropagate(net):
    torch.manual_seed(0)
    x = torch.rand(2, 3, 96, 160)
    boxes = [
        torch.tensor([[10.0, 10.0, 60.0, 40.0], [120.0, 60.0, 122.0, 62.0]]),
        torch.zeros(0, 4),
    ]
    classes = [torch.tensor([0, 2]), torch.zeros(0, dtype=torch.int64)]
    plain, _ = loss(net, x, boxes, classes)
    tuned, parts = loss(net, x, boxes, classes, tiny_px=8.0, balance=True)
    assert torch.isfinite(tuned) and set(parts) == {"cls", "l1", "giou"}
    assert abs(float(plain.detach()) - float(tuned.detach())) > 1e-4
    tuned.backward()
    assert all(p.grad is not None for p in net.parameters() if p.requires_grad)


def test_crops_centre_on_small_boxes_when_asked():
    boxes = np.array([[10.0, 10, 40, 40], [300, 170, 302, 172]])  # a 30 px box, a 2 px box
    s = Sample(np.zeros((192, 320, 3), np.uint8), boxes, np.array([0, 0]))

    def share(small_weight):
        rng = np.random.default_rng(2)
        crops = [random_crop(s, (96, 64), rng, None, 4.0, small_weight) for _ in range(400)]
        return np.mean([any(np.min(b[:, 2:] - b[:, :2], 1) < 4) for _, b, _ in crops])

    assert share(8.0) > 0.6 > 0.5 > share(1.0)


def test_small_recall_by_centre_distance():
    boxes = np.array([[10, 10, 12, 12], [50, 50, 52, 52], [80, 10, 83, 12], [0, 40, 30, 60.0]])
    frame = Frame(np.zeros((64, 96, 3), np.uint8), boxes, np.array([0, 1, 5, 0]))
    # box 0 found 1.5 px off (IoU 0.14, still found); box 1's detection is 2.5 px off; box 2
    # is a small moored boat (not a float kind); box 3 is not small
    det = Detections(
        np.array([[11.5, 10, 13.5, 12], [52.5, 50, 54.5, 52], [80, 10, 83, 12.0]]),
        np.array([0.9, 0.8, 0.7]),
        np.array([0, 1, 5]),
    )
    m = small_recall(lambda _: [det], [frame], min_box_px=3.0)
    assert m == {"small_truth": 2, "small_found": 1, "small_recall": 0.5}
    m = small_recall(lambda _: [det], [frame], min_box_px=3.0, max_offset_px=3.0)
    assert m["small_found"] == 2
