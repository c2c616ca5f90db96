"""SSD with a MobileNetV2 feature extractor (Liu et al., SSD, ECCV 2016; Sandler et al.,
MobileNetV2, CVPR 2018) in torch, built from the COCO-trained frozen graph of the TensorFlow
Object Detection API (`ssd_mobilenet_v2_coco_2018_03_29`, Apache 2.0) read by
:mod:`usvfast.shore.tfgraph`; every layer's kind, stride and activation is read from the graph.

* Input: RGB scaled to [−1, 1] (x · 2/255 − 1, the graph's preprocessor), 300 × 300 for the
  COCO weights (any size whose feature maps stay ≥ 1 px runs; the anchors follow the maps).
* Feature maps: MobileNetV2's `expanded_conv_13/expansion_output` (stride 16) and `Conv_1`
  (stride 32), then four extra layers (1×1, depthwise 3×3 stride 2, 1×1).
* Batch normalisation is folded into the convolutions (frozen statistics, as in the graph).
* Heads: 3×3 convolutions per map, k anchors per cell (3 on the first map, 6 after); box codes
  (ty, tx, th, tw) of the Faster R-CNN box coder (scales 10, 10, 5, 5) and one sigmoid logit
  per kept class (the graph has 91: background + the 90 COCO ids; `classes` keeps the chosen
  ids' channels, 9 = "boat", which is 8 in the 0-based 80-class list).
* Anchors: the SSD anchor generator of the graph (scales 0.2–0.95 over 6 maps, aspect ratios
  1, 2, ½, 3, 0.3333 (the graph's constant for ⅓) plus the interpolated scale; 0.1 / 2 / ½ on
  the lowest map), normalised (y, x, h, w) in [0, 1].

TensorFlow's SAME padding (extra row/column at the bottom/right for stride 2) is reproduced.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from usvfast.shore.tfgraph import FrozenGraph

#: Name prefix of the feature extractor in the graph.
PREFIX = "FeatureExtractor/MobilenetV2/"
#: Box-coder scale factors (y, x, h, w) of the graph's Faster R-CNN box coder.
BOX_SCALES = (10.0, 10.0, 5.0, 5.0)
#: The COCO weights' input size (width, height).
COCO_INPUT = (300, 300)
#: COCO id of "boat" in the graph's 1-based 90-id label map (8 in the 0-based 80 classes).
COCO_BOAT = 9


def same_pads(size: int, kernel: int, stride: int) -> tuple[int, int]:
    """TensorFlow SAME padding (before, after) of one axis of `size` px."""
    out = -(-size // stride)
    total = max((out - 1) * stride + kernel - size, 0)
    return total // 2, total - total // 2


class ConvUnit(nn.Module):
    """One convolution of the graph with its batch norm folded in, SAME padding and an
    optional ReLU6. `weight` (out, in/groups, k, k), `bias` (out,)."""

    def __init__(self, weight: np.ndarray, bias: np.ndarray, stride: int, groups: int, relu6: bool):
        super().__init__()
        out, inp, k, _ = weight.shape
        self.conv = nn.Conv2d(inp * groups, out, k, stride, 0, groups=groups, bias=True)
        self.conv.weight = nn.Parameter(torch.from_numpy(weight.copy()))
        self.conv.bias = nn.Parameter(torch.from_numpy(bias.copy()))
        self.stride, self.kernel, self.relu6 = stride, k, relu6

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.kernel > 1:
            t, b = same_pads(int(x.shape[2]), self.kernel, self.stride)
            left, right = same_pads(int(x.shape[3]), self.kernel, self.stride)
            x = F.pad(x, (left, right, t, b))
        x = self.conv(x)
        return F.relu6(x) if self.relu6 else x


def _unit(graph: FrozenGraph, prefix: str, names: set[str], keep=None) -> ConvUnit:
    """The ConvUnit of graph scope `prefix` (weights, BatchNorm or biases, stride, ReLU6);
    `keep` selects output channels (heads)."""
    c = graph.constants
    if prefix + "/depthwise_weights" in c:
        w = c[prefix + "/depthwise_weights"].transpose(2, 3, 0, 1)  # (k,k,C,1) -> (C,1,k,k)
        groups, op = w.shape[0], prefix + "/depthwise"
    else:
        w = c[prefix + "/weights"].transpose(3, 2, 0, 1)  # HWIO -> OIHW
        groups, op = 1, prefix + "/Conv2D"
    if prefix + "/BatchNorm/gamma" in c:
        bn = prefix + "/BatchNorm/"
        eps = float(c[bn + "batchnorm/add/y"])
        gain = c[bn + "gamma"] / np.sqrt(c[bn + "moving_variance"] + eps)
        w = w * gain[:, None, None, None]
        b = c[bn + "beta"] - c[bn + "moving_mean"] * gain
    else:
        b = c[prefix + "/biases"]
    if keep is not None:
        w, b = w[keep], b[keep]
    stride = int(graph.node(op).attrs["strides"][1])
    relu6 = prefix + "/Relu6" in names
    return ConvUnit(
        np.ascontiguousarray(w, dtype=np.float32), b.astype(np.float32), stride, groups, relu6
    )


class SsdMobileNetV2(nn.Module):
    """The SSD network: `forward(x)` with x (B, 3, H, W) RGB in [−1, 1] -> box codes
    (B, A, 4) (ty, tx, th, tw) and class logits (B, A, C), A anchors in the order of
    :func:`ssd_anchors` for the feature-map sizes of `feature_sizes(H, W)`.

    Build it with :meth:`from_graph`. `classes` are the COCO ids whose logits are kept."""

    def __init__(self, blocks, tap: int, extras, box_heads, class_heads, anchors_per_cell, classes):
        super().__init__()
        self.blocks = nn.ModuleList(nn.Sequential(*units) for units, _ in blocks)
        self.residual = [res for _, res in blocks]
        self.tap = tap
        self.extras = nn.ModuleList(nn.Sequential(*u) for u in extras)
        self.box_heads = nn.ModuleList(box_heads)
        self.class_heads = nn.ModuleList(class_heads)
        self.anchors_per_cell = tuple(anchors_per_cell)
        self.classes = tuple(int(c) for c in classes)

    @classmethod
    def from_graph(cls, graph: FrozenGraph, classes: Sequence[int] = (COCO_BOAT,)):
        """The network of the COCO graph, keeping the logits of COCO ids `classes` (1–90).
        Raises ValueError when an id is out of range or the graph is not this detector."""
        classes = [int(c) for c in classes]
        if not classes or any(not 1 <= c <= 90 for c in classes):
            raise ValueError(f"classes: COCO ids in 1..90 expected, got {classes}")
        names = {n.name for n in graph.nodes}
        if PREFIX + "Conv/weights" not in graph.constants:
            raise ValueError("graph: not the SSD-MobileNetV2 COCO graph (no MobilenetV2/Conv)")
        p = PREFIX
        blocks = [([_unit(graph, p + "Conv", names)], False)]
        tap = None
        for i in range(17):
            scope = p + ("expanded_conv" if i == 0 else f"expanded_conv_{i}")
            units = [
                _unit(graph, f"{scope}/{part}", names)
                for part in ("expand", "depthwise", "project")
                if f"{scope}/{part}/weights" in graph.constants
                or f"{scope}/{part}/depthwise_weights" in graph.constants
            ]
            if i == 13:
                # the first feature map is this block's expansion output: split the block
                # there (the block has no residual: stride 1 but 96 -> 160 channels)
                if f"{scope}/add" in names:
                    raise ValueError("graph: expanded_conv_13 unexpectedly residual")
                blocks.append(([units[0]], False))
                tap = len(blocks) - 1
                blocks.append((units[1:], False))
            else:
                blocks.append((units, f"{scope}/add" in names))
        blocks.append(([_unit(graph, p + "Conv_1", names)], False))
        if tap is None:
            raise ValueError("graph: no expanded_conv_13/expansion_output feature map")
        found = {m.group(1) for k in graph.constants if (m := re.match(rf"{p}(layer_19_\S+?)/", k))}

        def order(name: str) -> tuple[int, bool, bool]:
            # per extra layer: 1x1 reduction, depthwise 3x3 stride 2, 1x1 expansion
            m = re.search(r"Conv2d_(\d+)", name)
            return (int(m.group(1)) if m else 0, "_1x1" not in name, "_depthwise" not in name)

        extra_names = sorted(found, key=order)
        extras = [
            [_unit(graph, p + n, names) for n in extra_names[i : i + 3]]
            for i in range(0, len(extra_names), 3)
        ]
        box_heads, class_heads, per_cell = [], [], []
        for i in range(len(extras) + 2):
            b = f"BoxPredictor_{i}/"
            k = graph.constants[b + "BoxEncodingPredictor/biases"].shape[0] // 4
            per_cell.append(k)
            box_heads.append(_unit(graph, b + "BoxEncodingPredictor", names))
            keep = [a * 91 + c for a in range(k) for c in classes]
            class_heads.append(_unit(graph, b + "ClassPredictor", names, keep))
        return cls(blocks, tap, extras, box_heads, class_heads, per_cell, classes)

    def stem(self, x: torch.Tensor, end: int | None = None) -> torch.Tensor:
        """The blocks before block `end` (default: the first feature map's block, stride 16,
        96 channels): the part :mod:`usvfast.shore.ssd_train` keeps frozen."""
        end = self.tap if end is None else end
        for block, res in zip(self.blocks[:end], self.residual[:end], strict=True):
            y = block(x)
            x = x + y if res else y
        return x

    def maps(self, x: torch.Tensor, start: int | None = None) -> list[torch.Tensor]:
        """The six feature maps from x, the output of :meth:`stem` with `end=start`."""
        start = self.tap if start is None else start
        if not 0 <= start <= self.tap:
            raise ValueError(f"start: expected 0..{self.tap}, got {start}")
        out = []
        for i in range(start, len(self.blocks)):
            y = self.blocks[i](x)
            x = x + y if self.residual[i] else y
            if i == self.tap:
                out.append(x)
        out.append(x)
        for e in self.extras:
            x = e(x)
            out.append(x)
        return out

    def heads(self, maps: list[torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
        """Box codes (B, A, 4) and class logits (B, A, C) of the six feature maps."""
        b = maps[0].shape[0]
        boxes, logits = [], []
        n = len(self.classes)
        for f, bh, ch in zip(maps, self.box_heads, self.class_heads, strict=True):
            boxes.append(bh(f).permute(0, 2, 3, 1).reshape(b, -1, 4))
            logits.append(ch(f).permute(0, 2, 3, 1).reshape(b, -1, n))
        return torch.cat(boxes, 1), torch.cat(logits, 1)

    def features(self, x: torch.Tensor) -> list[torch.Tensor]:
        """The six feature maps of x (B, 3, H, W)."""
        return self.maps(self.stem(x))

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.heads(self.features(x))

    def feature_sizes(self, height: int, width: int) -> list[tuple[int, int]]:
        """(h, w) of the six feature maps for an input of height × width px."""
        sizes = []
        h, w = height, width
        for i, block in enumerate(self.blocks):
            for u in _units(block):
                h, w = -(-h // u.stride), -(-w // u.stride)
            if i == self.tap:
                sizes.append((h, w))
        sizes.append((h, w))
        for e in self.extras:
            for u in _units(e):
                h, w = -(-h // u.stride), -(-w // u.stride)
            sizes.append((h, w))
        return sizes


def _units(seq: nn.Module) -> list[ConvUnit]:
    """The ConvUnits of a block or extra layer, in order."""
    return [m for m in seq.children() if isinstance(m, ConvUnit)]


def ssd_anchors(
    sizes: Sequence[tuple[int, int]],
    min_scale: float = 0.2,
    max_scale: float = 0.95,
    aspect_ratios: Sequence[float] = (1.0, 2.0, 0.5, 3.0, 0.3333),
) -> np.ndarray:
    """(A, 4) normalised anchors (y centre, x centre, h, w) of the graph's SSD anchor generator
    for feature maps `sizes` [(h, w), ...]: per map i, scale s_i = min + (max − min) i/(n − 1);
    boxes (s_i, ar) for every aspect ratio plus (√(s_i s_{i+1}), 1), except the lowest map:
    (0.1, 1), (s_0, 2), (s_0, ½); h = s/√ar, w = s·√ar; centres at (j + ½)/size; ordered by
    row, column, box."""
    n = len(sizes)
    scales = [min_scale + (max_scale - min_scale) * i / (n - 1) for i in range(n)] + [1.0]
    out = []
    for i, (fh, fw) in enumerate(sizes):
        if i == 0:
            specs = [(0.1, 1.0), (scales[0], 2.0), (scales[0], 0.5)]
        else:
            specs = [(scales[i], a) for a in aspect_ratios]
            specs.append((math.sqrt(scales[i] * scales[i + 1]), 1.0))
        hw = np.array([(s / math.sqrt(a), s * math.sqrt(a)) for s, a in specs])
        yc = (np.arange(fh) + 0.5) / fh
        xc = (np.arange(fw) + 0.5) / fw
        gy, gx = np.meshgrid(yc, xc, indexing="ij")
        cell = np.stack([gy.ravel(), gx.ravel()], 1)  # (fh*fw, 2)
        a = np.concatenate(
            [np.repeat(cell, len(specs), 0), np.tile(hw, (fh * fw, 1))], 1
        )  # row, column, box
        out.append(a)
    return np.concatenate(out).astype(np.float32)


def decode_boxes(codes: torch.Tensor, anchors: torch.Tensor) -> torch.Tensor:
    """Box codes (..., A, 4) (ty, tx, th, tw) on anchors (A, 4) -> normalised corners
    (..., A, 4) (x1, y1, x2, y2) (Faster R-CNN box coder, scales :data:`BOX_SCALES`)."""
    sy, sx, sh, sw = BOX_SCALES
    ya, xa, ha, wa = anchors.unbind(-1)
    ty, tx, th, tw = codes.unbind(-1)
    yc = ty / sy * ha + ya
    xc = tx / sx * wa + xa
    h = torch.exp(th / sh) * ha
    w = torch.exp(tw / sw) * wa
    return torch.stack([xc - w / 2, yc - h / 2, xc + w / 2, yc + h / 2], -1)


def encode_boxes(boxes: torch.Tensor, anchors: torch.Tensor) -> torch.Tensor:
    """Normalised corners (A, 4) (x1, y1, x2, y2) -> codes (A, 4) on anchors (A, 4), the
    inverse of :func:`decode_boxes`."""
    sy, sx, sh, sw = BOX_SCALES
    ya, xa, ha, wa = anchors.unbind(-1)
    w = (boxes[:, 2] - boxes[:, 0]).clamp_min(1e-6)
    h = (boxes[:, 3] - boxes[:, 1]).clamp_min(1e-6)
    xc = (boxes[:, 0] + boxes[:, 2]) / 2
    yc = (boxes[:, 1] + boxes[:, 3]) / 2
    return torch.stack(
        [(yc - ya) / ha * sy, (xc - xa) / wa * sx, torch.log(h / ha) * sh, torch.log(w / wa) * sw],
        -1,
    )


class SsdExport(nn.Module):
    """The network with its anchors baked in for one input size, for ONNX: x (B, 3, H, W) in
    [−1, 1] -> (B, A, 4 + C): normalised corners (x1, y1, x2, y2) and sigmoid scores."""

    def __init__(self, net: SsdMobileNetV2, height: int, width: int):
        super().__init__()
        self.net = net
        a = ssd_anchors(net.feature_sizes(height, width))
        self.register_buffer("anchors", torch.from_numpy(a))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        codes, logits = self.net(x)
        return torch.cat([decode_boxes(codes, self.anchors), torch.sigmoid(logits)], -1)  # pyright: ignore[reportArgumentType]
