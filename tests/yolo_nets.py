"""Small randomly initialised YOLO-layout networks for tests and benches (no downloaded weights).

`KnownBoxesYolo` is a real conv backbone with strides 8/16/32 and a per-anchor head (8400
anchors at 640x640), whose scores are pushed far below any threshold, plus a buffer of known
predictions written into the first anchors: the decoder, letterbox inverse and NMS must recover
exactly the boxes encoded there.
"""

from __future__ import annotations

import torch
from torch import nn


class KnownBoxesYolo(nn.Module):
    def __init__(self, known: torch.Tensor, nc: int = 3, layout: str = "v8", seed: int = 0):
        """`known` (N, K, 4 + nc) for v8 or (N, K, 5 + nc) for v5: cx, cy, w, h[, obj], scores."""
        super().__init__()
        g = torch.Generator().manual_seed(seed)
        self.layout = layout
        self.nc = nc
        ch = 4 + nc if layout == "v8" else 5 + nc
        self.stem = nn.Sequential(
            nn.Conv2d(3, 16, 3, 2, 1),
            nn.SiLU(),
            nn.Conv2d(16, 32, 3, 2, 1),
            nn.SiLU(),
            nn.Conv2d(32, 32, 3, 2, 1),
            nn.SiLU(),
        )
        self.down16 = nn.Sequential(nn.Conv2d(32, 64, 3, 2, 1), nn.SiLU())
        self.down32 = nn.Sequential(nn.Conv2d(64, 64, 3, 2, 1), nn.SiLU())
        self.heads = nn.ModuleList([nn.Conv2d(c, ch, 1) for c in (32, 64, 64)])
        for p in self.parameters():
            with torch.no_grad():
                p.copy_(torch.randn(p.shape, generator=g) * 0.1)
        self.register_buffer("known", known.float())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        f8 = self.stem(x)
        f16 = self.down16(f8)
        f32 = self.down32(f16)
        outs = []
        for f, head, stride in zip((f8, f16, f32), self.heads, (8, 16, 32), strict=True):
            y = head(f)  # (N, ch, H, W)
            _, _, h, w = y.shape
            gy, gx = torch.meshgrid(torch.arange(h), torch.arange(w), indexing="ij")
            y = y.flatten(2)
            xy = (torch.stack([gx, gy]).flatten(1).float() + 0.5) * stride + y[:, :2]
            wh = torch.exp(y[:, 2:4].clamp(-4, 4)) * stride
            scores = torch.sigmoid(y[:, 4:] - 12.0)  # far below any confidence threshold
            outs.append(torch.cat([xy, wh, scores], dim=1))
        out = torch.cat(outs, dim=2)  # (N, ch, A): the v8 layout
        k = self.known.shape[1]
        out = torch.cat([self.known.transpose(1, 2).to(out.dtype), out[:, :, k:]], dim=2)
        return out if self.layout == "v8" else out.transpose(1, 2).contiguous()
