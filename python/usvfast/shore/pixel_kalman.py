"""The pixel Kalman filter of Kim, Chung and Lee (§IV, eqs. 9–11) and their adaptive rule
(§III-B, steps 8–11): a jumping detection is replaced by the Kalman prediction.

State [x, y, v_x, v_y]: the box centre (px) and its velocity (px per frame); F constant
velocity with dt = 1 frame, H picks (x, y), Q = I, R = I (eq. 11). The filter runs on the
Rust core through `usvfast.kalman` (a fixed `LinearModel`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usvfast.kalman import LinearModel, predict_states, update_states
from usvfast.shore.boxes import Detections


def paper_model() -> tuple[LinearModel, np.ndarray, np.ndarray]:
    """(model with F and Q, H, R) of eq. 11."""
    f = np.eye(4)
    f[0, 2] = f[1, 3] = 1.0  # x += v_x, y += v_y  (dt = 1)
    h = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
    return LinearModel(f, np.eye(4)), h, np.eye(2)


@dataclass
class AdaptiveConfig:
    """jump_px: the pseudo-code's "interval value" (px): a detection whose width, height or
    centre moves by more than this from the last accepted one is replaced by the prediction
    (the paper gives no value). max_rejections: after this many replaced detections in a row
    the next detection is accepted again (ours, so one bad first box cannot lock the tracker).
    initial_velocity_var: prior variance of v_x, v_y ((px/frame)²; position prior R = I)."""

    jump_px: float = 40.0
    max_rejections: int = 5
    initial_velocity_var: float = 100.0


class AdaptiveTracker:
    """One vessel, one id: the paper's adaptive Kalman tracker over per-frame detections.

    `step(detections)` -> Detections of the tracked box this frame (0 or 1 box) and whether it
    came from the prediction (`last_predicted`). The largest-score detection is the candidate.
    """

    def __init__(self, config: AdaptiveConfig | None = None) -> None:
        self.config = config or AdaptiveConfig()
        self.model, self.h, self.r = paper_model()
        self.f, self.q = self.model.matrices(1.0)
        self.x: np.ndarray | None = None
        self.p: np.ndarray | None = None
        self.prev_box: np.ndarray | None = None
        self.rejections = 0
        self.last_predicted = False

    def _accept(self, box: np.ndarray) -> bool:
        if self.prev_box is None:
            return True
        d = self.config.jump_px
        # steps 8–10: width, height and centre jumps against the interval value
        if abs(box[2] - self.prev_box[2]) > d or abs(box[3] - self.prev_box[3]) > d:
            return False
        c, cp = box[:2] + box[2:] / 2, self.prev_box[:2] + self.prev_box[2:] / 2
        return bool(np.hypot(*(c - cp)) <= d)

    def step(self, detections: Detections) -> Detections:
        """Advance one frame with this frame's detections; returns the tracked box."""
        cand = None
        if len(detections):
            cand = detections.boxes[int(np.argmax(detections.scores))].astype(float)
        if self.x is None:
            if cand is None:
                return Detections()
            self._start(cand)
            return Detections(cand[None], np.ones(1), np.array([-1]))
        prev = self.prev_box
        assert self.p is not None and prev is not None  # set with x by _start
        # X' = F X, P' = F P Fᵀ + Q  (eq. 10, prediction)
        xs, ps = predict_states(
            self.x[None], self.p[None], transition_matrix=self.f, process_noise=self.q
        )
        x, p = self.x, self.p = xs[0], ps[0]
        accepted = cand is not None and (
            self._accept(cand) or self.rejections >= self.config.max_rejections
        )
        if cand is not None and accepted:
            centre = cand[:2] + cand[2:] / 2
            # K = P' Hᵀ (H P' Hᵀ + R)⁻¹, X = X' + K (Z − H X')  (eq. 10, update)
            xs, ps, _ = update_states(
                x[None],
                p[None],
                centre[None],
                measurement_matrix=self.h,
                measurement_noise=self.r,
            )
            self.x, self.p = xs[0], ps[0]
            self.prev_box = cand  # step 11
            self.rejections = 0
            self.last_predicted = False
            return Detections(cand[None], np.ones(1), np.array([-1]))
        if cand is not None:
            self.rejections += 1
        self.last_predicted = True
        w, h = prev[2:]
        box = np.array([x[0] - w / 2, x[1] - h / 2, w, h])
        return Detections(box[None], np.full(1, 0.5), np.array([-1]))

    def _start(self, box: np.ndarray) -> None:
        centre = box[:2] + box[2:] / 2
        self.x = np.array([centre[0], centre[1], 0.0, 0.0])
        v = self.config.initial_velocity_var
        self.p = np.diag([1.0, 1.0, v, v])
        self.prev_box = box
        self.rejections = 0
        self.last_predicted = False
