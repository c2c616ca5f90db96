"""A temporal change detector for fixed or slowly panning shore cameras: what moves against
the registered background of the neighbouring frames is a boat candidate.

Per frame of a video (frames in time order, analysed at a working width):

1. every frame is registered to the one before it (:func:`usvfast.shore.register.register`:
   ECC from the identity and from the ORB + RANSAC similarity, the better correlation kept;
   affine when the camera zooms),
   and the pairwise warps are chained, so any neighbour can be warped onto the current frame;
   an unregistered pair cuts the chain (frames across the cut are not neighbours);
2. the background of the frame is the per-pixel, per-channel median of its `history`
   registered neighbours: the previous ones only (**online**, `online=True`: usable live) or,
   offline, half before and half after it; its spread is 1.4826 × the per-pixel median
   absolute deviation of those neighbours, floored at `spread_floor` grey levels (glittering
   water varies from frame to frame, so it needs a larger change);
3. a pixel's change is its largest channel deviation from the background in spreads (a robust
   z); pixels seen by fewer than half the neighbours get 0;
4. opening, closing (wider than tall), connected components; with `refine`, a component is
   grown by the components of the frame's own contrast mask (:mod:`usvfast.shore.contrast`)
   that it touches, no larger than `refine_growth` × its box's area — a boat that moved less
   than its length since the neighbours only changes at its ends, while its whole hull
   contrasts with the water;
5. boxes are kept when boat-shaped and floating: their bottom under the horizon line (or at
   most `-wet` of the frame height above it) — whatever the line's kind, since what moves
   against the background under the line is not the coast;
6. frames without enough registered neighbours (`min_neighbours`: the start of a video online,
   or a cut) get the contrast detector's boxes when `fallback`, else none.

The score of a box is its component's mean change over 4 × `threshold`, clipped to [0, 1].
Pixels: origin top-left, x right, y down; boxes x, y, w, h of the input frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from usvfast._validate import instance, integer, real
from usvfast.shore.boxes import Detections
from usvfast.shore.contrast import ContrastConfig, ContrastDetector, _check_frame, contrast_map
from usvfast.shore.horizon import HorizonLine, detect_horizon
from usvfast.shore.register import RegisterConfig, register, warp_to


@dataclass(frozen=True)
class ChangeConfig:
    """Parameters of :class:`ChangeDetector` (module doc).

    history: registered neighbours in each frame's background. online: past neighbours only
    (else half past, half future). min_neighbours: fewest registered neighbours for a
    background. threshold: robust z of a changed pixel. work_width: frames wider are analysed
    at this width (px). blur: Gaussian kernel (odd, working px). spread_floor: smallest spread
    (grey levels). open_px: opening kernel (working px; 1 = none). close: closing kernel
    (width, height), fractions of the working width. min_width: smallest box width, fraction
    of the frame width. min_aspect: smallest width / height. min_fill: smallest share of
    changed pixels in a component's box. wet: a box's bottom must lie at least this fraction
    of the frame height under the horizon line (negative: above it by at most that much).
    border_px: ignored margin (working px). refine: grow components by the contrast mask.
    refine_growth: largest area ratio of a grown box to its change box. fallback: contrast
    boxes on frames without a background. contained: a box with more than this share of its
    area inside a larger box is dropped (1: none). relative: boxes scoring under this share
    of the frame's best are dropped. register: the registration's parameters. contrast: the
    contrast cue's parameters (refine, fallback).
    """

    history: int = 4
    online: bool = True
    min_neighbours: int = 2
    threshold: float = 5.0
    work_width: int = 352
    blur: int = 5
    spread_floor: float = 4.0
    open_px: int = 3
    close: tuple[float, float] = (0.03, 0.02)
    min_width: float = 0.04
    min_aspect: float = 0.8
    min_fill: float = 0.2
    wet: float = -0.01
    border_px: int = 3
    refine: bool = True
    refine_growth: float = 10.0
    fallback: bool = True
    contained: float = 0.6
    relative: float = 0.8
    register: RegisterConfig = field(default_factory=RegisterConfig)
    contrast: ContrastConfig = field(default_factory=ContrastConfig)

    def __post_init__(self) -> None:
        integer("history", self.history, low=1)
        integer("min_neighbours", self.min_neighbours, low=1, high=self.history)
        real("threshold", self.threshold, positive=True)
        integer("work_width", self.work_width, low=16)
        if integer("blur", self.blur, low=1) % 2 == 0:
            raise ValueError(f"blur: must be odd and >= 1, got {self.blur}")
        real("spread_floor", self.spread_floor, positive=True)
        integer("open_px", self.open_px, low=1)
        integer("border_px", self.border_px, low=0)
        if not isinstance(self.close, tuple) or len(self.close) != 2:
            raise TypeError(f"close: expected a (width, height) tuple, got {self.close!r}")
        for name, value in (
            ("close", self.close[0]),
            ("close", self.close[1]),
            ("min_width", self.min_width),
            ("min_fill", self.min_fill),
        ):
            if not 0.0 <= real(name, value) < 1.0:
                raise ValueError(f"{name}: expected a fraction in [0, 1), got {value}")
        if not -1.0 < real("wet", self.wet) < 1.0:
            raise ValueError(f"wet: expected a fraction in (-1, 1), got {self.wet}")
        for name in ("contained", "relative"):
            if not 0.0 <= real(name, getattr(self, name)) <= 1.0:
                raise ValueError(
                    f"{name}: expected a fraction in [0, 1], got {getattr(self, name)}"
                )
        real("min_aspect", self.min_aspect, low=0.0)
        real("refine_growth", self.refine_growth, low=1.0)
        for name in ("online", "refine", "fallback"):
            if not isinstance(getattr(self, name), bool):
                raise TypeError(f"{name}: expected a bool, got {getattr(self, name)!r}")
        instance("register", self.register, RegisterConfig)
        instance("contrast", self.contrast, ContrastConfig)


def _uncontained(box: np.ndarray, share: float) -> np.ndarray:
    """Mask (k,) of boxes (k, 4) x, y, w, h of which no more than `share` of the area lies
    inside a larger box (1: keep all)."""
    x1, y1 = box[:, 0] + box[:, 2], box[:, 1] + box[:, 3]
    iw = np.minimum(x1[:, None], x1[None]) - np.maximum(box[:, None, 0], box[None, :, 0])
    ih = np.minimum(y1[:, None], y1[None]) - np.maximum(box[:, None, 1], box[None, :, 1])
    inter = np.clip(iw, 0, None) * np.clip(ih, 0, None)
    area = box[:, 2] * box[:, 3]
    inside = (inter > share * np.maximum(area, 1e-9)[:, None]) & (area[None] > area[:, None])
    return np.asarray(~inside.any(axis=1))


def _homogeneous(warp: np.ndarray) -> np.ndarray:
    return np.vstack([np.asarray(warp, dtype=np.float64), [0.0, 0.0, 1.0]])


@dataclass
class _Frame:
    """One frame at the working size: blurred BGR float32, grey uint8, the scale working /
    input px, and the 3 × 3 warp from the previous frame to this one (None: not registered,
    or the first frame)."""

    image: np.ndarray
    grey: np.ndarray
    scale: float
    from_prev: np.ndarray | None
    size: tuple[int, int]


class ChangeDetector:
    """Boats as what changed against the registered background of neighbouring frames
    (module doc). Offline, :meth:`detect_sequence` takes a whole video; online,
    :meth:`step` takes one frame at a time (past neighbours only, whatever `online` says)
    and :meth:`reset` starts a new video."""

    def __init__(self, config: ChangeConfig | None = None) -> None:
        if config is not None:
            instance("config", config, ChangeConfig)
        self.config = config or ChangeConfig()
        self._contrast = ContrastDetector(self.config.contrast)
        self._past: list[_Frame] = []
        #: How each frame was registered to its predecessor (RegisterConfig's METHODS).
        self.methods: list[str] = []

    def reset(self) -> None:
        """Forget the frames seen (a new video)."""
        self._past = []
        self.methods = []

    def _prepare(self, image: np.ndarray, prev: _Frame | None) -> _Frame:
        cfg = self.config
        h0, w0 = image.shape[:2]
        s = cfg.work_width / w0 if w0 > cfg.work_width else 1.0
        small = (
            cv2.resize(image, (round(w0 * s), max(1, round(h0 * s))), interpolation=cv2.INTER_AREA)
            if s < 1
            else image
        )
        grey = cv2.cvtColor(small, cv2.COLOR_BGR2GRAY)
        k = cfg.blur
        blurred = (cv2.GaussianBlur(small, (k, k), 0) if k > 1 else small).astype(np.float32)
        link = None
        if prev is not None:
            if prev.size != (h0, w0):
                raise ValueError(
                    f"image: size {image.shape[:2]} differs from the previous frame's; "
                    "a video's frames must share one size (reset() between videos)"
                )
            warp, method = register(grey, prev.grey, cfg.register)
            self.methods.append(method)
            link = None if method == "none" else _homogeneous(warp)
        else:
            self.methods.append("first")
        return _Frame(blurred, grey, s, link, (h0, w0))

    def _change(
        self, frames: Sequence[_Frame], t: int, neighbours: Sequence[int]
    ) -> np.ndarray | None:
        """The change z (h, w) of frame `t` against `neighbours` (indexes into `frames`),
        or None when fewer than `min_neighbours` of them are registered to it."""
        cfg = self.config
        cur = frames[t]
        h, w = cur.grey.shape
        stack, seen = [], []
        for j in neighbours:
            m: np.ndarray | None = np.eye(3)
            for k in range(min(j, t) + 1, max(j, t) + 1):  # chain the links between j and t
                link = frames[k].from_prev
                if link is None or m is None:
                    m = None
                    break
                m = link @ m
            if m is None:
                continue
            if j > t:  # the chain maps t -> j: invert it
                m = np.linalg.inv(m)
            image, inside = warp_to(frames[j].image, m[:2], (w, h))
            stack.append(image)
            seen.append(inside)
        if len(stack) < cfg.min_neighbours:
            return None
        st = np.stack(stack)  # (n, h, w, 3)
        med = np.median(st, axis=0)
        spread = np.maximum(1.4826 * np.median(np.abs(st - med), axis=0), cfg.spread_floor)
        z = (np.abs(cur.image - med) / spread).max(axis=2)
        z[np.sum(seen, axis=0) * 2 < len(stack)] = 0.0
        b = cfg.border_px
        if b > 0:
            z[:b] = 0
            z[-b:] = 0
            z[:, :b] = 0
            z[:, -b:] = 0
        return z

    def _boxes(
        self, z: np.ndarray, scale: float, image: np.ndarray, horizon: HorizonLine | None
    ) -> Detections:
        cfg = self.config
        h, w = z.shape
        cz = None
        if cfg.refine and horizon is not None:
            cz, _, _ = contrast_map(image, horizon, cfg.contrast)
            if cz.shape != (h, w):  # another working width: bring it to this one
                cz = cv2.resize(cz, (w, h), interpolation=cv2.INTER_NEAREST)
        raw = z > cfg.threshold
        mask = raw.astype(np.uint8)
        if cfg.open_px > 1:
            mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((cfg.open_px,) * 2, np.uint8))
        kw, kh = (max(1, round(c * w)) for c in cfg.close)
        if kw > 1 or kh > 1:
            mask = cv2.morphologyEx(
                mask, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_RECT, (kw, kh))
            )
        n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        if n <= 1:
            return Detections()
        box = stats[1:, :4].astype(float)
        area = np.maximum(stats[1:, 4], 1)
        mean_z = np.bincount(labels.ravel(), weights=(z * mask).ravel(), minlength=n)[1:] / area
        fill = np.bincount(labels.ravel(), weights=raw.ravel(), minlength=n)[1:] / np.maximum(
            box[:, 2] * box[:, 3], 1
        )
        if cz is not None:
            box = self._refine(box, labels, cz)
        keep = (box[:, 2] >= cfg.min_width * w) & (box[:, 2] >= cfg.min_aspect * box[:, 3])
        keep &= fill >= cfg.min_fill
        if horizon is not None:
            line = horizon.y_at((np.arange(w) + 0.5) / scale) * scale
            cx = np.clip((box[:, 0] + box[:, 2] / 2).astype(int), 0, w - 1)
            ly = line[cx]
            keep &= box[:, 1] + box[:, 3] >= ly + cfg.wet * h
        box, scores = box[keep], np.clip(mean_z[keep] / (4 * cfg.threshold), 0.0, 1.0)
        keep = _uncontained(box, cfg.contained) & (scores >= cfg.relative * scores.max(initial=0))
        scores, out = scores[keep], box[keep] / scale
        return Detections(out, scores, np.full(len(out), -1, dtype=np.int64))

    def _refine(
        self,
        box: np.ndarray,
        labels: np.ndarray,
        cz: np.ndarray,
    ) -> np.ndarray:
        """Change boxes (k, 4, working px; components `labels`) grown by the components of
        the contrast map `cz` (working px) they touch."""
        cfg = self.config
        cmask = (cz > cfg.contrast.threshold).astype(np.uint8)
        if cfg.contrast.open_px > 1:
            k = np.ones((cfg.contrast.open_px,) * 2, np.uint8)
            cmask = cv2.morphologyEx(cmask, cv2.MORPH_OPEN, k)
        _, clab, cstats, _ = cv2.connectedComponentsWithStats(cmask, connectivity=8)
        out = box.copy()
        for i in range(len(box)):
            touched = np.unique(clab[(labels == i + 1) & (clab > 0)])
            x0, y0 = box[i, 0], box[i, 1]
            x1, y1 = x0 + box[i, 2], y0 + box[i, 3]
            for c in touched:
                cx0, cy0, cw, ch = cstats[c, :4]
                gx0, gy0 = min(x0, cx0), min(y0, cy0)
                gx1, gy1 = max(x1, cx0 + cw), max(y1, cy0 + ch)
                if (gx1 - gx0) * (gy1 - gy0) <= cfg.refine_growth * box[i, 2] * box[i, 3]:
                    x0, y0, x1, y1 = gx0, gy0, gx1, gy1
            out[i] = (x0, y0, x1 - x0, y1 - y0)
        return out

    def _detect(
        self, z: np.ndarray | None, scale: float, image: np.ndarray, horizon: HorizonLine | None
    ) -> Detections:
        if z is None:
            return self._contrast.detect(image, horizon) if self.config.fallback else Detections()
        return self._boxes(z, scale, image, horizon)

    def step(self, image: np.ndarray, horizon: HorizonLine | None = None) -> Detections:
        """Boats of the next BGR uint8 frame (h, w, 3) of a video, against its past
        neighbours (online, whatever `config.online` says; the horizon is found when not
        given). A frame of another size than the previous one starts a new sequence."""
        _check_frame(image, horizon)
        if horizon is None:
            horizon = detect_horizon(image, config=self.config.contrast.horizon)
        if self._past and self._past[-1].size != image.shape[:2]:
            self.reset()  # another size: a new sequence (a folder of several cameras)
        frame = self._prepare(image, self._past[-1] if self._past else None)
        frames = [*self._past, frame]
        t = len(frames) - 1
        z = self._change(frames, t, range(max(0, t - self.config.history), t))
        self._past = frames[-self.config.history :]
        return self._detect(z, frame.scale, image, horizon)

    def change_maps(self, images: Sequence[np.ndarray]) -> list[tuple[np.ndarray | None, float]]:
        """Per frame of one video (BGR uint8, time order, one size): its change z (h, w,
        working px; None without enough registered neighbours) and the scale working /
        input px. Neighbours: the `history` previous frames when `online`, else half before
        and half after (fewer on one side at the video's ends)."""
        if not isinstance(images, Sequence) or isinstance(images, np.ndarray):
            raise TypeError("images: expected a sequence of frames (list of (h, w, 3) arrays)")
        self.reset()
        frames: list[_Frame] = []
        for im in images:
            _check_frame(im, None)
            frames.append(self._prepare(im, frames[-1] if frames else None))
        n, k = len(frames), self.config.history
        out = []
        for t in range(n):
            if self.config.online:
                nb: Sequence[int] = range(max(0, t - k), t)
            else:
                lo = max(0, min(t - (k + 1) // 2, n - 1 - k))
                nb = [j for j in range(lo, min(n, lo + k + 1)) if j != t][:k]
            out.append((self._change(frames, t, nb), frames[t].scale))
        return out

    def detect_maps(
        self,
        maps: Sequence[tuple[np.ndarray | None, float]],
        images: Sequence[np.ndarray],
        horizons: Sequence[HorizonLine | None],
    ) -> list[Detections]:
        """Boxes of every frame from its change map (:meth:`change_maps`, possibly computed
        by a detector with other box parameters: the maps depend only on `history`,
        `online`, `min_neighbours`, `work_width`, `blur`, `spread_floor`, `border_px` and
        `register`), its image and its horizon."""
        if not len(maps) == len(images) == len(horizons):
            raise ValueError(
                f"maps: expected one per image and horizon, got {len(maps)}, {len(images)}, "
                f"{len(horizons)}"
            )
        out = []
        for (z, scale), im, hz in zip(maps, images, horizons, strict=True):
            _check_frame(im, hz)
            out.append(self._detect(z, scale, im, hz))
        return out

    def detect_sequence(
        self,
        images: Sequence[np.ndarray],
        horizons: Sequence[HorizonLine | None] | None = None,
    ) -> list[Detections]:
        """Boats of every frame of one video (BGR uint8 frames in time order, one size), each
        against its neighbours (:meth:`change_maps`); horizons found when not given."""
        maps = self.change_maps(images)
        if horizons is None:
            horizons = [detect_horizon(im, config=self.config.contrast.horizon) for im in images]
        elif len(horizons) != len(images):
            raise ValueError(f"horizons: expected {len(images)}, got {len(horizons)}")
        return self.detect_maps(maps, images, horizons)
