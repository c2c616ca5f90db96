"""A small anchor-free grid detector for the harbour demo (torch), its target assignment and loss.

The network is a plain conv backbone (strides 2, 4, 8, 16) with two prediction grids, stride 8
for small objects and stride 16 for large ones. Each grid cell predicts a box centre offset,
log width and height, and one sigmoid score per class; the forward pass decodes them into the
YOLOv8 output layout `(N, 4 + nc, A)` (cx, cy, w, h in input pixels, class scores), so the
shared decoding of :mod:`usvfast.camera.detect` and both backends run it unchanged.

The grids are buffers built for one `input_size`: the traced/exported network takes exactly
(N, 3, height, width) and refuses other shapes.

Training (FCOS/YOLOX-style, simplified): a ground-truth box goes to the stride-8 grid when its
longer side is under `split_px` pixels, else to the stride-16 grid; the cells of that grid
whose centres lie within the box's central region (radius `radius` cells around the box
centre, clipped to the box, always including the centre cell) are positives. Loss = focal
binary cross-entropy of the class scores over all cells (normalised by the positives) +
L1 of the centre offsets and log sizes at the positives + (1 - GIoU) at the positives.

Two options for objects of a few pixels (both off by default): `tiny_px` makes every
stride-8 cell whose centre lies within one stride of a box's centre (in x and in y) a
positive when the box's longer side is under `tiny_px` (up to four cells instead of the one
cell a 2 px box covers), and `balance` gives every box the same total weight in the loss
(its cells share it), so that a 2 px float counts as much as a 60 px hull with 20 cells.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

STRIDES = (8, 16)


def _conv(c_in: int, c_out: int, stride: int = 1) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, 3, stride, 1, bias=False), nn.BatchNorm2d(c_out), nn.SiLU()
    )


class HarbourNet(nn.Module):
    """The demo detector: input (N, 3, h, w) RGB in [0, 1] with (w, h) = `input_size`, output
    (N, 4 + nc, A) in the YOLOv8 layout (A = cells of the stride-8 and stride-16 grids).

    `num_classes` nc; `width` scales the channel counts (16 -> about 0.2 M parameters).
    """

    def __init__(self, num_classes: int, input_size: tuple[int, int], width: int = 16) -> None:
        super().__init__()
        w, h = (int(v) for v in input_size)
        if w % 16 or h % 16:
            raise ValueError(f"input_size: width and height must be multiples of 16, got {w, h}")
        self.num_classes = int(num_classes)
        self.input_size = (w, h)
        c = width
        self.down4 = nn.Sequential(_conv(3, c, 2), _conv(c, 2 * c, 2), _conv(2 * c, 2 * c))
        self.down8 = nn.Sequential(_conv(2 * c, 3 * c, 2), _conv(3 * c, 3 * c))
        self.down16 = nn.Sequential(_conv(3 * c, 4 * c, 2), _conv(4 * c, 4 * c))
        self.up = nn.Sequential(nn.Conv2d(4 * c, 3 * c, 1), nn.Upsample(scale_factor=2.0))
        self.fuse8 = _conv(3 * c, 3 * c)
        out = 4 + self.num_classes
        self.head8 = nn.Conv2d(3 * c, out, 1)
        self.head16 = nn.Conv2d(4 * c, out, 1)
        prior = -4.6  # class scores start near sigmoid(-4.6) = 0.01 (focal-loss prior)
        for head in (self.head8, self.head16):
            nn.init.zeros_(head.weight)
            with torch.no_grad():
                head.bias.zero_()  # pyright: ignore[reportOptionalMemberAccess]
                head.bias[4:] = prior  # pyright: ignore[reportOptionalSubscript]
        for s in STRIDES:
            gy, gx = torch.meshgrid(torch.arange(h // s), torch.arange(w // s), indexing="ij")
            centres = (torch.stack([gx, gy]).flatten(1).float() + 0.5) * s  # (2, cells) px
            self.register_buffer(f"centres{s}", centres, persistent=False)

    def grids(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(cell centres (2, A) px, cell strides (A,) px) in the order of the output anchors."""
        cents = [getattr(self, f"centres{s}") for s in STRIDES]
        strides = [torch.full((c.shape[1],), float(s)) for c, s in zip(cents, STRIDES, strict=True)]
        return torch.cat(cents, 1), torch.cat(strides)

    def raw(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Undecoded predictions: (N, 4 + nc, A) = (tx, ty, tw, th, class logits) per cell, and
        the matching (N, 2, A) cell centres."""
        f4 = self.down4(x)
        f8 = self.down8(f4)
        f16 = self.down16(f8)
        p8 = self.head8(self.fuse8(f8 + self.up(f16)))
        p16 = self.head16(f16)
        return torch.cat([p8.flatten(2), p16.flatten(2)], 2), torch.cat(
            [self.centres8, self.centres16],  # pyright: ignore[reportArgumentType]  # (buffers)
            1,
        )

    def decode(self, raw: torch.Tensor) -> torch.Tensor:
        """(N, 4 + nc, A) raw predictions -> (N, 4 + nc, A) boxes cx, cy, w, h px + scores."""
        centres, strides = self.grids()
        strides = strides.to(raw.device)
        xy = centres.to(raw.device) + raw[:, :2] * strides
        wh = torch.exp(raw[:, 2:4].clamp(-6.0, 6.0)) * strides
        return torch.cat([xy, wh, torch.sigmoid(raw[:, 4:])], 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        w, h = self.input_size
        if not torch.jit.is_tracing() and tuple(x.shape[-2:]) != (h, w):  # pyright: ignore[reportPrivateImportUsage]
            raise ValueError(f"x: expected (N, 3, {h}, {w}), got {tuple(x.shape)}")
        return self.decode(self.raw(x)[0])


def assign(
    net: HarbourNet,
    boxes: list[torch.Tensor],
    classes: list[torch.Tensor],
    split_px: float = 48.0,
    radius: float = 1.5,
    tiny_px: float = 0.0,
    balance: bool = False,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Training targets for a batch: per image `boxes` (k, 4) xyxy input px and `classes` (k,).

    Returns (class targets (N, nc, A) in {0, 1}, box targets (N, 4, A) xyxy px, positive mask
    (N, A) bool, positive weights (N, A): 1 at every positive, or with `balance` 1 / (the
    number of cells of the cell's box) scaled to a mean of 1 over the positives). A cell
    claimed by two boxes keeps the smaller box. Boxes whose longer side is under `tiny_px` px
    take every stride-8 cell within one stride of their centre (see the module's doc).
    """
    centres, strides = net.grids()
    n, a = len(boxes), centres.shape[1]
    cls_t = torch.zeros(n, net.num_classes, a)
    box_t = torch.zeros(n, 4, a)
    pos = torch.zeros(n, a, dtype=torch.bool)
    owner = torch.full((n, a), -1, dtype=torch.int64)  # box index (over the batch) per cell
    n_boxes = 0
    for i, (b, c) in enumerate(zip(boxes, classes, strict=True)):
        if len(b) == 0:
            continue
        area = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
        best = torch.full((a,), float("inf"))
        for j in torch.argsort(area, descending=True).tolist():  # smaller boxes overwrite
            x1, y1, x2, y2 = b[j].tolist()
            cx, cy = (x1 + x2) / 2, (y1 + y2) / 2
            level = 8.0 if max(x2 - x1, y2 - y1) < split_px else 16.0
            r = radius * level
            if max(x2 - x1, y2 - y1) < tiny_px:
                inside = (
                    (strides == 8.0)
                    & ((centres[0] - cx).abs() < 8.0)
                    & ((centres[1] - cy).abs() < 8.0)
                )
            else:
                inside = (
                    (strides == level)
                    & (centres[0] >= max(x1, cx - r))
                    & (centres[0] <= min(x2, cx + r))
                    & (centres[1] >= max(y1, cy - r))
                    & (centres[1] <= min(y2, cy + r))
                )
            # The cell containing the centre is always positive (tiny boxes).
            d = (centres[0] - cx).abs().maximum((centres[1] - cy).abs())
            d = torch.where(strides == level, d, torch.full_like(d, float("inf")))
            inside[torch.argmin(d)] = True
            take = inside & (area[j] <= best)
            best[take] = area[j]
            pos[i, take] = True
            owner[i, take] = n_boxes + j
            box_t[i, :, take] = b[j][:, None]
            cls_t[i, :, take] = 0.0
            cls_t[i, int(c[j]), take] = 1.0
        n_boxes += len(b)
    weight = pos.float()
    if balance and pos.any():
        cells = torch.bincount(owner[pos], minlength=n_boxes).float()  # cells each box kept
        w = 1.0 / cells[owner[pos]]
        weight[pos] = w * (len(w) / w.sum())
    return cls_t, box_t, pos, weight


def _giou(p: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """Generalised IoU of paired boxes (4, k) xyxy."""
    iw = (torch.minimum(p[2], t[2]) - torch.maximum(p[0], t[0])).clamp(min=0)
    ih = (torch.minimum(p[3], t[3]) - torch.maximum(p[1], t[1])).clamp(min=0)
    inter = iw * ih
    union = (p[2] - p[0]) * (p[3] - p[1]) + (t[2] - t[0]) * (t[3] - t[1]) - inter
    cw = torch.maximum(p[2], t[2]) - torch.minimum(p[0], t[0])
    ch = torch.maximum(p[3], t[3]) - torch.minimum(p[1], t[1])
    hull = cw * ch + 1e-9
    iou = inter / (union + 1e-9)
    return iou - (hull - union) / hull


def loss(
    net: HarbourNet,
    x: torch.Tensor,
    boxes: list[torch.Tensor],
    classes: list[torch.Tensor],
    tiny_px: float = 0.0,
    balance: bool = False,
) -> tuple[torch.Tensor, dict[str, float]]:
    """Training loss of a batch `x` (N, 3, h, w) with per-image targets (see :func:`assign`,
    which also takes `tiny_px` and `balance`); returns (scalar loss, its parts as floats)."""
    raw, centres = net.raw(x)
    cls_t, box_t, pos, weight = assign(net, boxes, classes, tiny_px=tiny_px, balance=balance)
    npos = max(1.0, float(pos.sum()))
    logits = raw[:, 4:]
    p = torch.sigmoid(logits)
    ce = F.binary_cross_entropy_with_logits(logits, cls_t, reduction="none")
    pt = p * cls_t + (1 - p) * (1 - cls_t)
    alpha = 0.25 * cls_t + 0.75 * (1 - cls_t)
    cell_w = torch.where(pos, weight, torch.ones_like(weight))[:, None]  # (N, 1, A)
    l_cls = (cell_w * alpha * (1 - pt) ** 2 * ce).sum() / npos
    if pos.any():
        wk = weight[pos]  # (k,) positive weights, mean 1
        _, strides = net.grids()
        s = strides[None].expand_as(pos)[pos]  # (k,)
        cxy = centres[None].expand(len(x), -1, -1).permute(0, 2, 1)[pos].T  # (2, k)
        t = box_t.permute(0, 2, 1)[pos].T  # (4, k) xyxy
        txy = ((t[:2] + t[2:]) / 2 - cxy) / s
        twh = torch.log(((t[2:] - t[:2]) / s).clamp(min=1e-3))
        r = raw.permute(0, 2, 1)[pos].T  # (4 + nc, k)
        l_l1 = ((r[:2] - txy).abs() * wk).mean() + ((r[2:4] - twh).abs() * wk).mean()
        pxy = cxy + r[:2] * s
        pwh = torch.exp(r[2:4].clamp(-6.0, 6.0)) * s
        pb = torch.cat([pxy - pwh / 2, pxy + pwh / 2])
        l_iou = ((1 - _giou(pb, t)) * wk).mean()
    else:
        l_l1 = l_iou = raw.sum() * 0.0
    total = l_cls + l_l1 + 2.0 * l_iou
    parts = {"cls": l_cls, "l1": l_l1, "giou": l_iou}
    return total, {k: float(v.detach()) for k, v in parts.items()}


def fit(
    n_classes: int,
    input_size: tuple[int, int],
    crop_size: tuple[int, int],
    width: int,
    *,
    steps: int,
    lr: float,
    seed: int,
    batch: Callable[[np.random.Generator], list[tuple[np.ndarray, np.ndarray, np.ndarray]]],
    log: Callable[[str], None],
    log_every: int,
    tiny_px: float = 0.0,
    balance: bool = False,
) -> HarbourNet:
    """Train a HarbourNet of `input_size` on crops of `crop_size` (same weights, grids sized
    for the crops): AdamW + one-cycle learning rate over `steps`, seeded by `seed` (torch and
    the numpy generator handed to `batch`). `batch(rng)` returns the step's samples, each
    (image (h, w, 3) float32 RGB in [0, 1], boxes (k, 4) px, classes (k,)); `tiny_px` and
    `balance` are :func:`assign`'s. Returns the `input_size` network in eval mode."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    net = HarbourNet(n_classes, input_size, width)
    crop_net = HarbourNet(n_classes, crop_size, width)
    crop_net.load_state_dict(net.state_dict())
    opt = torch.optim.AdamW(crop_net.parameters(), lr=lr, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=lr, total_steps=steps, pct_start=0.1)
    crop_net.train()
    t0 = time.perf_counter()
    for step in range(steps):
        samples = batch(rng)
        x = torch.from_numpy(np.stack([s[0] for s in samples]).transpose(0, 3, 1, 2).copy())
        boxes = [torch.from_numpy(s[1].astype(np.float32)) for s in samples]
        classes = [torch.from_numpy(s[2].astype(np.int64)) for s in samples]
        total, parts = loss(crop_net, x.float(), boxes, classes, tiny_px, balance)
        opt.zero_grad()
        total.backward()
        opt.step()
        sched.step()
        if step % log_every == 0 or step == steps - 1:
            log(
                f"step {step:4d}/{steps}  loss {float(total.detach()):.3f}  "
                + "  ".join(f"{k} {v:.3f}" for k, v in parts.items())
                + f"  {time.perf_counter() - t0:.0f} s"
            )
    net.load_state_dict(crop_net.state_dict())
    return net.eval()
