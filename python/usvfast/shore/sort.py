"""A SORT-like multi-target image tracker (Bewley et al., 2016): one Kalman filter per track
on the box [u, v, s, r] (centre px, area px², aspect w/h) with constant velocity of u, v, s,
and optimal assignment on IoU; colour histograms re-identify tracks lost for a few frames.

Every frame: predict all tracks in one Rust call (`usvfast.kalman.predict_states`, a fixed
`LinearModel`), assign detections to tracks by `usvfast._core.linear_sum_assignment` on the
cost 1 − IoU (+ a share of the histogram distance), update the matched tracks in one Rust
call, then match the leftovers by appearance alone near the predicted box (re-identification),
start tracks on unmatched detections and delete tracks unseen for `max_age` frames.

Two-stage association (ByteTrack, Zhang et al., ECCV 2022, §3 "BYTE"), on when
`SortConfig.high_score` > 0: only the detections scoring at least `high_score` take part in
the steps above (and only they start tracks); the tracks still unmatched after them are then
assigned to the low-score detections (`low_score` ≤ score < `high_score`) on IoU alone
(gated at `low_iou_threshold`), so that a boat whose detector confidence drops for a few
frames (occlusion, glare, a wake) keeps its track; low-score detections left over and
detections below `low_score` are dropped. With the defaults (`high_score` = `low_score` = 0)
every detection is used in one stage, as before.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usvfast import _core
from usvfast._validate import as_float_array, finite_result, instance, real
from usvfast.kalman import LinearModel, predict_states, update_states
from usvfast.shore.appearance import box_histogram, histogram_distance
from usvfast.shore.boxes import Detections, iou_matrix

#: Cost of a forbidden pair (the assignment then drops it).
FORBIDDEN = 1e6


@dataclass(frozen=True)
class SortConfig:
    """iou_threshold: least IoU of an assigned pair. max_age: frames a track survives
    unseen. min_hits: updates before a track is reported (reported at once in the first
    min_hits frames). appearance_weight: share of the histogram distance in the assignment
    cost. reid_distance: largest histogram distance of a re-identification. reid_radius: a
    re-identified detection's centre lies within this many predicted-box diagonals.
    measurement_noise, process_noise, initial_covariance: diagonals of R (4,), Q (7,), P₀ (7,)
    (SORT's published values).

    Two-stage association (ByteTrack, module doc): high_score: detection score (the
    detector's confidence in [0, 1]) from which a detection is associated first and may start
    a track; 0 (default) turns the second stage off and every detection is used as before.
    low_score: least score of a second-stage detection (low_score ≤ score < high_score;
    lower scores are dropped); at most high_score. low_iou_threshold: least IoU of a
    second-stage pair (ByteTrack's published 0.5). Raises ValueError naming the field for a
    negative or non-finite value or low_score > high_score."""

    iou_threshold: float = 0.3
    max_age: int = 3
    min_hits: int = 2
    appearance_weight: float = 0.3
    reid_distance: float = 0.35
    reid_radius: float = 1.5
    measurement_noise: tuple[float, ...] = (1.0, 1.0, 10.0, 10.0)
    process_noise: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0, 1e-2, 1e-2, 1e-4)
    initial_covariance: tuple[float, ...] = (10.0, 10.0, 10.0, 10.0, 1e4, 1e4, 1e4)
    high_score: float = 0.0
    low_score: float = 0.0
    low_iou_threshold: float = 0.5

    def __post_init__(self) -> None:
        for name in ("high_score", "low_score", "low_iou_threshold"):
            v = real(name, getattr(self, name), low=0.0)
            if v > 1.0:
                raise ValueError(f"{name}: expected a value in [0, 1], got {v}")
            object.__setattr__(self, name, v)
        if self.low_score > self.high_score:
            raise ValueError(
                f"low_score: must be at most high_score ({self.high_score}), got {self.low_score}"
            )

    @property
    def two_stage(self) -> bool:
        """Whether the second (low-score) association stage is on (high_score > 0)."""
        return self.high_score > 0.0


def sort_config_from_options(high_score: float, low_score: float) -> SortConfig:
    """The SortConfig of the command-line options --sort-high-score and --sort-low-score;
    its ValueError names the option."""
    try:
        return SortConfig(high_score=high_score, low_score=low_score)
    except ValueError as exc:
        name, _, why = str(exc).partition(":")
        why = why.replace("high_score", "--sort-high-score")
        raise ValueError(f"--sort-{name.replace('_', '-')}:{why}") from exc


def box_to_z(box: np.ndarray) -> np.ndarray:
    """(k, 4) x, y, w, h -> (k, 4) u, v, s, r."""
    box = as_float_array("box", box)
    if box.size % 4:
        raise ValueError(f"box: expected (k, 4) boxes, got shape {box.shape}")
    b = np.asarray(box, dtype=float).reshape(-1, 4)
    w, h = b[:, 2], b[:, 3]
    with np.errstate(over="ignore", invalid="ignore"):  # an overflow is refused just below
        z = np.column_stack([b[:, 0] + w / 2, b[:, 1] + h / 2, w * h, w / np.maximum(h, 1e-9)])
    return finite_result("z", z, "box")


def state_to_box(x: np.ndarray) -> np.ndarray:
    """(k, ≥4) states u, v, s, r, ... -> (k, 4) x, y, w, h (w = sqrt(s r), h = s / w)."""
    x = as_float_array("x", x)
    if x.ndim != 2 or x.shape[1] < 4:
        raise ValueError(f"x: expected (k, >= 4) states, got shape {x.shape}")
    x = np.asarray(x, dtype=float).reshape(len(x), -1)
    s = np.maximum(x[:, 2], 1e-9)
    r = np.maximum(x[:, 3], 1e-9)
    with np.errstate(over="ignore"):
        w = np.sqrt(s * r)
    big = np.isinf(w)  # s r beyond float64: the same root, taken factor by factor
    w[big] = np.sqrt(s[big]) * np.sqrt(r[big])
    h = s / w
    return np.column_stack([x[:, 0] - w / 2, x[:, 1] - h / 2, w, h])


@dataclass
class _Track:
    track_id: int
    hist: np.ndarray | None
    hits: int = 1
    time_since_update: int = 0
    score: float = 1.0
    history: list[int] = field(default_factory=list)


class SortTracker:
    """Frame-by-frame multi-target tracker; `step(image, detections)` returns the reported
    tracks of this frame as (ids (k,), boxes (k, 4) x, y, w, h px, scores (k,))."""

    def __init__(self, config: SortConfig | None = None) -> None:
        if config is not None:
            instance("config", config, SortConfig)
        self.config = c = config or SortConfig()
        f = np.eye(7)
        f[0, 4] = f[1, 5] = f[2, 6] = 1.0  # u += u̇, v += v̇, s += ṡ per frame
        self.model = LinearModel(f, np.diag(c.process_noise))
        self.f, self.q = self.model.matrices(1.0)
        self.h = np.eye(4, 7)
        self.r = np.diag(c.measurement_noise)
        self.x = np.zeros((0, 7))
        self.p = np.zeros((0, 7, 7))
        self.tracks: list[_Track] = []
        self.next_id = 1
        self.frame = 0

    def _predict(self) -> None:
        if not self.tracks:
            return
        grow = self.x[:, 2] + self.x[:, 6] <= 0
        self.x[grow, 6] = 0.0  # an area never predicted below zero
        self.x, self.p = predict_states(
            self.x, self.p, transition_matrix=self.f, process_noise=self.q
        )
        for t in self.tracks:
            t.time_since_update += 1

    def _assign(self, cost: np.ndarray) -> list[tuple[int, int]]:
        """Optimal (row, col) pairs of a cost matrix, forbidden pairs dropped."""
        if cost.size == 0:
            return []
        if cost.shape[0] <= cost.shape[1]:
            cols = _core.linear_sum_assignment(np.ascontiguousarray(cost))
            pairs = [(i, int(j)) for i, j in enumerate(cols)]
        else:
            rows = _core.linear_sum_assignment(np.ascontiguousarray(cost.T))
            pairs = [(int(i), j) for j, i in enumerate(rows)]
        return [(i, j) for i, j in pairs if cost[i, j] < FORBIDDEN]

    def step(self, image: np.ndarray, detections: Detections) -> tuple[np.ndarray, ...]:
        """Advance one frame (BGR image for the histograms, this frame's detections)."""
        c = self.config
        self.frame += 1
        self._predict()
        all_boxes = np.asarray(detections.boxes, dtype=float).reshape(-1, 4)
        all_scores = np.asarray(detections.scores, dtype=float).reshape(-1)
        if c.two_stage:
            high = all_scores >= c.high_score
            low = ~high & (all_scores >= c.low_score)
        else:
            high = np.ones(len(all_boxes), dtype=bool)
            low = np.zeros(len(all_boxes), dtype=bool)
        boxes, det_scores = all_boxes[high], all_scores[high]
        hists = [box_histogram(image, b) for b in boxes]
        pred = state_to_box(self.x) if self.tracks else np.zeros((0, 4))
        iou = iou_matrix(pred, boxes)
        app = np.array(
            [[histogram_distance(t.hist, h) for h in hists] for t in self.tracks]
        ).reshape(len(self.tracks), len(boxes))
        cost = (1 - c.appearance_weight) * (1 - iou) + c.appearance_weight * app
        cost[iou < c.iou_threshold] = FORBIDDEN
        matches = self._assign(cost)
        # re-identification of the leftovers: appearance alone, near the predicted box
        used_t = {i for i, _ in matches}
        used_d = {j for _, j in matches}
        left_t = [i for i in range(len(self.tracks)) if i not in used_t]
        left_d = [j for j in range(len(boxes)) if j not in used_d]
        if left_t and left_d:
            pc = pred[left_t, :2] + pred[left_t, 2:] / 2
            dc = boxes[left_d, :2] + boxes[left_d, 2:] / 2
            diag = np.hypot(pred[left_t, 2], pred[left_t, 3])
            dist = np.linalg.norm(pc[:, None] - dc[None], axis=2)
            sub = app[np.ix_(left_t, left_d)].copy()
            sub[(sub > c.reid_distance) | (dist > c.reid_radius * diag[:, None])] = FORBIDDEN
            matches += [(left_t[i], left_d[j]) for i, j in self._assign(sub)]
        # second stage (ByteTrack): still-unmatched tracks against the low-score detections
        low_matches: list[tuple[int, int]] = []
        low_boxes = all_boxes[low]
        if len(low_boxes):
            used_t = {i for i, _ in matches}
            left_t = [i for i in range(len(self.tracks)) if i not in used_t]
            if left_t:
                sub = 1 - iou_matrix(pred[left_t], low_boxes)
                sub[sub > 1 - c.low_iou_threshold] = FORBIDDEN
                low_matches = [(left_t[i], j) for i, j in self._assign(sub)]
        n_high = len(boxes)
        if low_matches:  # low-score detections indexed after the high ones
            boxes = np.vstack([boxes, low_boxes])
            det_scores = np.concatenate([det_scores, all_scores[low]])
            hists = hists + [None] * len(low_boxes)  # no appearance update from them
            matches += [(i, n_high + j) for i, j in low_matches]
        if matches:
            ti = np.array([i for i, _ in matches])
            dj = np.array([j for _, j in matches])
            xs, ps, _ = update_states(
                self.x[ti],
                self.p[ti],
                box_to_z(boxes[dj]),
                measurement_matrix=self.h,
                measurement_noise=self.r,
            )
            self.x[ti], self.p[ti] = xs, ps
            for i, j in matches:
                t = self.tracks[i]
                t.hits += 1
                t.time_since_update = 0
                t.score = float(det_scores[j])
                h = hists[j]
                if h is not None:
                    t.hist = h if t.hist is None else 0.7 * t.hist + 0.3 * h
        matched_d = {j for _, j in matches}
        new = [j for j in range(n_high) if j not in matched_d]  # high-score ones only
        if new:
            z = box_to_z(boxes[new])
            x0 = np.zeros((len(new), 7))
            x0[:, :4] = z
            self.x = np.vstack([self.x, x0])
            p0 = np.repeat(np.diag(c.initial_covariance)[None], len(new), axis=0)
            self.p = np.concatenate([self.p, p0])
            for j in new:
                self.tracks.append(_Track(self.next_id, hists[j], score=float(det_scores[j])))
                self.next_id += 1
        keep = np.array([t.time_since_update <= c.max_age for t in self.tracks], dtype=bool)
        self.tracks = [t for t, k in zip(self.tracks, keep, strict=True) if k]
        self.x, self.p = self.x[keep], self.p[keep]
        report = [
            i
            for i, t in enumerate(self.tracks)
            if t.time_since_update == 0 and (t.hits >= c.min_hits or self.frame <= c.min_hits)
        ]
        ids = np.array([self.tracks[i].track_id for i in report], dtype=np.int64)
        out_boxes = state_to_box(self.x[report]) if report else np.zeros((0, 4))
        scores = np.array([self.tracks[i].score for i in report])
        return ids, out_boxes, scores
