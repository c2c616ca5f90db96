"""The paper's image tracker: the two-tier multi-clustered particle filter of Bloisi et al.
(§V, Figs. 9–12, after PTracking), with the local tier in Rust (`usvfast._core.ParticleTracker`).

Every frame, per camera (local tier): propagate each track's particles (constant velocity,
random acceleration), draw proposal particles around each detection, weight them by the
detections, SIR-resample, KClusterize into a Gaussian mixture, and associate the clusters with
the tracks by proximity, direction (≤ 10° apart) and speed module; colour histograms
(hue–saturation, `usvfast.shore.appearance`) add to the cost and re-identify lost tracks, and
tracks whose boxes close in form an occlusion group whose frozen histograms give the
identities back when the boats separate. Confirmation is M-of-N, deletion after `max_age`
misses. The global tier (`fuse_mixtures`) fuses the mixtures of several sensors that arrive
within Δt; with one camera it is not needed.

Units: pixels (origin top-left, x right, y down), px/frame, frames. Deterministic from `seed`.
No re-identification network weights are available here: colour histograms stand in.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from usvfast import _core
from usvfast.shore.appearance import BINS, box_histogram
from usvfast.shore.boxes import Detections


@dataclass(frozen=True)
class ParticleConfig:
    """Parameters of the particle tracker (px, px/frame, frames). particles: drawn per
    detection and kept per track; accel_std: random acceleration (px/frame²); meas_scale:
    observation std as a share of the box size; birth_vel_std / track_vel_std: velocity std
    of proposal particles near no track / near a track; vel_gain: share of the innovation per
    frame added to a track's velocity in its proposals; clutter: weight floor (per px²);
    delta: KClusterize's δ_model (px; None: 6 % of the frame width); min_cluster,
    min_kurtosis, max_depth: KClusterize's Gaussianity test and splits; gate: proximity in
    predicted-box diagonals; max_angle_deg: same-direction test (the paper's 10°);
    min_speed: slower velocities are not tested for direction; speed_abs, speed_rel: the
    speed-module test |s₁ − s₂| ≤ abs + rel·max; appearance_weight: share of the histogram
    distance in the cost; confirm_hits of confirm_window: M-of-N confirmation; max_age:
    misses before a confirmed track is deleted (twice in an occlusion group); group_iou:
    overlap that forms a group; reid_distance, reid_radius: re-identification limits
    (Bhattacharyya distance, predicted-box diagonals); size_gain: box-size smoothing; seed."""

    particles: int = 64
    accel_std: float = 0.01
    meas_scale: float = 0.15
    birth_vel_std: float = 1.0
    track_vel_std: float = 0.3
    vel_gain: float = 0.5
    clutter: float = 1e-9
    delta: float | None = None
    min_cluster: int = 8
    min_kurtosis: float = 1.9
    max_depth: int = 3
    gate: float = 1.0
    max_angle_deg: float = 10.0
    min_speed: float = 0.5
    speed_abs: float = 1.0
    speed_rel: float = 0.5
    appearance_weight: float = 0.3
    confirm_hits: int = 2
    confirm_window: int = 3
    max_age: int = 3
    group_iou: float = 0.05
    reid_distance: float = 0.35
    reid_radius: float = 1.5
    size_gain: float = 0.6
    seed: int = 0


class ParticleTracker:
    """Frame-by-frame particle tracker; `step(image, detections, dt)` returns the confirmed
    tracks updated in this frame as (ids (k,), boxes (k, 4) x, y, w, h px, scores (k,)).
    The Rust tracker is created on the first frame (δ_model defaults to the frame width)."""

    def __init__(self, config: ParticleConfig | None = None) -> None:
        self.config = config or ParticleConfig()
        self.core: _core.ParticleTracker | None = None

    def _make(self, width: int) -> _core.ParticleTracker:
        kw = asdict(self.config)
        if kw["delta"] is None:
            kw["delta"] = max(0.06 * width, 4.0)
        return _core.ParticleTracker(**kw)

    def step(
        self, image: np.ndarray | None, detections: Detections, dt: float = 1.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Advance `dt` frames with this frame's detections (BGR `image` for the colour
        histograms; None: no appearance)."""
        core = self.core
        if core is None:
            core = self.core = self._make(image.shape[1] if image is not None else 320)
        boxes = np.ascontiguousarray(np.asarray(detections.boxes, dtype=float).reshape(-1, 4))
        scores = np.ascontiguousarray(np.asarray(detections.scores, dtype=float).reshape(-1))
        hists = None
        if image is not None:
            empty = np.zeros(BINS, np.float32)
            hs = [box_histogram(image, b) for b in boxes]
            hists = np.array(
                [(empty if h is None else h).ravel() for h in hs], dtype=float
            ).reshape(len(boxes), BINS[0] * BINS[1])
        return core.step(boxes, scores, hists, float(dt))
